#include "subslam/app/run_pipeline.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "subslam/io/dataset_reader.h"
#include "subslam/io/dataset_writer.h"
#include "subslam/io/run_output_writer.h"
#include "subslam/sim/simulator.h"
#include "test_util.h"

namespace subslam::app {
namespace {

namespace fs = std::filesystem;

TEST(RunPipeline, WritesOutputsWithMetrics) {
  sim::ScenarioOptions o;
  o.seed = 1;
  o.duration_s = 60;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("hybrid-120m", o);
  ASSERT_TRUE(d.ok());
  RunOptions options;
  options.out_dir = ::testing::TempDir() + "/subslam_run_outputs";
  fs::remove_all(options.out_dir);
  absl::StatusOr<RunResult> r = RunPipeline(*d, options);
  ASSERT_TRUE(r.ok()) << r.status();
  for (const char* f : {"trajectory_online.csv", "trajectory_final.csv", "landmarks.csv", "report.json"}) {
    EXPECT_TRUE(fs::exists(fs::path(options.out_dir) / f)) << f;
  }
  absl::StatusOr<Trajectory> back = io::ReadTrajectoryCsv(options.out_dir + "/trajectory_online.csv");
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->size(), r->online.size());
  std::ifstream report(options.out_dir + "/report.json");
  const nlohmann::json j = nlohmann::json::parse(report);
  EXPECT_EQ(j["configuration"]["frontend"], "ekfslam");
  EXPECT_TRUE(j["metrics"]["trajectory"].contains("mean_pose_nees"));
  EXPECT_TRUE(j["metrics"]["map"].contains("rms_m"));
  EXPECT_TRUE(j["time_seconds"]["stages"].contains("update"));
  EXPECT_FALSE(SummaryTable(*r).empty());
}

TEST(RunPipeline, SimulatedFilesGiveTheSameRunAsMemory) {
  sim::ScenarioOptions o;
  o.seed = 2;
  o.duration_s = 40;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("iseif-circle", o);
  ASSERT_TRUE(d.ok());
  const std::string dir = ::testing::TempDir() + "/subslam_same_run";
  ASSERT_TRUE(io::WriteDataset(*d, dir).ok());
  absl::StatusOr<io::Dataset> read = io::ReadDataset(dir);
  ASSERT_TRUE(read.ok()) << read.status();
  absl::StatusOr<RunResult> a = RunPipeline(*d, {});
  absl::StatusOr<RunResult> b = RunPipeline(*read, {});
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->online.size(), b->online.size());
  EXPECT_EQ(a->online.back().pose.x, b->online.back().pose.x);
  EXPECT_EQ(a->landmarks.size(), b->landmarks.size());
}

TEST(RunPipeline, RejectsBadOverrides) {
  sim::ScenarioOptions o;
  o.duration_s = 5;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("hybrid-120m", o);
  ASSERT_TRUE(d.ok());
  RunOptions options;
  options.noise.sigma_range = -1.0;
  EXPECT_FALSE(RunPipeline(*d, options).ok());
}

// The acceptance run on real data: EKF-SLAM on Victoria Park, aligned against
// GPS, far below dead reckoning.
TEST(RunPipeline, VictoriaParkEkfSlamBeatsDeadReckoning) {
  const std::string dir = testing::VictoriaParkDir();
  if (!fs::exists(dir + "/dataset.json")) GTEST_SKIP() << "no Victoria Park data at " << dir;
  absl::StatusOr<io::Dataset> d = io::ReadDataset(dir);
  ASSERT_TRUE(d.ok()) << d.status();
  RunOptions odometry;
  odometry.frontend = Frontend::kOdometry;
  absl::StatusOr<RunResult> dr = RunPipeline(*d, odometry);
  absl::StatusOr<RunResult> ekf = RunPipeline(*d, {});
  ASSERT_TRUE(dr.ok() && ekf.ok());
  ASSERT_TRUE(dr->gps_final.has_value() && ekf->gps_final.has_value());
  EXPECT_GT(ekf->gps_final->matched_fixes, 4000);
  EXPECT_LT(ekf->gps_final->rms_m, 6.0);
  EXPECT_LT(ekf->gps_final->rms_m, 0.2 * dr->gps_final->rms_m);
}

TEST(RunPipeline, SeifAndIseifRunWithTheirReport) {
  sim::ScenarioOptions o;
  o.seed = 2;
  o.duration_s = 60;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("hybrid-120m", o);
  ASSERT_TRUE(d.ok());
  for (Frontend f : {Frontend::kSeif, Frontend::kIseif}) {
    RunOptions options;
    options.frontend = f;
    options.seif.iterated.period_scans = 10;
    absl::StatusOr<RunResult> r = RunPipeline(*d, options);
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_EQ(r->frontend, ToString(f));
    EXPECT_EQ(r->report["configuration"]["seif"]["iterated"], f == Frontend::kIseif);
    EXPECT_TRUE(r->report["time_seconds"]["stages"].contains("sparsification"));
    EXPECT_EQ(r->report["estimator_counters"]["iterated_updates"].get<double>() > 0, f == Frontend::kIseif);
    ASSERT_TRUE(r->errors.has_value());
    EXPECT_LT(r->errors->rms_position_m, 1.0);
    EXPECT_FALSE(r->landmarks.empty());
  }
}

TEST(RunPipeline, SeifKnownAssociationNeedsTrueIds) {
  sim::ScenarioOptions o;
  o.duration_s = 10;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("hybrid-120m", o);
  ASSERT_TRUE(d.ok());
  d->sensor.has_truth_id = false;
  RunOptions options;
  options.frontend = Frontend::kSeif;
  options.seif.known_association = true;
  absl::StatusOr<RunResult> r = RunPipeline(*d, options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("true ids"), std::string::npos) << r.status();
  options.seif.max_active_landmarks = -1;
  options.seif.known_association = false;
  EXPECT_FALSE(RunPipeline(*d, options).ok());
}

// The paper's Table 3 (SEIF 7.53 / 5.38 m, ISEIF 4.71 / 4.83 m per axis) as an upper bound.
TEST(RunPipeline, VictoriaParkSeifAndIseifBelowThePapersErrors) {
  const std::string dir = testing::VictoriaParkDir();
  if (!fs::exists(dir + "/dataset.json")) GTEST_SKIP() << "no Victoria Park data at " << dir;
  absl::StatusOr<io::Dataset> d = io::ReadDataset(dir);
  ASSERT_TRUE(d.ok()) << d.status();
  for (Frontend f : {Frontend::kSeif, Frontend::kIseif}) {
    RunOptions options;
    options.frontend = f;
    absl::StatusOr<RunResult> r = RunPipeline(*d, options);
    ASSERT_TRUE(r.ok()) << r.status();
    ASSERT_TRUE(r->gps_final.has_value());
    EXPECT_GT(r->gps_final->matched_fixes, 4000);
    EXPECT_LT(r->gps_final->rms_x_m, f == Frontend::kSeif ? 7.53 : 4.71) << ToString(f);
    EXPECT_LT(r->gps_final->rms_y_m, f == Frontend::kSeif ? 5.38 : 4.83) << ToString(f);
  }
}

}  // namespace
}  // namespace subslam::app
