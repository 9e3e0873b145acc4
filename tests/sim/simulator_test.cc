#include "subslam/sim/simulator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "subslam/models/range_bearing_model.h"
#include "test_util.h"

namespace subslam::sim {
namespace {

TEST(Simulator, EveryScenarioRunsAndIsDeterministic) {
  for (const std::string& name : ScenarioNames()) {
    ScenarioOptions o;
    o.seed = 7;
    o.duration_s = 30.0;
    absl::StatusOr<io::Dataset> a = SimulateScenario(name, o);
    absl::StatusOr<io::Dataset> b = SimulateScenario(name, o);
    ASSERT_TRUE(a.ok()) << name << ": " << a.status();
    ASSERT_TRUE(b.ok());
    EXPECT_GT(a->controls.size(), 100u) << name;
    EXPECT_GT(a->NumDetections(), 10u) << name;
    ASSERT_EQ(a->controls.size(), b->controls.size());
    for (size_t i = 0; i < a->controls.size(); ++i) EXPECT_EQ(a->controls[i].u, b->controls[i].u);
    ASSERT_EQ(a->scans.size(), b->scans.size());
    EXPECT_EQ(a->truth_poses.back().pose.x, b->truth_poses.back().pose.x) << name;
    o.seed = 8;
    absl::StatusOr<io::Dataset> c = SimulateScenario(name, o);
    ASSERT_TRUE(c.ok());
    EXPECT_NE(a->truth_poses.back().pose.x, c->truth_poses.back().pose.x) << name;
  }
}

TEST(Simulator, PaperParameters) {
  ScenarioOptions o;
  auto combined = MakeScenario("combined-2km", o);
  ASSERT_TRUE(combined.ok());
  EXPECT_EQ(combined->landmarks.size(), 554u);
  EXPECT_DOUBLE_EQ(combined->control_rate_hz / combined->observation_every, 5.0);
  EXPECT_DOUBLE_EQ(combined->sensor.max_range_m, 30.0);
  EXPECT_DOUBLE_EQ(combined->sensor.fov_max_rad - combined->sensor.fov_min_rad, kPi);
  for (const io::TruthLandmark& l : combined->landmarks) {
    EXPECT_LE(std::abs(l.p.x()), 1000.0);
    EXPECT_LE(std::abs(l.p.y()), 1000.0);
  }
  auto hybrid = MakeScenario("hybrid-120m", o);
  ASSERT_TRUE(hybrid.ok());
  EXPECT_EQ(hybrid->landmarks.size(), 35u);
  EXPECT_DOUBLE_EQ(hybrid->motion.noise.scale_u0, 0.25);
  EXPECT_DOUBLE_EQ(hybrid->motion.noise.scale_u1, 0.35);
  auto circle = MakeScenario("iseif-circle", o);
  ASSERT_TRUE(circle.ok());
  EXPECT_EQ(circle->landmarks.size(), 200u);
  EXPECT_DOUBLE_EQ(circle->motion.geometry.wheelbase_m, 4.0);
  o.fmj_case = 1;
  EXPECT_EQ(MakeScenario("fmj-ellipse", o)->landmarks.size(), 98u);
  o.fmj_case = 2;
  EXPECT_EQ(MakeScenario("fmj-ellipse", o)->landmarks.size(), 100u);
  EXPECT_FALSE(MakeScenario("no-such-scenario", o).ok());
}

TEST(ScenarioOptions, RejectsInvalidKnobs) {
  ScenarioOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.detection_probability = 1.5;
  EXPECT_FALSE(MakeScenario("hybrid-120m", o).ok());
  o = {};
  o.false_alarm_probability = -0.1;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.duration_s = 0.0;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.fmj_case = 3;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.random_noise_scale = 0.0;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.random_lattice_spacing_m = 0.1;
  EXPECT_FALSE(o.Validate().ok());
  o.random_lattice_spacing_m = -1.0;
  EXPECT_FALSE(o.Validate().ok());
}

// The random world's lattice layout: every landmark on the grid, one per cell, the whole
// world covered.
TEST(Simulator, RandomWorldOnALattice) {
  ScenarioOptions o;
  o.random_world_size_m = 20.0;
  o.random_lattice_spacing_m = 4.0;
  absl::StatusOr<ScenarioConfig> c = MakeScenario("random", o);
  ASSERT_TRUE(c.ok()) << c.status();
  ASSERT_EQ(c->landmarks.size(), 25u);
  for (const auto& l : c->landmarks) {
    for (double v : {l.p.x(), l.p.y()}) {
      EXPECT_NEAR(std::fmod(v - 2.0, 4.0), 0.0, 1e-12);
      EXPECT_GT(v, 0.0);
      EXPECT_LT(v, 20.0);
    }
  }
}

TEST(Simulator, DetectionsMatchTruthWithinNoise) {
  ScenarioOptions o;
  o.seed = 3;
  o.duration_s = 60.0;
  absl::StatusOr<io::Dataset> d = SimulateScenario("hybrid-120m", o);
  ASSERT_TRUE(d.ok());
  const models::RangeBearingModel sensor(d->sensor.range_bearing);
  double sum_r = 0, sum_b = 0;
  int n = 0;
  size_t k = 0;
  for (const Scan& scan : d->scans) {
    while (d->truth_poses[k].t < scan.t) ++k;
    ASSERT_EQ(d->truth_poses[k].t, scan.t);
    for (const Detection& det : scan.detections) {
      ASSERT_GE(det.truth_id, 0);  // no clutter by default
      const Eigen::Vector2d z = sensor.Observe(d->truth_poses[k].pose, d->truth_landmarks[det.truth_id].p);
      const Eigen::Vector2d e = models::RangeBearingModel::Difference(det.z(), z);
      sum_r += e[0] * e[0];
      sum_b += e[1] * e[1];
      ++n;
    }
  }
  ASSERT_GT(n, 1000);
  // Sample σ within 10% of the configured one (n > 1000 samples: ~2% standard error).
  EXPECT_NEAR(std::sqrt(sum_r / n), d->sensor.range_bearing.sigma_range_m, 0.1 * d->sensor.range_bearing.sigma_range_m);
  EXPECT_NEAR(std::sqrt(sum_b / n), d->sensor.range_bearing.sigma_bearing_rad,
              0.1 * d->sensor.range_bearing.sigma_bearing_rad);
}

TEST(Simulator, ClutterAndMissedDetections) {
  ScenarioOptions o;
  o.seed = 5;
  o.world_seed = 5;
  absl::StatusOr<io::Dataset> clean = SimulateScenario("hybrid-120m", o);
  o.detection_probability = 0.4;
  o.false_alarm_probability = 0.04;
  absl::StatusOr<io::Dataset> noisy = SimulateScenario("hybrid-120m", o);
  ASSERT_TRUE(clean.ok() && noisy.ok());
  long true_clean = 0, true_noisy = 0, false_noisy = 0;
  for (const Scan& s : clean->scans) true_clean += static_cast<long>(s.detections.size());
  for (const Scan& s : noisy->scans) {
    for (const Detection& det : s.detections) (det.truth_id >= 0 ? true_noisy : false_noisy)++;
  }
  // α = 0.4 of the visible features are detected; β = 0.04 false alarms per visible
  // feature. Counts over > 10,000 visible features: 5σ binomial margins.
  const double visible = static_cast<double>(true_clean);
  EXPECT_NEAR(true_noisy / visible, 0.4, 5 * std::sqrt(0.4 * 0.6 / visible));
  EXPECT_NEAR(false_noisy / visible, 0.04, 5 * std::sqrt(0.04 * 0.96 / visible));
}

TEST(Simulator, TruthFollowsTheMotionModelAndPath) {
  ScenarioOptions o;
  o.seed = 2;
  absl::StatusOr<ScenarioConfig> config = MakeScenario("fmj-ellipse", o);
  ASSERT_TRUE(config.ok());
  absl::StatusOr<io::Dataset> d = Simulate(*config, 2);
  ASSERT_TRUE(d.ok());
  // Kanayama tracking keeps the true vehicle on the reference ellipse.
  double worst = 0;
  for (const io::TimedPose& p : d->truth_poses) {
    worst = std::max(worst, (p.pose.translation() - config->reference(p.t).pose.translation()).norm());
  }
  EXPECT_LT(worst, 2.0);
  // The iseif-circle vehicle goes round its 100 m circle and comes back to the start.
  absl::StatusOr<io::Dataset> circle = SimulateScenario("iseif-circle", o);
  ASSERT_TRUE(circle.ok());
  double max_radius_error = 0;
  for (const io::TimedPose& p : circle->truth_poses) {
    max_radius_error =
        std::max(max_radius_error, std::abs((p.pose.translation() - Eigen::Vector2d(0, 100)).norm() - 100));
  }
  EXPECT_LT(max_radius_error, 10.0);
  EXPECT_GT(circle->truth_poses.back().t, 2 * kPi * 100 / 3.0);
}

}  // namespace
}  // namespace subslam::sim

namespace subslam::sim {
namespace {

// camera-robot holds what a new robot's manifest does not say: odometry that reports the
// commanded rates while the robot drives at 0.93× them, gaps in the odometry, moving
// objects with landmark markers (detections without a true id, as the scenario has no
// clutter), and a detection probability that falls with range.
TEST(Simulator, CameraRobotHoldsWhatItsManifestDoesNotSay) {
  ScenarioOptions o;
  o.seed = 3;
  o.duration_s = 300.0;
  absl::StatusOr<ScenarioConfig> config = MakeScenario("camera-robot", o);
  ASSERT_TRUE(config.ok());
  absl::StatusOr<io::Dataset> d = Simulate(*config, o.seed);
  ASSERT_TRUE(d.ok()) << d.status();
  // Distance the reported odometry drives (each control held until the next) against the
  // true path's.
  double reported = 0.0, driven = 0.0, longest_gap = 0.0;
  for (size_t i = 0; i + 1 < d->controls.size(); ++i) {
    const double dt = d->controls[i + 1].t - d->controls[i].t;
    reported += d->controls[i].u[0] * dt;
    longest_gap = std::max(longest_gap, dt);
  }
  for (size_t k = 0; k + 1 < d->truth_poses.size(); ++k) {
    driven += (d->truth_poses[k + 1].pose.translation() - d->truth_poses[k].pose.translation()).norm();
  }
  EXPECT_NEAR(driven / reported, config->odometry_scale[0], 0.02);
  EXPECT_GT(longest_gap, 0.2);
  EXPECT_LE(longest_gap, config->max_control_gap_s + 1.0 / config->control_rate_hz + 1e-9);
  // Detections per visible landmark near (within the full-probability range) and far.
  std::map<double, const Scan*> scan_at;
  for (const Scan& scan : d->scans) scan_at[scan.t] = &scan;
  const models::RangeBearingModel sensor(config->sensor);
  long near_visible = 0, near_detected = 0, far_visible = 0, far_detected = 0, moving = 0;
  for (const Scan& scan : d->scans) {
    for (const Detection& z : scan.detections) moving += z.truth_id == kFalseAlarmId;
  }
  for (size_t k = config->observation_every; k < d->truth_poses.size(); k += config->observation_every) {
    const io::TimedPose& x = d->truth_poses[k];
    const auto it = scan_at.find(x.t);
    for (const io::TruthLandmark& l : config->landmarks) {
      const Eigen::Vector2d z = sensor.Observe(x.pose, l.p);
      if (!sensor.IsVisible(z) || (z[0] > 2.0 && z[0] < 6.0)) continue;
      bool detected = false;
      if (it != scan_at.end()) {
        for (const Detection& det : it->second->detections) detected = detected || det.truth_id == l.id;
      }
      (z[0] <= 2.0 ? near_visible : far_visible) += 1;
      (z[0] <= 2.0 ? near_detected : far_detected) += detected;
    }
  }
  ASSERT_GT(near_visible, 200);
  ASSERT_GT(far_visible, 200);
  // Binomial: 0.56 within ±4σ near; beyond 6 m the probability is at most 0.56·2.7/6.7.
  const double near_rate = static_cast<double>(near_detected) / near_visible;
  EXPECT_NEAR(near_rate, 0.56, 4.0 * std::sqrt(0.56 * 0.44 / near_visible));
  EXPECT_LT(static_cast<double>(far_detected) / far_visible, 0.56 * 2.7 / 6.7);
  EXPECT_GT(moving, 20);
}

}  // namespace
}  // namespace subslam::sim
