#include "subslam/study/study_runner.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "table_statistics.h"

namespace subslam::study {
namespace {

using nlohmann::json;

std::string Describe(const StudyRun& run) {
  std::string text = absl::StrCat("run ", run.index, " (", run.method);
  for (const auto& [name, value] : run.setting) absl::StrAppend(&text, " ", name, "=", FormatNumber(value));
  absl::StrAppend(&text, ", trial ", run.trial, ", seed ", run.seed, ")");
  return text;
}

std::vector<std::string> RunColumns(const Study& study) {
  std::vector<std::string> columns = {"run", "method"};
  for (const std::string& name : study.setting_names()) columns.push_back(name);
  columns.push_back("trial");
  columns.push_back("seed");
  for (const std::string& name : study.metric_names()) columns.push_back(name);
  return columns;
}

std::vector<std::string> SeriesColumns(const Study& study) {
  std::vector<std::string> columns = {"run"};
  for (const std::string& name : study.series_names()) columns.push_back(name);
  return columns;
}

std::vector<std::string> TimingColumns(const Study& study) {
  std::vector<std::string> columns = {"run", "wall_s"};
  for (const std::string& name : study.timing_names()) columns.push_back(name);
  return columns;
}

absl::Status WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  out.close();
  if (!out) return absl::InternalError(absl::StrCat(path, ": cannot write"));
  return absl::OkStatus();
}

absl::StatusOr<json> ReadJson(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat(path, ": cannot open"));
  try {
    return json::parse(in);
  } catch (const json::exception& e) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": ", e.what()));
  }
}

// The runs of `trials` trials of `methods` (all when empty), with their indices in
// Study::Runs().
std::vector<StudyRun> SelectedRuns(const Study& study, int trials, const std::vector<std::string>& methods,
                                   const std::string& dataset_dir) {
  std::vector<StudyRun> runs = study.Runs(trials, dataset_dir);
  if (!methods.empty()) {
    std::erase_if(runs, [&](const StudyRun& run) {
      return std::find(methods.begin(), methods.end(), run.method) == methods.end();
    });
  }
  return runs;
}

json ConfigJson(const Study& study, int trials, const std::vector<std::string>& methods, const std::string& dataset_dir,
                const Shard& shard, int runs_total) {
  return {{"study", study.name()},
          {"dataset", dataset_dir},
          {"title", study.title()},
          {"trials", trials},
          {"methods", methods.empty() ? study.method_names() : methods},
          {"runs", runs_total},
          {"shard", absl::StrCat(shard.index, "/", shard.count)},
          {"configuration", study.Configuration()}};
}

// Progress on stderr, one line rewritten in place.
class ProgressLine {
 public:
  ProgressLine(bool enabled, std::string name, int total)
      : enabled_(enabled && isatty(fileno(stderr))), name_(std::move(name)), total_(total), start_(absl::Now()) {}
  void Done(int done) {
    if (!enabled_) return;
    const double elapsed = absl::ToDoubleSeconds(absl::Now() - start_);
    const double left = done > 0 ? elapsed * (total_ - done) / done : 0.0;
    std::fprintf(stderr, "\rstudy %s: %d / %d runs, %.0f s elapsed, about %.0f s left   ", name_.c_str(), done, total_,
                 elapsed, left);
    if (done == total_) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  }

 private:
  bool enabled_;
  std::string name_;
  int total_;
  absl::Time start_;
};

// timings.md: per method, the median and minimum of each timing column.
std::string TimingsMarkdown(const Study& study, const RunTable& runs, const RunTable& timings) {
  std::string md =
      absl::StrCat("# ", study.name(), ": run times\n\nWall-clock seconds per run (median / minimum over ",
                   "the runs), each run on one thread; they vary with the machine and its load.\n\n| method |");
  std::string rule = "| --- |";
  for (size_t c = 1; c < timings.columns().size(); ++c) {
    absl::StrAppend(&md, " ", timings.columns()[c], " |");
    absl::StrAppend(&rule, " --- |");
  }
  absl::StrAppend(&md, "\n", rule, "\n");
  std::map<std::string, std::string> method_of_run;
  for (int r = 0; r < runs.num_rows(); ++r) method_of_run[runs.rows()[r][0]] = runs.rows()[r][1];
  for (const std::string& method : study.method_names()) {
    std::vector<int> rows;
    for (int r = 0; r < timings.num_rows(); ++r) {
      if (method_of_run[timings.rows()[r][0]] == method) rows.push_back(r);
    }
    if (rows.empty()) continue;
    absl::StrAppend(&md, "| ", method, " |");
    for (size_t c = 1; c < timings.columns().size(); ++c) {
      const std::vector<double> values = Values(timings, rows, timings.columns()[c]).value_or(std::vector<double>{});
      const double fastest = values.empty() ? std::nan("") : *std::min_element(values.begin(), values.end());
      absl::StrAppend(&md, absl::StrFormat(" %.4g / %.4g |", Median(values), fastest));
    }
    absl::StrAppend(&md, "\n");
  }
  if (!study.paper_timings().empty()) absl::StrAppend(&md, "\n", study.paper_timings(), "\n");
  return md;
}

// Writes the summary of a complete study in `dir` (from its files as read back).
absl::Status Summarize(const Study& study, const std::string& dir) {
  absl::StatusOr<RunTable> runs = RunTable::Read(dir + "/runs.csv");
  if (!runs.ok()) return runs.status();
  RunTable series({});
  if (!study.series_names().empty()) {
    absl::StatusOr<RunTable> read = RunTable::Read(dir + "/series.csv");
    if (!read.ok()) return read.status();
    series = *std::move(read);
  }
  absl::StatusOr<RunTable> timings = RunTable::Read(dir + "/timings.csv");
  if (!timings.ok()) return timings.status();
  absl::StatusOr<json> summary = study.Summarize(*runs, series);
  if (!summary.ok()) return summary.status();
  if (absl::Status s = WriteText(dir + "/summary.json", summary->dump(2) + "\n"); !s.ok()) return s;
  if (absl::Status s = WriteText(dir + "/summary.md", study.SummaryMarkdown(*summary)); !s.ok()) return s;
  return WriteText(dir + "/timings.md", TimingsMarkdown(study, *runs, *timings));
}

}  // namespace

absl::StatusOr<Shard> ShardFromString(const std::string& text) {
  std::vector<std::string> parts = absl::StrSplit(text, '/');
  Shard shard;
  if (parts.size() != 2 || !absl::SimpleAtoi(parts[0], &shard.index) || !absl::SimpleAtoi(parts[1], &shard.count) ||
      shard.count < 1 || shard.index < 1 || shard.index > shard.count) {
    return absl::InvalidArgumentError(absl::StrCat("--shard \"", text, "\": expected K/N with 1 <= K <= N"));
  }
  return shard;
}

namespace {

// The methods asked for are the study's, and a data set is given only to a study that uses one.
absl::Status CheckStudyOptions(const Study& study, const StudyOptions& options) {
  const std::vector<std::string> known = study.method_names();
  for (const std::string& method : options.methods) {
    if (std::find(known.begin(), known.end(), method) == known.end()) {
      return absl::InvalidArgumentError(absl::StrCat("study ", study.name(), " has no method \"", method,
                                                     "\" (methods: ", absl::StrJoin(known, ", "), ")"));
    }
  }
  if (!options.dataset_dir.empty() && !study.uses_dataset()) {
    return absl::InvalidArgumentError(
        absl::StrCat("study ", study.name(), " has no runs on a real data set (--dataset)"));
  }
  return absl::OkStatus();
}

// What the workers measured: one entry per run (empty where it was not run), its wall time,
// and the first error (the workers stop at it).
struct Measurements {
  std::vector<std::optional<RunMeasurement>> measured;
  std::vector<double> wall;
  absl::Status first_error;
};

// Runs `runs` on options.workers threads (0: every core), each run on one thread.
Measurements MeasureRuns(const Study& study, const std::vector<StudyRun>& runs, const StudyOptions& options) {
  const int workers = std::max(
      1, std::min<int>(options.workers > 0 ? options.workers : static_cast<int>(std::thread::hardware_concurrency()),
                       static_cast<int>(runs.size())));
  Measurements out;
  out.measured.resize(runs.size());
  out.wall.assign(runs.size(), 0.0);
  std::vector<std::optional<RunMeasurement>>& measured = out.measured;
  std::vector<double>& wall = out.wall;
  std::atomic<size_t> next{0};
  std::atomic<bool> stop{false};
  std::mutex mutex;  // guards first_error, done, progress
  absl::Status& first_error = out.first_error;
  int done = 0;
  ProgressLine progress(options.progress, study.name(), static_cast<int>(runs.size()));
  auto work = [&] {
    for (size_t i = next++; i < runs.size() && !stop; i = next++) {
      const absl::Time start = absl::Now();
      absl::StatusOr<RunMeasurement> m = study.Execute(runs[i]);
      std::lock_guard<std::mutex> lock(mutex);
      if (!m.ok()) {
        if (first_error.ok())
          first_error = absl::Status(m.status().code(), absl::StrCat(Describe(runs[i]), ": ", m.status().message()));
        stop = true;
        return;
      }
      const bool series_ok = std::all_of(m->series.begin(), m->series.end(), [&](const std::vector<std::string>& row) {
        return row.size() == study.series_names().size();
      });
      if (m->metrics.size() != study.metric_names().size() || m->timings.size() != study.timing_names().size() ||
          !series_ok) {
        if (first_error.ok())
          first_error = absl::InternalError(absl::StrCat(Describe(runs[i]), ": wrong number of values"));
        stop = true;
        return;
      }
      wall[i] = absl::ToDoubleSeconds(absl::Now() - start);
      measured[i] = *std::move(m);
      progress.Done(++done);
    }
  };
  std::vector<std::thread> threads;
  for (int w = 0; w < workers; ++w) threads.emplace_back(work);
  for (std::thread& t : threads) t.join();

  return out;
}

// runs.csv, series.csv, timings.csv and join_times.csv of the runs measured; `rows`: how many.
absl::Status WriteRunTables(const Study& study, const std::vector<StudyRun>& runs, Measurements* m,
                            const std::string& out_dir, int* rows) {
  RunTable table(RunColumns(study));
  RunTable timings(TimingColumns(study));
  RunTable series(SeriesColumns(study));
  RunTable join_times({"run", "join", "seconds"});
  for (size_t i = 0; i < runs.size(); ++i) {
    if (!m->measured[i]) continue;
    const StudyRun& run = runs[i];
    std::vector<std::string> row = {absl::StrCat(run.index), run.method};
    for (const auto& [name, value] : run.setting) row.push_back(FormatNumber(value));
    row.push_back(absl::StrCat(run.trial));
    row.push_back(absl::StrCat(run.seed));
    for (std::string& value : m->measured[i]->metrics) row.push_back(std::move(value));
    if (absl::Status s = table.Add(std::move(row)); !s.ok()) return s;
    std::vector<std::string> timing = {absl::StrCat(run.index), FormatNumber(m->wall[i])};
    for (double t : m->measured[i]->timings) timing.push_back(FormatNumber(t));
    if (absl::Status s = timings.Add(std::move(timing)); !s.ok()) return s;
    for (size_t j = 0; j < m->measured[i]->join_seconds.size(); ++j) {
      if (absl::Status s =
              join_times.Add({absl::StrCat(run.index), absl::StrCat(j), FormatNumber(m->measured[i]->join_seconds[j])});
          !s.ok()) {
        return s;
      }
    }
    for (std::vector<std::string>& values : m->measured[i]->series) {
      std::vector<std::string> row = {absl::StrCat(run.index)};
      for (std::string& value : values) row.push_back(std::move(value));
      if (absl::Status s = series.Add(std::move(row)); !s.ok()) return s;
    }
  }
  if (absl::Status s = table.Write(out_dir + "/runs.csv"); !s.ok()) return s;
  if (!study.series_names().empty()) {
    if (absl::Status s = series.Write(out_dir + "/series.csv"); !s.ok()) return s;
  }
  if (absl::Status s = timings.Write(out_dir + "/timings.csv"); !s.ok()) return s;
  if (join_times.num_rows() > 0) {
    if (absl::Status s = join_times.Write(out_dir + "/join_times.csv"); !s.ok()) return s;
  }
  *rows = table.num_rows();
  return absl::OkStatus();
}

}  // namespace

absl::Status RunStudy(const Study& study, const StudyOptions& options) {
  if (options.out_dir.empty()) return absl::InvalidArgumentError("a study needs an output directory (--out)");
  if (options.trials < 0) return absl::InvalidArgumentError("--trials must be positive");
  const int trials = options.trials > 0 ? options.trials : study.paper_trials();
  if (absl::Status s = CheckStudyOptions(study, options); !s.ok()) return s;
  const std::vector<StudyRun> all = SelectedRuns(study, trials, options.methods, options.dataset_dir);
  std::vector<StudyRun> runs;
  for (const StudyRun& run : all) {
    if (run.index % options.shard.count == options.shard.index - 1) runs.push_back(run);
  }
  std::error_code ec;
  std::filesystem::create_directories(options.out_dir, ec);
  if (ec) return absl::InternalError(absl::StrCat(options.out_dir, ": ", ec.message()));
  const int total_runs = static_cast<int>(all.size());
  if (absl::Status s = WriteText(
          options.out_dir + "/config.json",
          ConfigJson(study, trials, options.methods, options.dataset_dir, options.shard, total_runs).dump(2) + "\n");
      !s.ok()) {
    return s;
  }

  Measurements measured = MeasureRuns(study, runs, options);
  int rows = 0;
  if (absl::Status s = WriteRunTables(study, runs, &measured, options.out_dir, &rows); !s.ok()) return s;
  if (!measured.first_error.ok()) {
    return absl::Status(measured.first_error.code(),
                        absl::StrCat(measured.first_error.message(), " (the ", rows, " runs measured are in ",
                                     options.out_dir, "/runs.csv)"));
  }
  if (options.shard.count > 1) return absl::OkStatus();
  return Summarize(study, options.out_dir);
}

namespace {

// Whether the merged rows are the study's runs, each once.
absl::Status CheckEveryRunOnce(const Study& study, const json& reference, const RunTable& runs,
                               const std::string& first_dir) {
  std::vector<StudyRun> expected;
  try {
    expected =
        SelectedRuns(study, reference.at("trials").get<int>(), reference.at("methods").get<std::vector<std::string>>(),
                     reference.at("dataset").get<std::string>());
  } catch (const json::exception& e) {
    return absl::InvalidArgumentError(absl::StrCat(first_dir, "/config.json: ", e.what()));
  }
  if (runs.num_rows() != static_cast<int>(expected.size())) {
    return absl::InvalidArgumentError(
        absl::StrCat("the slices hold ", runs.num_rows(), " runs of ", expected.size(), " (a slice stopped early?)"));
  }
  for (size_t i = 0; i < expected.size(); ++i) {
    if (runs.rows()[i][0] != absl::StrCat(expected[i].index)) {
      return absl::InvalidArgumentError(absl::StrCat("run ", expected[i].index, " is missing or given twice"));
    }
  }
  return absl::OkStatus();
}

// The merged study's config.json and tables in `out_dir`.
absl::Status WriteMerged(const Study& study, const json& reference, const RunTable& runs, const RunTable& timings,
                         const RunTable& series, const RunTable& join_times, const std::string& out_dir) {
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) return absl::InternalError(absl::StrCat(out_dir, ": ", ec.message()));
  json config = reference;
  config["shard"] = "1/1";
  if (absl::Status s = WriteText(out_dir + "/config.json", config.dump(2) + "\n"); !s.ok()) return s;
  if (absl::Status s = runs.Write(out_dir + "/runs.csv"); !s.ok()) return s;
  if (absl::Status s = timings.Write(out_dir + "/timings.csv"); !s.ok()) return s;
  if (join_times.num_rows() > 0) {
    if (absl::Status s = join_times.Write(out_dir + "/join_times.csv"); !s.ok()) return s;
  }
  if (!study.series_names().empty()) {
    if (absl::Status s = series.Write(out_dir + "/series.csv"); !s.ok()) return s;
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status MergeStudy(const std::vector<std::string>& shard_dirs, const std::string& out_dir) {
  if (shard_dirs.empty()) return absl::InvalidArgumentError("merge needs the slices' directories");
  if (out_dir.empty()) return absl::InvalidArgumentError("merge needs an output directory (--out)");
  std::optional<json> reference;
  std::unique_ptr<Study> study;
  std::set<int> slices;
  int count = 0;
  std::optional<RunTable> runs, timings, series;
  RunTable join_times({"run", "join", "seconds"});
  for (const std::string& dir : shard_dirs) {
    absl::StatusOr<json> config = ReadJson(dir + "/config.json");
    if (!config.ok()) return config.status();
    absl::StatusOr<Shard> shard = ShardFromString(
        config->contains("shard") && (*config)["shard"].is_string() ? (*config)["shard"].get<std::string>() : "");
    if (!shard.ok())
      return absl::InvalidArgumentError(absl::StrCat(dir, "/config.json: field shard: ", shard.status().message()));
    json same = *config;
    same.erase("shard");
    if (!reference) {
      reference = same;
      count = shard->count;
      absl::StatusOr<std::unique_ptr<Study>> made = MakeStudy(same.value("study", ""));
      if (!made.ok())
        return absl::InvalidArgumentError(absl::StrCat(dir, "/config.json: field study: ", made.status().message()));
      study = *std::move(made);
    } else if (same != *reference) {
      return absl::InvalidArgumentError(absl::StrCat(
          dir, "/config.json: another study, trial count or configuration than ", shard_dirs.front(), "/config.json"));
    } else if (shard->count != count) {
      return absl::InvalidArgumentError(
          absl::StrCat(dir, ": slice ", shard->index, "/", shard->count, ", the others are of ", count));
    }
    if (!slices.insert(shard->index).second) {
      return absl::InvalidArgumentError(absl::StrCat(dir, ": slice ", shard->index, "/", count, " given twice"));
    }
    absl::StatusOr<RunTable> part = RunTable::Read(dir + "/runs.csv");
    if (!part.ok()) return part.status();
    absl::StatusOr<RunTable> part_timings = RunTable::Read(dir + "/timings.csv");
    if (!part_timings.ok()) return part_timings.status();
    if (std::filesystem::exists(dir + "/join_times.csv")) {
      absl::StatusOr<RunTable> part_joins = RunTable::Read(dir + "/join_times.csv");
      if (!part_joins.ok()) return part_joins.status();
      for (const auto& row : part_joins->rows()) {
        if (absl::Status s = join_times.Add(row); !s.ok()) return s;
      }
    }
    if (part->columns() != RunColumns(*study))
      return absl::InvalidArgumentError(absl::StrCat(dir, "/runs.csv: columns are not the study's"));
    if (!runs) {
      runs.emplace(part->columns());
      timings.emplace(part_timings->columns());
      series.emplace(SeriesColumns(*study));
    }
    if (!study->series_names().empty()) {
      absl::StatusOr<RunTable> part_series = RunTable::Read(dir + "/series.csv");
      if (!part_series.ok()) return part_series.status();
      if (part_series->columns() != series->columns()) {
        return absl::InvalidArgumentError(absl::StrCat(dir, "/series.csv: columns are not the study's"));
      }
      for (const auto& row : part_series->rows()) {
        if (absl::Status s = series->Add(row); !s.ok()) return s;
      }
    }
    for (const auto& row : part->rows()) {
      if (absl::Status s = runs->Add(row); !s.ok()) return s;
    }
    for (const auto& row : part_timings->rows()) {
      if (absl::Status s = timings->Add(row); !s.ok()) return s;
    }
  }
  if (static_cast<int>(slices.size()) != count) {
    std::vector<int> missing;
    for (int k = 1; k <= count; ++k) {
      if (!slices.contains(k)) missing.push_back(k);
    }
    return absl::InvalidArgumentError(absl::StrCat("slices missing: ", absl::StrJoin(missing, ", "), " of ", count));
  }
  if (absl::Status s = runs->SortBy("run"); !s.ok()) return s;
  if (absl::Status s = timings->SortBy("run"); !s.ok()) return s;
  if (absl::Status s = series->SortBy("run"); !s.ok()) return s;  // stable: each run's rows keep their order
  if (absl::Status s = join_times.SortBy("run"); !s.ok()) return s;
  if (absl::Status s = CheckEveryRunOnce(*study, *reference, *runs, shard_dirs.front()); !s.ok()) return s;
  if (absl::Status s = WriteMerged(*study, *reference, *runs, *timings, *series, join_times, out_dir); !s.ok()) {
    return s;
  }
  return Summarize(*study, out_dir);
}

}  // namespace subslam::study
