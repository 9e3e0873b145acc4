#include "subslam/pipeline/run_pipeline.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>

#include "subslam/io/dataset_reader.h"
#include "subslam/io/dataset_writer.h"
#include "subslam/io/run_output_writer.h"
#include "subslam/pipeline/join_pipeline.h"
#include "subslam/sim/simulator.h"
#include "test_util.h"

namespace subslam::pipeline {
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

  // The TUM trajectory (t x y z qx qy qz qw) is the online one, its heading a rotation
  // about z; the ground truth and the per-step errors are beside it.
  std::ifstream tum(options.out_dir + "/trajectory_online.tum");
  std::vector<std::array<double, 8>> poses;
  for (std::array<double, 8> p; tum >> p[0] >> p[1] >> p[2] >> p[3] >> p[4] >> p[5] >> p[6] >> p[7];)
    poses.push_back(p);
  ASSERT_EQ(poses.size(), r->online.size());
  for (size_t k = 0; k < poses.size(); k += 97) {
    EXPECT_NEAR(poses[k][1], r->online[k].pose.x, 1e-6);
    EXPECT_NEAR(poses[k][3], 0.0, 0.0);
    EXPECT_NEAR(2 * std::atan2(poses[k][6], poses[k][7]), r->online[k].pose.theta, 1e-8);
  }
  for (const char* f : {"truth.tum", "truth_trajectory.csv", "truth_landmarks.csv", "trajectory_final.tum"}) {
    EXPECT_TRUE(fs::exists(fs::path(options.out_dir) / f)) << f;
  }
  std::ifstream errors(options.out_dir + "/pose_errors.csv");
  std::string line;
  std::getline(errors, line);
  EXPECT_EQ(line,
            "t,online_position_error_m,online_heading_error_rad,online_nees,final_position_error_m,"
            "final_heading_error_rad,final_nees");
  size_t lines = 0;
  while (std::getline(errors, line)) ++lines;
  EXPECT_EQ(lines, r->online.size());
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

// --sensor_yaw adds to every bearing (wrapped); a non-finite value is an error.
TEST(RunPipeline, SensorYawRotatesEveryBearing) {
  sim::ScenarioOptions o;
  o.duration_s = 5;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("hybrid-120m", o);
  ASSERT_TRUE(d.ok());
  io::Dataset rotated = *d;
  NoiseOverrides yaw;
  yaw.sensor_yaw = 0.25;
  ASSERT_TRUE(yaw.ApplyTo(&rotated).ok());
  long checked = 0;
  for (size_t s = 0; s < d->scans.size(); ++s) {
    for (size_t k = 0; k < d->scans[s].detections.size(); ++k) {
      EXPECT_NEAR(WrapAngle(rotated.scans[s].detections[k].bearing_rad - d->scans[s].detections[k].bearing_rad), 0.25,
                  1e-12);
      EXPECT_LE(std::abs(rotated.scans[s].detections[k].bearing_rad), kPi);
      ++checked;
    }
  }
  EXPECT_GT(checked, 50);
  yaw.sensor_yaw = NAN;
  EXPECT_FALSE(yaw.ApplyTo(&rotated).ok());
}

// EKF-SLAM's innovation likelihood identifies a sensor mounted with a yaw error: with
// every bearing of a simulated run rotated by +0.03 rad, the innovations are most
// likely (per dimension) when the correction is −0.03, less so at 0 or −0.06.
// hybrid-120m (seed, optionally cut to `duration_s`) with every bearing turned by `yaw`: what
// a sensor mounted with that yaw error sees.
absl::StatusOr<io::Dataset> MisalignedHybrid(uint64_t seed, double yaw,
                                             std::optional<double> duration_s = std::nullopt) {
  sim::ScenarioOptions o;
  o.seed = seed;
  o.duration_s = duration_s;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("hybrid-120m", o);
  if (!d.ok()) return d.status();
  NoiseOverrides misalign;
  misalign.sensor_yaw = yaw;
  if (absl::Status s = misalign.ApplyTo(&*d); !s.ok()) return s;
  return d;
}

TEST(RunPipeline, InnovationLikelihoodFindsAMisalignedSensor) {
  absl::StatusOr<io::Dataset> d = MisalignedHybrid(3, 0.03, 120.0);
  ASSERT_TRUE(d.ok()) << d.status();
  const auto nll_per_dof = [&](double correction) {
    RunOptions options;
    options.noise.sensor_yaw = correction;
    absl::StatusOr<RunResult> r = RunPipeline(*d, options);
    EXPECT_TRUE(r.ok()) << r.status();
    const nlohmann::json& c = r->report["estimator_counters"];
    EXPECT_GT(c["innovation_dof"].get<double>(), 1000);
    return c["innovation_neg_log_likelihood"].get<double>() / c["innovation_dof"].get<double>();
  };
  const double right = nll_per_dof(-0.03);
  EXPECT_LT(right, nll_per_dof(0.0));
  EXPECT_LT(right, nll_per_dof(-0.06));
}

// The single-map baseline on real data: EKF-SLAM on Victoria Park, aligned against
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

TEST(RunPipeline, KnownAssociationNeedsTrueIds) {
  sim::ScenarioOptions o;
  o.duration_s = 10;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("hybrid-120m", o);
  ASSERT_TRUE(d.ok());
  d->sensor.has_truth_id = false;
  RunOptions options;
  options.frontend = Frontend::kSeif;
  options.seif.landmarks.known_association = true;
  absl::StatusOr<RunResult> r = RunPipeline(*d, options);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("true ids"), std::string::npos) << r.status();
  options.seif.max_active_landmarks = -1;
  options.seif.landmarks.known_association = false;
  EXPECT_FALSE(RunPipeline(*d, options).ok());
  // The same for the local mappers and the back-end (--known_association reaches all).
  RunOptions rbpf;
  rbpf.frontend = Frontend::kRbpf;
  rbpf.fastslam.landmarks.known_association = true;
  r = RunPipeline(*d, rbpf);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("true ids"), std::string::npos) << r.status();
  RunOptions ekf_eif;
  ekf_eif.frontend = Frontend::kEkfLocal;
  ekf_eif.backend.kind = Backend::kEif;
  ekf_eif.backend.eif.association.known_association = true;
  EXPECT_FALSE(RunPipeline(*d, ekf_eif).ok());
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

// RBPF local maps joined by the EIF on Victoria Park with `yaw` applied to the bearings and
// `yaw_sigma` for the particles' own yaws, the online yaw calibration on or off; nullopt
// when the data set is absent.
std::optional<RunResult> RunVictoriaParkRbpfEif(double yaw, double yaw_sigma, bool online_calibration) {
  const std::string dir = testing::VictoriaParkDir();
  if (!fs::exists(dir + "/dataset.json")) return std::nullopt;
  absl::StatusOr<io::Dataset> d = io::ReadDataset(dir);
  EXPECT_TRUE(d.ok()) << d.status();
  if (!d.ok()) return std::nullopt;
  RunOptions options;
  options.frontend = Frontend::kRbpf;
  options.backend.kind = Backend::kEif;
  options.noise.sensor_yaw = yaw;
  options.fastslam.sensor_yaw_sigma = yaw_sigma;
  options.backend.sensor_yaw.enabled = online_calibration;
  absl::StatusOr<RunResult> r = RunPipeline(*d, options);
  EXPECT_TRUE(r.ok()) << r.status();
  if (!r.ok() || !r->gps_final.has_value()) return std::nullopt;
  return *std::move(r);
}

// The submap pipeline on real data with the sensor yaw estimated by maximum likelihood from
// EKF-SLAM's innovations (−0.0182 rad, bench/sensor_yaw_calibration; GPS plays no part in
// it): below the ISEIF paper's Victoria Park errors per axis (4.71 m / 4.83 m).
TEST(RunPipeline, VictoriaParkRbpfEifWithCalibratedYawBelowThePapersErrors) {
  if (!fs::exists(testing::VictoriaParkDir() + "/dataset.json")) GTEST_SKIP() << "no Victoria Park data";
  const std::optional<RunResult> r = RunVictoriaParkRbpfEif(-0.0182, 0.0, /*online_calibration=*/false);
  ASSERT_TRUE(r.has_value());
  EXPECT_GT(r->gps_final->matched_fixes, 4000);
  EXPECT_LT(r->gps_final->rms_x_m, 4.71);
  EXPECT_LT(r->gps_final->rms_y_m, 4.83);
}

// Without the calibration, the particles' sensor yaws (sensor_yaw_sigma) make each local
// map's covariance carry a rotation of its bearings, so consecutive maps agree on the
// same trees: RBPF + EIF below single-map EKF-SLAM's error against GPS (2.26 m).
TEST(RunPipeline, VictoriaParkRbpfEifWithTheSensorYawSpreadPerLocalMapBelowEkfSlam) {
  if (!fs::exists(testing::VictoriaParkDir() + "/dataset.json")) GTEST_SKIP() << "no Victoria Park data";
  const std::optional<RunResult> r = RunVictoriaParkRbpfEif(0.0, 0.01, /*online_calibration=*/false);
  ASSERT_TRUE(r.has_value());
  EXPECT_LT(r->gps_final->rms_m, 2.26);
}

// At the defaults, with no calibration given, the back-end's online yaw calibration turns the
// local maps so that consecutive ones agree: within 3 m of GPS (without it, 11-25 m over
// filter seeds), the correction negative as the offline calibration's, and nine maps in ten
// or more joined turned.
TEST(RunPipeline, VictoriaParkRbpfEifCalibratesTheSensorYawOnline) {
  if (!fs::exists(testing::VictoriaParkDir() + "/dataset.json")) GTEST_SKIP() << "no Victoria Park data";
  const std::optional<RunResult> r = RunVictoriaParkRbpfEif(0.0, 0.0, /*online_calibration=*/true);
  ASSERT_TRUE(r.has_value());
  EXPECT_LT(r->gps_final->rms_m, 3.0);
  const nlohmann::json& c = r->report["estimator_counters"];
  const double correction = c["sensor_yaw_correction"].get<double>();
  const double sigma = c["sensor_yaw_correction_sigma"].get<double>();
  EXPECT_LT(correction + 5.0 * sigma, 0.0);
  EXPECT_GT(c["sensor_yaw_maps_turned"].get<double>(), 0.9 * c["local_maps_closed"].get<double>());
}

// A simulated sensor turned by 1° (every bearing of hybrid-120m + 0.0175 rad): without the
// online calibration the local maps disagree and the run ends over a metre off with
// duplicates (1.2 m, 9 on this seed); with it the correction comes out near −0.0175 and the
// run ends as an aligned sensor's does (0.16 m).
TEST(RunPipeline, OnlineYawCalibrationUndoesASimulatedMisalignment) {
  absl::StatusOr<io::Dataset> d = MisalignedHybrid(1, 0.0175);
  ASSERT_TRUE(d.ok()) << d.status();
  const auto run = [&](bool calibrate) {
    RunOptions options;
    options.frontend = Frontend::kRbpf;
    options.backend.kind = Backend::kEif;
    options.backend.sensor_yaw.enabled = calibrate;
    absl::StatusOr<RunResult> r = RunPipeline(*d, options);
    EXPECT_TRUE(r.ok()) << r.status();
    return *std::move(r);
  };
  const RunResult off = run(false);
  const RunResult on = run(true);
  const nlohmann::json& c = on.report["estimator_counters"];
  EXPECT_NEAR(c["sensor_yaw_correction"].get<double>(), -0.0175, 0.1 * 0.0175);
  EXPECT_EQ(c["sensor_yaw_joiner_restarts"].get<double>(), 1);  // the warm-up's maps joined again, turned
  const auto final_rms = [](const RunResult& r) {
    return r.report["metrics"]["trajectory"]["rms_position_m"].get<double>();
  };
  const auto duplicates = [](const RunResult& r) { return r.report["metrics"]["map"]["duplicates"].get<int>(); };
  EXPECT_LT(final_rms(on), 0.3);
  EXPECT_GT(final_rms(off), 1.0);
  EXPECT_LE(duplicates(on), 1);
  EXPECT_GE(duplicates(off), 5);  // 9 on this seed
  // `subslam join` on the run's recorded maps calibrates them the same way: the same map.
  JoinOptions join;
  join.initial_pose = d->initial_pose;
  join.backend.kind = Backend::kEif;
  absl::StatusOr<JoinResult> j = RunJoin(on.local_maps, join);
  ASSERT_TRUE(j.ok()) << j.status();
  ASSERT_EQ(j->landmarks.size(), on.landmarks.size());
  for (size_t k = 0; k < on.landmarks.size(); ++k) {
    EXPECT_LT((j->landmarks[k].position - on.landmarks[k].position).norm(), 1e-9) << "landmark " << k;
  }
}

}  // namespace
}  // namespace subslam::pipeline
