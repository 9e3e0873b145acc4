#include "subslam/study/study.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_replace.h"
#include "subslam/study/binomial_interval.h"
#include "subslam/study/run_table.h"
#include "subslam/study/study_runner.h"
#include "test_util.h"

namespace subslam::study {
namespace {

using nlohmann::json;

std::string Slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string FreshDir(const std::string& name) {
  const std::string dir = absl::StrCat(::testing::TempDir(), "/study_test_", name);
  std::filesystem::remove_all(dir);
  return dir;
}

TEST(RunTable, NumbersReadBackToTheSameDouble) {
  for (double v : {0.1, 1.0 / 3.0, 2.0, -1e-300, 6.02214076e23, 0.49872910268551146}) {
    EXPECT_EQ(std::stod(FormatNumber(v)), v) << FormatNumber(v);
  }
  EXPECT_EQ(FormatNumber(0.02), "0.02");
  EXPECT_EQ(FormatNumber(std::nan("")), "nan");
  RunTable t({"run", "x"});
  ASSERT_TRUE(t.Add({"1", FormatNumber(1.0 / 3.0)}).ok());
  ASSERT_TRUE(t.Add({"0", "nan"}).ok());
  const std::string path = FreshDir("table.csv");
  ASSERT_TRUE(t.Write(path).ok());
  absl::StatusOr<RunTable> back = RunTable::Read(path);
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_TRUE(back->SortBy("run").ok());
  EXPECT_TRUE(std::isnan(*back->Number(0, "x")));
  EXPECT_EQ(*back->Number(1, "x"), 1.0 / 3.0);
}

TEST(RunTable, BadInputGetsAClearError) {
  RunTable t({"run", "method"});
  EXPECT_FALSE(t.Add({"1"}).ok());
  EXPECT_FALSE(t.Add({"1", "a,b"}).ok());
  ASSERT_TRUE(t.Add({"1", "ekf"}).ok());
  absl::StatusOr<double> not_number = t.Number(0, "method");
  ASSERT_FALSE(not_number.ok());
  EXPECT_NE(not_number.status().message().find("column method"), std::string::npos) << not_number.status();
  EXPECT_FALSE(t.Number(0, "nope").ok());
  const std::string path = FreshDir("short_row.csv");
  std::ofstream(path) << "run,method\n0,ekf\n1\n";
  absl::StatusOr<RunTable> read = RunTable::Read(path);
  ASSERT_FALSE(read.ok());
  EXPECT_NE(read.status().message().find(path + ":3:"), std::string::npos) << read.status();
}

// At the ends the Clopper-Pearson bounds have closed forms: 0 of n gives an upper bound
// 1 − (α/2)^(1/n), n of n a lower bound (α/2)^(1/n); and k of n mirrors n − k of n.
TEST(BinomialInterval, MatchesTheClosedFormsAndSymmetry) {
  for (int n : {1, 2, 20, 100}) {
    EXPECT_NEAR(BinomialInterval(0, n).low, 0.0, 1e-12);
    EXPECT_NEAR(BinomialInterval(0, n).high, 1.0 - std::pow(0.025, 1.0 / n), 1e-9);
    EXPECT_NEAR(BinomialInterval(n, n).low, std::pow(0.025, 1.0 / n), 1e-9);
    EXPECT_NEAR(BinomialInterval(n, n).high, 1.0, 1e-12);
  }
  const ProportionInterval a = BinomialInterval(87, 100), b = BinomialInterval(13, 100);
  EXPECT_NEAR(a.low, 1.0 - b.high, 1e-9);
  EXPECT_NEAR(a.high, 1.0 - b.low, 1e-9);
  EXPECT_LT(a.low, 0.87);
  EXPECT_GT(a.high, 0.87);
}

TEST(Shard, ParsesKOfN) {
  absl::StatusOr<Shard> s = ShardFromString("2/3");
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->index, 2);
  EXPECT_EQ(s->count, 3);
  for (const char* bad : {"0/3", "4/3", "1", "a/b", "1/0", ""}) EXPECT_FALSE(ShardFromString(bad).ok()) << bad;
}

StudyOptions Options(const std::string& dir, int workers, Shard shard = {}) {
  StudyOptions o;
  o.trials = 1;
  o.methods = {"ekf", "rbpf-eif"};
  o.workers = workers;
  o.shard = shard;
  o.out_dir = dir;
  return o;
}

// The study's outputs depend only on its runs: one process with two workers, and slices of
// 2 and of 3 run one worker each and merged, give the same bytes.
TEST(HybridSlamStudy, SlicesMergeToTheSingleRunsBytes) {
  absl::StatusOr<std::unique_ptr<Study>> study = MakeStudy("hybridslam");
  ASSERT_TRUE(study.ok());
  const std::string single = FreshDir("single");
  ASSERT_TRUE(RunStudy(**study, Options(single, 2)).ok());
  for (int n : {2, 3}) {
    std::vector<std::string> slices;
    for (int k = n; k >= 1; --k) {  // merged in any order
      slices.push_back(FreshDir(absl::StrCat("slice", k, "of", n)));
      ASSERT_TRUE(RunStudy(**study, Options(slices.back(), 1, {k, n})).ok());
      EXPECT_FALSE(std::filesystem::exists(slices.back() + "/summary.json")) << "a slice has no summary";
    }
    const std::string merged = FreshDir(absl::StrCat("merged", n));
    ASSERT_TRUE(MergeStudy(slices, merged).ok());
    for (const char* file : {"runs.csv", "summary.json", "summary.md", "config.json"}) {
      EXPECT_EQ(Slurp(merged + "/" + file), Slurp(single + "/" + file)) << file << ", " << n << " slices";
    }
    // Bad merges: a slice missing, a slice twice.
    EXPECT_FALSE(MergeStudy({slices[0]}, FreshDir("bad")).ok());
    std::vector<std::string> twice = slices;
    twice.push_back(slices[0]);
    EXPECT_FALSE(MergeStudy(twice, FreshDir("bad")).ok());
  }

  // The table's shape and ranges: one row per method and setting, the paper's figure
  // beside the EKF row, none beside ours.
  const json summary = json::parse(Slurp(single + "/summary.json"));
  ASSERT_EQ(summary["rows"].size(), 8u);
  for (const json& row : summary["rows"]) {
    SCOPED_TRACE(row.dump());
    EXPECT_EQ(row["trials"], 1);
    EXPECT_GE(row["successes"].get<int>(), 0);
    EXPECT_LE(row["successes"].get<int>(), 1);
    EXPECT_LE(row["success_rate_ci95"][0].get<double>(), row["success_rate"].get<double>());
    EXPECT_GE(row["success_rate_ci95"][1].get<double>(), row["success_rate"].get<double>());
    EXPECT_EQ(row["paper_success_rate"].is_null(), row["method"] == "rbpf-eif");
    EXPECT_GT(row["median_rms_online_m"].get<double>(), 0.0);
    EXPECT_LT(row["median_rms_online_m"].get<double>(), 20.0);
    EXPECT_GT(row["landmarks_seen"].get<int>(), 20);  // of 35 in the world
    EXPECT_LE(row["landmarks_seen"].get<int>(), 35);
  }
  EXPECT_NE(Slurp(single + "/summary.md").find("| ekf | 1 / 1: 100 % (3–100), paper 79 % |"), std::string::npos)
      << Slurp(single + "/summary.md");
}

// A study with series (combined-slam): series.csv and the curves in the summary merge to
// the same bytes too.
TEST(CombinedSlamStudy, SlicesWithSeriesMergeToTheSingleRunsBytes) {
  absl::StatusOr<std::unique_ptr<Study>> study = MakeStudy("combined-slam");
  ASSERT_TRUE(study.ok());
  StudyOptions o;
  o.trials = 3;
  o.methods = {"ekf-eif"};
  o.out_dir = FreshDir("combined_single");
  ASSERT_TRUE(RunStudy(**study, o).ok());
  std::vector<std::string> slices;
  for (int k = 1; k <= 2; ++k) {
    StudyOptions slice = o;
    slice.workers = 1;
    slice.shard = {k, 2};
    slice.out_dir = FreshDir(absl::StrCat("combined_slice", k));
    ASSERT_TRUE(RunStudy(**study, slice).ok());
    slices.push_back(slice.out_dir);
  }
  const std::string merged = FreshDir("combined_merged");
  ASSERT_TRUE(MergeStudy(slices, merged).ok());
  for (const char* file : {"runs.csv", "series.csv", "summary.json", "summary.md", "config.json"}) {
    EXPECT_EQ(Slurp(merged + "/" + file), Slurp(o.out_dir + "/" + file)) << file;
  }
}

// The Monte Carlo studies' tables: one row per method (and setting), curves of equal
// length with the χ² band of as many runs around the dof, and ranges a run can reach.
TEST(MonteCarloStudies, TablesHaveTheirShapeAndRanges) {
  struct Case {
    std::string study;
    int trials;
    std::vector<std::string> methods;
    size_t rows;
  };
  for (const Case& c :
       {Case{"fmj", 5, {}, 6}, Case{"iseif", 3, {}, 3}, Case{"combined-slam", 2, {"rbpf-eif", "ekfslam"}, 2}}) {
    SCOPED_TRACE(c.study);
    absl::StatusOr<std::unique_ptr<Study>> study = MakeStudy(c.study);
    ASSERT_TRUE(study.ok());
    StudyOptions o;
    o.trials = c.trials;
    o.methods = c.methods;
    o.out_dir = FreshDir(c.study);
    ASSERT_TRUE(RunStudy(**study, o).ok());
    const json summary = json::parse(Slurp(o.out_dir + "/summary.json"));
    ASSERT_EQ(summary["rows"].size(), c.rows);
    for (const json& row : summary["rows"]) {
      SCOPED_TRACE(row["method"].get<std::string>());
      EXPECT_EQ(row["trials"], c.trials);
      const json& curve = row["curve"];
      const size_t n = curve["t_s"].size();
      EXPECT_GT(n, 10u);
      EXPECT_EQ(row["anees_times"].get<size_t>(), n);
      for (const char* key : {"anees", "band_low", "band_high", "mean_ci", "rms_position_m", "runs"}) {
        EXPECT_EQ(curve[key].size(), n) << key;
      }
      for (size_t i = 0; i < n; ++i) {
        EXPECT_LT(curve["band_low"][i].get<double>(), 3.0);
        EXPECT_GT(curve["band_high"][i].get<double>(), 3.0);
        EXPECT_GT(curve["anees"][i].get<double>(), 0.0);
        EXPECT_GE(curve["rms_position_m"][i].get<double>(), 0.0);
        EXPECT_GE(curve["runs"][i].get<int>(), 1);  // fewer near the end: runs differ in length
        EXPECT_LE(curve["runs"][i].get<int>(), c.trials);
      }
      for (const char* key : {"anees_inside_band", "mean_ci_below_one"}) {
        EXPECT_GE(row[key].get<double>(), 0.0);
        EXPECT_LE(row[key].get<double>(), 1.0);
      }
      EXPECT_LE(row["successes"].get<int>(), c.trials);
      EXPECT_GT(row["mean_map_rms_x_m"].get<double>(), 0.0);
      EXPECT_FALSE(row["paper"].get<std::string>().empty());
    }
    if (c.study == "combined-slam") {
      // The paper's finding, on two runs: the joined RBPF local maps stay consistent far
      // more often than single-map EKF-SLAM, which diverges on the 4 km loop.
      EXPECT_GT(summary["rows"][0]["anees_inside_band"].get<double>(), 0.9);
      EXPECT_LT(summary["rows"][1]["anees_inside_band"].get<double>(), 0.5);
    }
    EXPECT_NE(Slurp(o.out_dir + "/timings.md").find("| method | wall_s | estimator_s"), std::string::npos);
  }
}

TEST(StudyRunner, BadRequestsGetAClearError) {
  EXPECT_FALSE(MakeStudy("nope").ok());
  absl::StatusOr<std::unique_ptr<Study>> study = MakeStudy("hybridslam");
  ASSERT_TRUE(study.ok());
  StudyOptions o = Options(FreshDir("bad_method"), 1);
  o.methods = {"ekf", "gtsam"};
  absl::Status s = RunStudy(**study, o);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("gtsam"), std::string::npos) << s;
  o.methods.clear();
  o.out_dir.clear();
  EXPECT_FALSE(RunStudy(**study, o).ok());
  EXPECT_FALSE(MergeStudy({FreshDir("absent")}, FreshDir("bad")).ok());
  o.out_dir = FreshDir("dataset_for_hybridslam");
  o.dataset_dir = "/somewhere";
  s = RunStudy(**study, o);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("real data set"), std::string::npos) << s;
}

// A merge refuses slices that do not make one study, naming the file: unreadable or
// different configurations, a slice cut short, a table of other columns.
TEST(StudyMerge, RefusesSlicesThatDoNotBelongTogether) {
  absl::StatusOr<std::unique_ptr<Study>> study = MakeStudy("fmj");
  ASSERT_TRUE(study.ok());
  std::vector<std::string> slices;
  for (int k = 1; k <= 2; ++k) {
    StudyOptions o;
    o.trials = 1;
    o.methods = {"ekfslam"};
    o.workers = 1;
    o.shard = {k, 2};
    o.out_dir = FreshDir(absl::StrCat("merge_slice", k));
    ASSERT_TRUE(RunStudy(**study, o).ok());
    slices.push_back(o.out_dir);
  }
  ASSERT_TRUE(MergeStudy(slices, FreshDir("merge_good")).ok());
  // Slice 2 altered one way at a time, in a copy.
  const auto expect_refused = [&](const std::string& name, const std::string& file, const std::string& content,
                                  const std::string& message) {
    SCOPED_TRACE(name);
    const std::string altered = FreshDir(absl::StrCat("merge_", name));
    std::filesystem::copy(slices[1], altered);
    std::ofstream(altered + "/" + file) << content;
    const absl::Status s = MergeStudy({slices[0], altered}, FreshDir("merge_bad"));
    ASSERT_FALSE(s.ok());
    EXPECT_NE(s.message().find(message), std::string::npos) << s;
  };
  const std::string config = Slurp(slices[1] + "/config.json");
  const std::string runs = Slurp(slices[1] + "/runs.csv");
  expect_refused("not_json", "config.json", "{\"study\": ", "config.json");
  json other = json::parse(config);
  other["trials"] = 2;
  expect_refused("other_trials", "config.json", other.dump(), "another study, trial count or configuration");
  expect_refused("cut_short", "runs.csv", runs.substr(0, runs.rfind('\n', runs.size() - 2) + 1), "slices hold");
  expect_refused("other_columns", "runs.csv", "run,method\n", "columns are not the study's");
}

// The ISEIF study's real-data table (Victoria Park, the paper's Table 3): SEIF's and
// ISEIF's errors against the GPS below the paper's (7.53 / 5.38 m and 4.71 / 4.83 m).
TEST(IseifStudy, VictoriaParkTableBelowThePapersErrors) {
  const std::string vp = testing::VictoriaParkDir();
  if (!std::filesystem::exists(vp + "/dataset.json")) GTEST_SKIP() << "no Victoria Park data at " << vp;
  absl::StatusOr<std::unique_ptr<Study>> study = MakeStudy("iseif");
  ASSERT_TRUE(study.ok());
  StudyOptions o;
  o.trials = 1;
  o.methods = {"seif-vp", "iseif-vp"};
  o.dataset_dir = vp;
  o.out_dir = FreshDir("iseif_vp");
  ASSERT_TRUE(RunStudy(**study, o).ok());
  const json summary = json::parse(Slurp(o.out_dir + "/summary.json"));
  ASSERT_EQ(summary["rows"].size(), 2u);
  for (const json& row : summary["rows"]) {
    SCOPED_TRACE(row.dump());
    EXPECT_TRUE(row["dataset"].get<bool>());
    EXPECT_LT(row["gps_rms_x_m"].get<double>(), 4.71);
    EXPECT_LT(row["gps_rms_y_m"].get<double>(), 4.83);
  }
  EXPECT_NE(Slurp(o.out_dir + "/summary.md").find("Victoria Park"), std::string::npos);
}

// Every method's recorded command (config.json), run with the tool, measures what the
// study measured for it: the configuration a user reads is the one that ran.
TEST(HybridSlamStudy, EachMethodIsItsRecordedCommand) {
  absl::StatusOr<std::unique_ptr<Study>> study = MakeStudy("hybridslam");
  ASSERT_TRUE(study.ok());
  const std::string dir = FreshDir("commands");
  StudyOptions o;
  o.trials = 1;
  o.shard = {1, 4};  // with one trial: one run of each of the five methods
  o.out_dir = dir;
  ASSERT_TRUE(RunStudy(**study, o).ok());
  absl::StatusOr<RunTable> runs = RunTable::Read(dir + "/runs.csv");
  ASSERT_TRUE(runs.ok());
  ASSERT_EQ(runs->num_rows(), 5);
  const json config = json::parse(Slurp(dir + "/config.json"));
  for (int r = 0; r < runs->num_rows(); ++r) {
    const std::string method = *runs->Text(r, "method");
    SCOPED_TRACE(method);
    std::string command;
    for (const json& m : config["configuration"]["methods"]) {
      if (m["method"] == method) command = m["command"];
    }
    ASSERT_FALSE(command.empty());
    const std::string out = FreshDir(absl::StrCat("command_", method));
    command = absl::StrReplaceAll(command, {{"subslam ", absl::StrCat(SUBSLAM_TOOL, " ")},
                                            {"TRIAL", *runs->Text(r, "trial")},
                                            {"ALPHA", *runs->Text(r, "alpha")},
                                            {"BETA", *runs->Text(r, "beta")}});
    ASSERT_EQ(std::system(absl::StrCat(command, " --quiet --progress=false --out ", out).c_str()), 0) << command;
    const json metrics = json::parse(Slurp(out + "/report.json"))["metrics"];
    const json& online = metrics.contains("trajectory_online") ? metrics["trajectory_online"] : metrics["trajectory"];
    EXPECT_EQ(online["rms_position_m"].get<double>(), *runs->Number(r, "rms_online_m"));
    EXPECT_EQ(metrics["trajectory"]["rms_position_m"].get<double>(), *runs->Number(r, "rms_final_m"));
    EXPECT_EQ(online["failed_10_sigma_test"].get<bool>() ? 0.0 : 1.0, *runs->Number(r, "success"));
    EXPECT_EQ(metrics["map"]["duplicates"].get<double>(), *runs->Number(r, "duplicates"));
  }
}

// The tool refuses a run or join flag given to `subslam study` (its methods carry their
// papers' settings, so the flag would change nothing) and runs no trial.
TEST(StudyTool, RefusesFlagsItDoesNotRead) {
  const std::string dir = FreshDir("refused_flags");
  std::filesystem::create_directories(dir);
  const std::string err = dir + "/stderr.txt";
  for (const std::string flags : {"--join_merge_loops=false --particles 7", "--backend ceres"}) {
    SCOPED_TRACE(flags);
    const std::string command = absl::StrCat(SUBSLAM_TOOL, " study fmj --trials 1 --quiet --progress=false --out ", dir,
                                             "/study ", flags, " 2> ", err);
    EXPECT_NE(std::system(command.c_str()), 0);
    const std::string message = Slurp(err);
    EXPECT_NE(message.find("study does not read"), std::string::npos) << message;
    for (const char* name : {"--join_merge_loops", "--particles", "--backend"}) {
      EXPECT_EQ(message.find(absl::StrCat(name, " (read by")) != std::string::npos,
                flags.find(name) != std::string::npos)
          << name;
    }
    EXPECT_FALSE(std::filesystem::exists(dir + "/study/runs.csv"));
  }
  // The flags it reads pass.
  const std::string command = absl::StrCat(SUBSLAM_TOOL, " study fmj --trials 1 --methods ekfslam --plots=false",
                                           " --quiet --progress=false --out ", dir, "/study 2> ", err);
  EXPECT_EQ(std::system(command.c_str()), 0) << Slurp(err);
  EXPECT_TRUE(std::filesystem::exists(dir + "/study/runs.csv"));
}

}  // namespace
}  // namespace subslam::study
