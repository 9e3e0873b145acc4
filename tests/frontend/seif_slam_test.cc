#include "subslam/frontend/seif_slam.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <functional>
#include <memory>

#include "subslam/core/check.h"
#include "subslam/frontend/ekf_slam.h"
#include "subslam/io/steps.h"
#include "subslam/models/range_bearing_model.h"
#include "subslam/sim/simulator.h"

namespace subslam::frontend {
namespace {

io::Dataset Simulate(const std::string& scenario, sim::ScenarioOptions o) {
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario(scenario, o);
  SUBSLAM_CHECK(d.ok()) << d.status().message();
  return *std::move(d);
}

// The exact EIF: no sparsification, exact mean and covariances, no candidate pre-filter.
SeifOptions ExactEifOptions() {
  SeifOptions o;
  o.max_active_landmarks = 0;
  o.recovery = MeanRecovery::kExact;
  o.covariance = CovarianceRecovery::kExact;
  o.pose_covariance = CovarianceRecovery::kExact;
  o.candidate_radius_m = 1e9;
  return o;
}

Eigen::Matrix3d PriorCovariance(const SeifOptions& o) {
  return o.initial_pose_sigma.array().square().matrix().asDiagonal();
}

// Feeds the data set to the filter, calling after_scan(scan) after every update.
void Drive(SeifSlam* seif, const io::Dataset& d, const std::function<void(const Scan&)>& after_scan = nullptr) {
  for (const io::Step& step : io::BuildSteps(d)) {
    seif->Predict(step.control, step.dt);
    if (step.scan_index < 0) continue;
    EXPECT_TRUE(seif->Update(d.scans[step.scan_index]).ok());
    if (after_scan) after_scan(d.scans[step.scan_index]);
  }
}

double MaxRelativeDifference(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(1.0, b.cwiseAbs().maxCoeff());
}

// Without sparsification and with exact recovery, SEIF is the EIF, which equals the
// EKF on the same linearisation: the same associations, landmarks, existence and
// culls, and the same mean and covariance after every scan.
TEST(SeifSlam, EqualsEkfSlamWithoutSparsificationAndWithExactRecovery) {
  sim::ScenarioOptions so;
  so.seed = 3;
  so.duration_s = 60.0;
  so.detection_probability = 0.8;
  so.false_alarm_probability = 0.02;
  io::Dataset d = Simulate("hybrid-120m", so);
  const SeifOptions seif_options = ExactEifOptions();
  EkfSlamOptions ekf_options;
  EkfSlam ekf(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, ekf_options, PriorCovariance(seif_options));
  SeifSlam seif(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, seif_options);
  double worst_mean = 0, worst_cov = 0;
  int scans = 0;
  for (const io::Step& step : io::BuildSteps(d)) {
    ekf.Predict(step.control, step.dt);
    seif.Predict(step.control, step.dt);
    if (step.scan_index < 0) continue;
    EXPECT_TRUE(ekf.Update(d.scans[step.scan_index]).ok());
    EXPECT_TRUE(seif.Update(d.scans[step.scan_index]).ok());
    ++scans;
    ASSERT_EQ(seif.last_scan_features(), ekf.last_scan_features()) << "scan " << scans;
    ASSERT_EQ(seif.num_landmarks(), ekf.num_landmarks()) << "scan " << scans;
    Eigen::VectorXd mean = seif.DenseMean();
    Eigen::VectorXd ekf_mean = ekf.mean();
    mean[2] = WrapAngle(mean[2] - ekf_mean[2]);
    ekf_mean[2] = 0;
    worst_mean = std::max(worst_mean, MaxRelativeDifference(mean, ekf_mean));
    if (scans % 25 == 0) {
      const Eigen::MatrixXd covariance =
          seif.DenseInformation().llt().solve(Eigen::MatrixXd::Identity(ekf.state_dimension(), ekf.state_dimension()));
      worst_cov = std::max(worst_cov, MaxRelativeDifference(covariance, ekf.covariance()));
      worst_cov =
          std::max(worst_cov, MaxRelativeDifference(seif.pose_covariance(), ekf.covariance().topLeftCorner<3, 3>()));
    }
  }
  EXPECT_GT(scans, 100);
  EXPECT_GT(seif.counters().deleted_landmarks, 0) << "the test should cover marginalising false alarms";
  EXPECT_GE(seif.num_landmarks(), 8);
  EXPECT_LT(worst_mean, 1e-7);
  EXPECT_LT(worst_cov, 1e-7);
  std::printf("SEIF vs EKF over %d scans: mean %.2g, covariance %.2g (max relative)\n", scans, worst_mean, worst_cov);
}

// JCBB, and a world on both sides of the axes (the landmark grid's cells around the origin).
TEST(SeifSlam, JcbbEqualsEkfSlamToo) {
  sim::ScenarioOptions so;
  so.seed = 5;
  so.duration_s = 50.0;
  io::Dataset d = Simulate("iseif-circle", so);
  SeifOptions seif_options = ExactEifOptions();
  seif_options.association = association::AssociationMethod::kJointCompatibility;
  EkfSlamOptions ekf_options;
  ekf_options.association = association::AssociationMethod::kJointCompatibility;
  EkfSlam ekf(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, ekf_options, PriorCovariance(seif_options));
  SeifSlam seif(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, seif_options);
  for (const io::Step& step : io::BuildSteps(d)) {
    ekf.Predict(step.control, step.dt);
    seif.Predict(step.control, step.dt);
    if (step.scan_index < 0) continue;
    EXPECT_TRUE(ekf.Update(d.scans[step.scan_index]).ok());
    EXPECT_TRUE(seif.Update(d.scans[step.scan_index]).ok());
    ASSERT_EQ(seif.last_scan_features(), ekf.last_scan_features());
  }
  Eigen::VectorXd diff = seif.DenseMean() - ekf.mean();
  diff[2] = WrapAngle(diff[2]);
  EXPECT_LT(diff.cwiseAbs().maxCoeff(), 1e-6);
}

struct SeifRun {
  std::vector<Pose2> poses;
  SeifCounters counters;
};

SeifRun RunSeif(const io::Dataset& d, const SeifOptions& options,
                const std::function<void(const SeifSlam&)>& after_scan = nullptr) {
  SeifSlam seif(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  SeifRun run;
  for (const io::Step& step : io::BuildSteps(d)) {
    seif.Predict(step.control, step.dt);
    if (step.scan_index >= 0) {
      EXPECT_TRUE(seif.Update(d.scans[step.scan_index]).ok());
      if (after_scan) after_scan(seif);
    }
    run.poses.push_back(seif.pose());
  }
  run.counters = seif.counters();
  return run;
}

TEST(SeifSlam, SparsificationBoundsTheActiveLandmarksAndStaysClose) {
  sim::ScenarioOptions so;
  so.seed = 2;
  so.duration_s = 200.0;
  io::Dataset d = Simulate("iseif-circle", so);
  SeifOptions options;
  options.max_active_landmarks = 6;
  int worst_active = 0;
  const SeifRun run =
      RunSeif(d, options, [&](const SeifSlam& s) { worst_active = std::max(worst_active, s.num_active_landmarks()); });
  EXPECT_LE(worst_active, 6);
  EXPECT_GT(run.counters.sparsifications, 100);
  EXPECT_GT(run.counters.deactivated_landmarks, 100);
  // A sparse filter stays near the truth on a short run (it is over-confident, not lost).
  double sum2 = 0;
  int n = 0;
  for (size_t k = 0; k < run.poses.size() && k < d.truth_poses.size(); ++k) {
    sum2 += (run.poses[k].translation() - d.truth_poses[k].pose.translation()).squaredNorm();
    ++n;
  }
  EXPECT_LT(std::sqrt(sum2 / n), 3.0);
}

// Thrun's sparsification replaces p(x | m⁺, m⁰, m⁻) by p(x | m⁺, m⁻ = μ⁻) and sets
// ξ̃ = ξ + (Ω̃ − Ω) μ, so the exact mean is unchanged; only the covariance is approximated.
TEST(SeifSlam, SparsificationKeepsTheMean) {
  sim::ScenarioOptions so;
  so.seed = 2;
  so.duration_s = 200.0;
  io::Dataset d = Simulate("iseif-circle", so);
  SeifOptions options;
  options.max_active_landmarks = 6;  // sparsifies on most scans
  options.recovery = MeanRecovery::kExact;
  options.landmarks.known_association = true;
  SeifSlam seif(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  double worst = 0;
  Drive(&seif, d, [&](const Scan&) {
    const Eigen::VectorXd before = seif.DenseMean();
    seif.RecoverMeanExactly();
    Eigen::VectorXd diff = seif.DenseMean() - before;
    diff[2] = WrapAngle(diff[2]);
    worst = std::max(worst, diff.cwiseAbs().maxCoeff());
  });
  EXPECT_GT(seif.counters().sparsifications, 100);
  EXPECT_LT(worst, 1e-8);
}
// Landmarks in every quadrant around the origin (the landmark grid's cells meet there):
// each is found again on every scan, so none is duplicated.
TEST(SeifSlam, FindsLandmarksInEveryQuadrant) {
  sim::ScenarioOptions so;
  absl::StatusOr<sim::ScenarioConfig> config = sim::MakeScenario("iseif-circle", so);
  ASSERT_TRUE(config.ok());
  config->sensor.fov_min_rad = -M_PI;
  config->sensor.fov_max_rad = M_PI;
  config->max_duration_s = 20.0;
  config->landmarks.clear();
  int id = 0;
  for (double x : {-12.0, -5.0, 5.0, 12.0}) {
    for (double y : {-12.0, -5.0, 5.0, 12.0}) config->landmarks.push_back({id++, Eigen::Vector2d(x, y)});
  }
  absl::StatusOr<io::Dataset> d = sim::Simulate(*config, 3);
  ASSERT_TRUE(d.ok()) << d.status().message();
  SeifOptions options;
  options.max_active_landmarks = 4;
  SeifSlam seif(d->motion.MakeModel(), d->sensor.range_bearing, d->initial_pose, options);
  Drive(&seif, *d);
  EXPECT_EQ(seif.counters().new_landmarks, 16);
  EXPECT_EQ(seif.Map().size(), 16u);
}

// Clutter and missed detections with the default options: false alarms are culled
// (marginalised out) while the sparse filter keeps running, and none is reported.
TEST(SeifSlam, CullsFalseAlarmsUnderClutter) {
  sim::ScenarioOptions so;
  so.seed = 8;
  so.duration_s = 150.0;
  so.detection_probability = 0.7;
  so.false_alarm_probability = 0.05;
  io::Dataset d = Simulate("hybrid-120m", so);
  for (bool iterated : {false, true}) {
    SeifOptions options;
    options.iterated.enabled = iterated;
    options.iterated.period_scans = 7;
    SeifSlam seif(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
    bool finite = true;
    Drive(&seif, d, [&](const Scan&) { finite &= seif.pose().vector().allFinite(); });
    EXPECT_TRUE(finite);
    EXPECT_GT(seif.counters().deleted_landmarks, 20);
    int far_from_truth = 0;
    for (const LandmarkEstimate& l : seif.Map()) {
      double nearest = INFINITY;
      for (const io::TruthLandmark& t : d.truth_landmarks) nearest = std::min(nearest, (t.p - l.position).norm());
      far_from_truth += nearest > 3.0 ? 1 : 0;
    }
    EXPECT_EQ(far_from_truth, 0) << (iterated ? "iseif" : "seif");
  }
}

TEST(Iseif, OneIterationIsTheSeifUpdate) {
  sim::ScenarioOptions so;
  so.seed = 4;
  so.duration_s = 100.0;
  io::Dataset d = Simulate("iseif-circle", so);
  SeifOptions seif = ExactEifOptions();
  seif.max_active_landmarks = 8;
  const SeifRun reference = RunSeif(d, seif);
  // One linearisation, two ways: the iteration limit, and an adaptive stop that is
  // always met after the first pass.
  SeifOptions limit = seif;
  limit.iterated = {true, 1, 1, 1e-3, 1};
  SeifOptions stop = seif;
  stop.iterated = {true, 1, 10, 1e9, 1};
  for (const SeifOptions& o : {limit, stop}) {
    const SeifRun run = RunSeif(d, o);
    ASSERT_EQ(run.poses.size(), reference.poses.size());
    for (size_t k = 0; k < run.poses.size(); ++k) {
      ASSERT_EQ(run.poses[k].vector(), reference.poses[k].vector()) << "step " << k;
    }
  }
  const SeifRun iterated = RunSeif(d, [&] {
    SeifOptions o = seif;
    o.iterated = {true, 1, 10, 1e-6, 10};
    return o;
  }());
  EXPECT_GT(iterated.counters.iterations, iterated.counters.iterated_updates)
      << "with a tight stop some updates should iterate more than once";
}

// The gradient of the step's MAP cost (ISEIF Eq. 9) at the updated mean,
//   ∇J = Ω⁻ (μ⁺ − μ⁻) − Σ Hᵀ R⁻¹ (z − h(μ⁺)),
// relative to the size of its first term.
double RelativeMapGradient(const Eigen::MatrixXd& omega_prior, const Eigen::VectorXd& mu_prior,
                           const Eigen::VectorXd& mu_post, const std::vector<int>& live, const Scan& scan,
                           const std::vector<int>& features, const models::RangeBearingModel& sensor) {
  Eigen::VectorXd delta = mu_post - mu_prior;
  delta[2] = WrapAngle(delta[2]);
  const Eigen::VectorXd prior_term = omega_prior * delta;
  Eigen::VectorXd gradient = prior_term;
  const Pose2 p(mu_post[0], mu_post[1], mu_post[2]);
  const Eigen::Matrix2d R_inv = sensor.NoiseCovariance().inverse();
  for (size_t k = 0; k < features.size(); ++k) {
    if (features[k] < 0) continue;
    const int slot = static_cast<int>(std::find(live.begin(), live.end(), features[k]) - live.begin());
    const int o = 3 + 2 * slot;
    Matrix23d H_pose;
    Eigen::Matrix2d H_landmark;
    const Eigen::Vector2d z_hat = sensor.Observe(p, mu_post.segment<2>(o), &H_pose, &H_landmark);
    const Eigen::Vector2d nu = models::RangeBearingModel::Difference(scan.detections[k].z(), z_hat);
    gradient.head<3>() -= H_pose.transpose() * R_inv * nu;
    gradient.segment<2>(o) -= H_landmark.transpose() * R_inv * nu;
  }
  return gradient.norm() / std::max(prior_term.norm(), 1e-12);
}

// Iterated to convergence, each update is the MAP estimate of its step (a stationary
// point of Eq. 9, with the step's prior Ω⁻ — sparsified or not); the plain SEIF update
// is not, so the test can tell them apart. The run is long enough for the heading to
// cross ±π, where the state's angle coordinate is shifted.
TEST(Iseif, IteratedUpdateReachesTheStepsMapEstimate) {
  sim::ScenarioOptions so;
  so.seed = 6;
  so.duration_s = 120.0;
  io::Dataset d = Simulate("iseif-circle", so);
  auto worst_gradient = [&](const SeifOptions& options) {
    SeifSlam seif(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
    models::RangeBearingModel sensor(d.sensor.range_bearing);
    double worst = 0;
    int checked = 0;
    bool wrapped = false;
    for (const io::Step& step : io::BuildSteps(d)) {
      seif.Predict(step.control, step.dt);
      wrapped |= std::abs(seif.pose().theta) > 3.0;
      if (step.scan_index < 0) continue;
      const std::vector<int> live = seif.LiveLandmarkIds();
      const Eigen::MatrixXd omega = seif.DenseInformation();
      const Eigen::VectorXd mu = seif.DenseMean();
      const long created = seif.counters().new_landmarks, deleted = seif.counters().deleted_landmarks;
      EXPECT_TRUE(seif.Update(d.scans[step.scan_index]).ok());
      if (seif.counters().new_landmarks != created || seif.counters().deleted_landmarks != deleted) continue;
      worst = std::max(worst, RelativeMapGradient(omega, mu, seif.DenseMean(), live, d.scans[step.scan_index],
                                                  seif.last_scan_features(), sensor));
      ++checked;
    }
    EXPECT_GT(checked, 100);
    EXPECT_TRUE(wrapped) << "the run should cross the heading's cut at ±π";
    return worst;
  };
  SeifOptions seif;
  seif.recovery = MeanRecovery::kExact;
  SeifOptions iseif = seif;
  iseif.iterated = {true, 1, 20, 1e-10, 20};
  const double seif_gradient = worst_gradient(seif);
  const double iseif_gradient = worst_gradient(iseif);
  std::printf("relative MAP gradient: SEIF %.3g, ISEIF %.3g\n", seif_gradient, iseif_gradient);
  EXPECT_GT(seif_gradient, 1e-4);
  EXPECT_LT(iseif_gradient, 1e-6);
}

TEST(SeifSlam, KnownAssociationUsesTrueIdsAndDropsFalseAlarms) {
  sim::ScenarioOptions so;
  so.seed = 7;
  so.duration_s = 80.0;
  so.false_alarm_probability = 0.05;
  io::Dataset d = Simulate("hybrid-120m", so);
  SeifOptions options;
  options.landmarks.known_association = true;
  SeifSlam seif(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  std::map<int, int> truth_of_landmark;
  bool consistent = true;
  Drive(&seif, d, [&](const Scan& scan) {
    for (size_t k = 0; k < scan.detections.size(); ++k) {
      const int l = seif.last_scan_features()[k];
      if (scan.detections[k].truth_id < 0) {
        consistent &= l < 0;
      } else if (l >= 0) {
        auto [it, inserted] = truth_of_landmark.try_emplace(l, scan.detections[k].truth_id);
        consistent &= it->second == scan.detections[k].truth_id;
      }
    }
  });
  EXPECT_TRUE(consistent);
  EXPECT_EQ(seif.counters().ambiguous, 0);
  EXPECT_EQ(static_cast<size_t>(seif.counters().new_landmarks), truth_of_landmark.size());
}

TEST(SeifOptions, RejectsBadValues) {
  EXPECT_TRUE(SeifOptions().Validate().ok());
  auto bad = [](auto edit) {
    SeifOptions o;
    edit(o);
    return !o.Validate().ok();
  };
  EXPECT_TRUE(bad([](SeifOptions& o) { o.landmarks.gate_probability = 1.0; }));
  EXPECT_TRUE(bad([](SeifOptions& o) { o.max_active_landmarks = -1; }));
  EXPECT_TRUE(bad([](SeifOptions& o) { o.relaxation_sweeps = 0; }));
  EXPECT_TRUE(bad([](SeifOptions& o) { o.candidate_radius_m = NAN; }));
  EXPECT_TRUE(bad([](SeifOptions& o) { o.initial_pose_sigma[2] = 0.0; }));
  EXPECT_TRUE(bad([](SeifOptions& o) { o.iterated.max_iterations = 0; }));
  EXPECT_TRUE(bad([](SeifOptions& o) { o.iterated.stop_change = -1; }));
  EXPECT_TRUE(bad([](SeifOptions& o) { o.iterated.exact_recoveries = -1; }));
  EXPECT_FALSE(MeanRecoveryFromString("cg").ok());
  EXPECT_EQ(*CovarianceRecoveryFromString("markov-blanket"), CovarianceRecovery::kMarkovBlanket);
}

}  // namespace
}  // namespace subslam::frontend
