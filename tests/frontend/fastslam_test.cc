#include "subslam/frontend/fastslam.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "subslam/core/check.h"
#include "subslam/frontend/ekf_slam.h"
#include "subslam/io/steps.h"
#include "subslam/models/unicycle_model.h"
#include "subslam/sim/simulator.h"
#include "test_util.h"

namespace subslam::frontend {
namespace {

io::Dataset Simulate(const std::string& scenario, uint64_t seed, double duration_s) {
  sim::ScenarioOptions o;
  o.seed = seed;
  o.duration_s = duration_s;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario(scenario, o);
  SUBSLAM_CHECK(d.ok()) << d.status().message();
  return *std::move(d);
}

Trajectory RunFilter(OnlineEstimator* estimator, const io::Dataset& d) {
  Trajectory out;
  for (const io::Step& step : io::BuildSteps(d)) {
    estimator->Predict(step.control, step.dt);
    if (step.scan_index >= 0) EXPECT_TRUE(estimator->Update(d.scans[step.scan_index]).ok());
    out.push_back({step.t, estimator->pose(), estimator->pose_covariance()});
  }
  return out;
}

TEST(FastSlam, SameSeedSameRunBitForBit) {
  const io::Dataset d = Simulate("hybrid-120m", 4, 30.0);
  FastSlamOptions options;
  options.num_particles = 50;
  FastSlam a(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  FastSlam b(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  const Trajectory ta = RunFilter(&a, d), tb = RunFilter(&b, d);
  ASSERT_EQ(ta.size(), tb.size());
  for (size_t k = 0; k < ta.size(); ++k) {
    ASSERT_EQ(ta[k].pose.x, tb[k].pose.x) << k;
    ASSERT_EQ(ta[k].pose.theta, tb[k].pose.theta) << k;
  }
  options.seed = 2;
  FastSlam c(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  const Trajectory tc = RunFilter(&c, d);
  EXPECT_NE(ta.back().pose.x, tc.back().pose.x);
}

// The particle update runs on several threads, and the run is the same bit for bit for
// any number of them — trajectory, map and counters — with clutter (creations and culls),
// data-association sampling, and the particles' sensor yaws too.
TEST(FastSlam, ThreadCountDoesNotChangeTheRun) {
  sim::ScenarioOptions so;
  so.seed = 6;
  so.duration_s = 40.0;
  so.detection_probability = 0.7;
  so.false_alarm_probability = 0.02;
  absl::StatusOr<io::Dataset> simulated = sim::SimulateScenario("hybrid-120m", so);
  ASSERT_TRUE(simulated.ok());
  const io::Dataset& d = *simulated;
  for (const auto& [sample_association, sensor_yaw_sigma] :
       {std::pair{false, 0.0}, std::pair{true, 0.0}, std::pair{false, 0.01}}) {
    FastSlamOptions options;
    options.num_particles = 37;  // not a multiple of the chunk or the thread count
    options.sample_association = sample_association;
    options.sensor_yaw_sigma = sensor_yaw_sigma;
    options.num_threads = 1;
    FastSlam one(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
    const Trajectory t1 = RunFilter(&one, d);
    for (int threads : {2, 3}) {
      options.num_threads = threads;
      FastSlam many(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
      const Trajectory tn = RunFilter(&many, d);
      ASSERT_EQ(t1.size(), tn.size());
      for (size_t k = 0; k < t1.size(); ++k) {
        ASSERT_EQ(t1[k].pose.vector(), tn[k].pose.vector()) << "step " << k << ", " << threads << " threads";
        ASSERT_EQ(t1[k].covariance, tn[k].covariance) << "step " << k;
      }
      EXPECT_EQ(one.Counters(), many.Counters()) << threads << " threads";
      const std::vector<LandmarkEstimate> m1 = one.Map(), mn = many.Map();
      ASSERT_EQ(m1.size(), mn.size());
      for (size_t i = 0; i < m1.size(); ++i) EXPECT_EQ(m1[i].position, mn[i].position);
    }
    EXPECT_GT(one.counters().landmarks_culled, 0);  // the clutter was exercised
    EXPECT_GT(one.counters().landmark_copies, 0);
  }
}

// set_thread_limit (what a background join asks of the RBPF) changes only how many of
// the pool's threads a scan uses: a limit that changes from scan to scan gives the
// one-thread run, and the scans run below the pool's size are counted.
TEST(FastSlam, ThreadLimitChangesNothingButTheThreadsUsed) {
  const io::Dataset d = Simulate("hybrid-120m", 5, 30.0);
  FastSlamOptions options;
  options.num_particles = 37;
  options.num_threads = 1;
  FastSlam one(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  const Trajectory t1 = RunFilter(&one, d);
  options.num_threads = 3;
  FastSlam limited(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  ASSERT_EQ(limited.threads(), 3);
  Trajectory tl;
  long scans = 0, expected_limited = 0;
  for (const io::Step& step : io::BuildSteps(d)) {
    limited.Predict(step.control, step.dt);
    if (step.scan_index >= 0) {
      const int limit = static_cast<int>(scans++ % 4);  // 0 (all), 1, 2, 3 (all)
      expected_limited += limit == 1 || limit == 2 ? 1 : 0;
      limited.set_thread_limit(limit);
      EXPECT_TRUE(limited.Update(d.scans[step.scan_index]).ok());
    }
    tl.push_back({step.t, limited.pose(), limited.pose_covariance()});
  }
  ASSERT_EQ(t1.size(), tl.size());
  for (size_t k = 0; k < t1.size(); ++k) ASSERT_EQ(t1[k].pose.vector(), tl[k].pose.vector()) << "step " << k;
  EXPECT_EQ(limited.counters().scans_with_fewer_threads, expected_limited);
  EXPECT_GT(expected_limited, 0);
  EXPECT_EQ(one.counters().scans_with_fewer_threads, 0);
}

// pose() and pose_covariance() come from per-scan sums in O(1) per step; they equal the
// weighted moments of the particles' current poses (mean, spread — scaled by
// (1 + R) / (1 − R), R = SharedAncestry(), when corrected — and each particle's motion
// covariance),
// computed directly, at every step — between scans too — and MomentMatched()'s pose.
class PoseMoments : public ::testing::TestWithParam<bool> {};

TEST_P(PoseMoments, EqualTheParticlesMoments) {
  const io::Dataset d = Simulate("hybrid-120m", 5, 20.0);
  FastSlamOptions options;
  options.num_particles = 40;
  options.correct_shared_ancestry = GetParam();
  FastSlam f(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  int checked = 0;
  double largest_genealogy_share = 0.0;  // R − Σ_p w_p²: what shared ancestors add
  std::vector<io::Step> steps = io::BuildSteps(d);
  // Then a long stretch without scans, so that the motion since the last scan (r, Σ_r)
  // is large.
  for (int k = 0; k < 40; ++k) {
    io::Step coast = steps.back();
    coast.scan_index = -1;
    coast.dt = 0.1;
    steps.push_back(coast);
  }
  for (const io::Step& step : steps) {
    f.Predict(step.control, step.dt);
    if (step.scan_index >= 0) EXPECT_TRUE(f.Update(d.scans[step.scan_index]).ok());
    const std::vector<ParticleHypothesis> h = f.Hypotheses();
    size_t heaviest = 0;
    for (size_t p = 1; p < h.size(); ++p) {
      if (h[p].weight > h[heaviest].weight) heaviest = p;
    }
    const double reference = h[heaviest].pose.theta;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
    double total = 0.0;
    for (const ParticleHypothesis& p : h) {
      const Eigen::Vector3d v(p.pose.x, p.pose.y, WrapAngle(p.pose.theta - reference));
      mean += p.weight * v;
      second += p.weight * (p.pose_covariance + v * v.transpose());
      total += p.weight;
    }
    mean /= total;
    Eigen::Matrix3d own = Eigen::Matrix3d::Zero();
    for (const ParticleHypothesis& p : h) own += p.weight / total * p.pose_covariance;
    const double R = f.SharedAncestry();
    const double scale = GetParam() ? (1.0 + R) / (1.0 - R) : 1.0;
    double sum_sq = 0.0;
    for (const ParticleHypothesis& p : h) sum_sq += (p.weight / total) * (p.weight / total);
    if (f.counters().scans > 0) {                                               // (0 before: no draw yet)
      EXPECT_GE(f.SharedAncestry(), sum_sq - 1e-12) << "step at t " << step.t;  // ρ_pq ≥ 0, ρ_pp = 1
    }
    largest_genealogy_share = std::max(largest_genealogy_share, f.SharedAncestry() - sum_sq);
    const Eigen::Matrix3d covariance = scale * (second / total - own - mean * mean.transpose()) + own;
    // The reference subtracts mean meanᵀ from the second moment about the world origin
    // (positions up to 100 m): its rounding error grows with |mean|².
    const double tolerance = 1e-9 * covariance.norm() + 1e-11 + 1e-14 * mean.squaredNorm();
    const Pose2 pose = f.pose();
    EXPECT_NEAR(pose.x, mean.x(), 1e-9);
    EXPECT_NEAR(pose.y, mean.y(), 1e-9);
    EXPECT_NEAR(WrapAngle(pose.theta - (mean.z() + reference)), 0.0, 1e-12);
    EXPECT_LE((f.pose_covariance() - covariance).norm(), tolerance) << "step at t " << step.t;
    if (step.scan_index >= 0) {  // MomentMatched() takes the pose at the scan
      const MomentMatchedGaussian g = f.MomentMatched();
      EXPECT_LE((g.covariance.topLeftCorner<3, 3>() - covariance).norm(), tolerance) << "step at t " << step.t;
    }
    ++checked;
  }
  EXPECT_GT(checked, 100);
  EXPECT_GT(f.counters().resamples, 0);
  EXPECT_GT(largest_genealogy_share, 0.01);  // resampling made particles share draws
}

INSTANTIATE_TEST_SUITE_P(FastSlam, PoseMoments, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "Corrected" : "Uncorrected"; });

// Without resampling the particles share nothing but the start: R = Σ_p w_p², the
// correction of a weighted sample covariance.
TEST(FastSlam, SharedAncestryWithoutResamplingIsTheSumOfSquaredWeights) {
  const io::Dataset d = Simulate("hybrid-120m", 5, 10.0);
  FastSlamOptions options;
  options.num_particles = 30;
  options.resample_ess_ratio = 0.0;
  FastSlam f(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  EXPECT_EQ(f.SharedAncestry(), 0.0);
  int scans = 0;
  for (const io::Step& step : io::BuildSteps(d)) {
    f.Predict(step.control, step.dt);
    if (step.scan_index < 0) continue;
    EXPECT_TRUE(f.Update(d.scans[step.scan_index]).ok());
    ++scans;
    double sum_sq = 0.0;
    for (const ParticleHypothesis& p : f.Hypotheses()) sum_sq += p.weight * p.weight;
    EXPECT_NEAR(f.SharedAncestry(), sum_sq, 1e-12);
  }
  EXPECT_GT(scans, 50);
  EXPECT_EQ(f.counters().resamples, 0);
}

// With no motion noise the pose is known: every particle equals the one sample, and each
// landmark is an independent EKF at the same linearisation points as EKF-SLAM with a
// zero pose covariance, so the two maps agree.
TEST(FastSlam, WithoutMotionNoiseEqualsEkfSlam) {
  const io::Dataset d = Simulate("hybrid-120m", 2, 40.0);
  const models::ControlNoise none;
  FastSlamOptions fo;
  fo.num_particles = 3;
  fo.association_score = AssociationScore::kMahalanobis;  // as EKF-SLAM's NN
  FastSlam fast(std::make_unique<models::UnicycleModel>(none), d.sensor.range_bearing, d.initial_pose, fo);
  EkfSlamOptions eo;
  EkfSlam ekf(std::make_unique<models::UnicycleModel>(none), d.sensor.range_bearing, d.initial_pose, eo);
  RunFilter(&fast, d);
  RunFilter(&ekf, d);
  // Every landmark, tentative ones included: EKF-SLAM's state against the particles'.
  MomentMatchingOptions all;
  all.min_existence = 0.0;
  const MomentMatchedGaussian g = MomentMatch(fast.Hypotheses(), all);
  const Eigen::VectorXd x = ekf.mean();
  const Eigen::MatrixXd P = ekf.covariance();
  ASSERT_GE(ekf.num_landmarks(), 8);
  EXPECT_EQ(fast.counters().associated, fo.num_particles * ekf.counters().associated);
  EXPECT_EQ(fast.counters().ignored, fo.num_particles * ekf.counters().ambiguous);
  ASSERT_EQ(static_cast<int>(g.features.size()), ekf.num_landmarks());
  for (int k = 0; k < ekf.num_landmarks(); ++k) {  // pair each with its nearest
    const int j = 3 + 2 * k;
    int best = 0;
    for (size_t f = 1; f < g.features.size(); ++f) {
      if ((g.mean.segment<2>(3 + 2 * f) - x.segment<2>(j)).norm() <
          (g.mean.segment<2>(3 + 2 * best) - x.segment<2>(j)).norm()) {
        best = static_cast<int>(f);
      }
    }
    const int i = 3 + 2 * best;
    EXPECT_TRUE(testing::MatricesNear(x.segment<2>(j), g.mean.segment<2>(i), 1e-9)) << k;
    EXPECT_TRUE(testing::MatricesNear(P.block<2, 2>(j, j), g.covariance.block<2, 2>(i, i), 1e-9)) << k;
  }
  EXPECT_TRUE(testing::MatricesNear(ekf.pose().vector(), fast.pose().vector(), 1e-12));
}

// Resampling shares landmark Gaussians between particles; updating a shared one copies
// it (copy-on-write), and the particles' maps stay independent.
TEST(FastSlam, ResamplingSharesLandmarksCopyOnWrite) {
  const io::Dataset d = Simulate("hybrid-120m", 5, 30.0);
  FastSlamOptions options;
  options.num_particles = 40;
  FastSlam f(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  RunFilter(&f, d);
  EXPECT_GT(f.counters().resamples, 0);
  EXPECT_GT(f.counters().landmark_copies, 0);
  // Far fewer copies than landmark updates: untouched landmarks stay shared.
  EXPECT_LT(f.counters().landmark_copies, f.counters().detections * options.num_particles);
  const MomentMatchedGaussian g = f.MomentMatched();
  EXPECT_GE(g.features.size(), 3u);
  EXPECT_LE(f.LineageDiversity(), 1.0);
}

TEST(FastSlam, ResetStartsAnEmptyMapAtTheGivenPose) {
  const io::Dataset d = Simulate("hybrid-120m", 6, 20.0);
  FastSlam f(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, {});
  RunFilter(&f, d);
  ASSERT_FALSE(f.Map().empty());
  f.Reset(Pose2(1, 2, 0.5));
  EXPECT_TRUE(f.Map().empty());
  EXPECT_TRUE(testing::MatricesNear(Eigen::Vector3d(1, 2, 0.5), f.pose().vector(), 0.0));
  EXPECT_TRUE(testing::MatricesNear(Eigen::Matrix3d::Zero(), f.pose_covariance(), 0.0));
  EXPECT_EQ(f.LineageDiversity(), 1.0);
}

// With sensor_yaw_sigma the counters give the particles' weighted yaw and spread: in a
// single-map run the particles' now; once Reset() has closed particle sets (local maps),
// their average over those sets — not the fresh draws of the prior after the last Reset().
TEST(FastSlam, SensorYawCountersDescribeTheClosedParticleSets) {
  const io::Dataset d = Simulate("hybrid-120m", 6, 20.0);
  FastSlamOptions options;
  options.num_particles = 50;
  {
    FastSlam plain(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
    EXPECT_EQ(plain.Counters().count("sensor_yaw_mean"), 0u);  // only with the option
  }
  options.sensor_yaw_sigma = 0.01;
  FastSlam f(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  RunFilter(&f, d);
  const double first_mean = f.Counters().at("sensor_yaw_mean");
  const double first_spread = f.Counters().at("sensor_yaw_spread");
  ASSERT_GT(f.counters().resamples, 10);
  EXPECT_LT(first_spread, 0.01);  // the weights and resampling narrowed the prior's draws
  f.Reset(d.initial_pose);        // closes the set: the counters keep describing it
  EXPECT_EQ(f.Counters().at("sensor_yaw_mean"), first_mean);
  EXPECT_EQ(f.Counters().at("sensor_yaw_spread"), first_spread);
  f.Reset(d.initial_pose);  // a set that saw no scan is not counted
  EXPECT_EQ(f.Counters().at("sensor_yaw_mean"), first_mean);
  RunFilter(&f, d);
  EXPECT_EQ(f.Counters().at("sensor_yaw_mean"), first_mean);  // the closed sets until the next close
  f.Reset(d.initial_pose);
  EXPECT_NE(f.Counters().at("sensor_yaw_mean"), first_mean);  // now the average of two
  EXPECT_LT(f.Counters().at("sensor_yaw_spread"), 0.01);
}

// Two landmarks 1 m apart; a later detection lies nearer A but carries B's signature:
// without the cue it goes to A, with it to B.
TEST(FastSlam, SignatureCueResolvesGeometricAmbiguity) {
  models::RangeBearingConfig sensor;
  sensor.sigma_range_m = 0.5;
  sensor.sigma_bearing_rad = 0.05;
  const models::RangeBearingModel model(sensor);
  const Eigen::Vector2d A(10.0, 0.0), B(10.0, 1.0);
  auto detection = [&](const Eigen::Vector2d& p, double signature) {
    const Eigen::Vector2d z = model.Observe(Pose2(), p);
    return Detection{z[0], z[1], signature, 0};
  };
  for (const double sigma_signature : {0.0, 0.05}) {
    FastSlamOptions options;
    options.num_particles = 1;
    options.sigma_signature = sigma_signature;
    FastSlam f(std::make_unique<models::UnicycleModel>(models::ControlNoise{}), sensor, Pose2(), options);
    Scan first;
    first.detections = {detection(A, 0.2), detection(B, 0.5)};
    EXPECT_TRUE(f.Update(first).ok());
    const int feature_a = f.last_scan_features()[0], feature_b = f.last_scan_features()[1];
    ASSERT_NE(feature_a, feature_b);
    Scan second;
    second.detections = {detection(A + Eigen::Vector2d(0.0, 0.4), 0.5)};
    EXPECT_TRUE(f.Update(second).ok());
    EXPECT_EQ(f.last_scan_features()[0], sigma_signature > 0 ? feature_b : feature_a)
        << "sigma_signature " << sigma_signature;
  }
}

TEST(FastSlamOptions, ValidationRejectsNonsense) {
  FastSlamOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.num_particles = 0;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.resample_ess_ratio = 1.5;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.sigma_signature = -1;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.num_threads = -1;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.sensor_yaw_sigma = -0.01;
  EXPECT_FALSE(o.Validate().ok());
  o.sensor_yaw_sigma = NAN;
  EXPECT_FALSE(o.Validate().ok());
  // A repair floor below what LocalSubmap::Validate accepts would abort at export.
  o = {};
  o.moment_matching.repair_relative_floor = 0.0;
  EXPECT_FALSE(o.Validate().ok());
  o.moment_matching.repair_relative_floor = 1.0;
  EXPECT_FALSE(o.Validate().ok());
  o.moment_matching.repair_relative_floor = 1e-12;
  EXPECT_TRUE(o.Validate().ok());
}

}  // namespace
}  // namespace subslam::frontend
