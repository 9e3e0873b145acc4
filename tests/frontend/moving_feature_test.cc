#include "subslam/frontend/moving_feature_test.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <random>

#include "subslam/frontend/local_mapper.h"
#include "subslam/models/unicycle_model.h"

namespace subslam::frontend {
namespace {

// P(X > k) for X ~ Binomial(n, p), by summing the probabilities of 0..k.
double BinomialUpperTail(int n, double p, int k) {
  double term = std::pow(1.0 - p, n), below = 0.0;
  for (int i = 0; i <= k; ++i) {
    below += term;
    term *= (n - i) / (i + 1.0) * p / (1.0 - p);
  }
  return 1.0 - below;
}

// The smallest k with P(X > k) below `alpha`.
int BinomialBound(int n, double p, double alpha) {
  int k = 0;
  while (BinomialUpperTail(n, p, k) > alpha) ++k;
  return k;
}

models::RangeBearingConfig Sensor(double sigma_range_m, double sigma_bearing_rad) {
  models::RangeBearingConfig sensor;
  sensor.sigma_range_m = sigma_range_m;
  sensor.sigma_bearing_rad = sigma_bearing_rad;
  return sensor;
}

Eigen::Matrix2d RandomCovariance(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  Eigen::Matrix2d A;
  A << u(rng), u(rng), u(rng), u(rng);
  return A * A.transpose() + 0.005 * Eigen::Matrix2d::Identity();
}

// Λ from the sufficient statistics equals the difference of the two weighted least-squares
// fits computed directly, point by point, with the stacked design matrices; fits of two
// parts add up to the fit of the whole.
TEST(TrendFit, StatisticIsTheDifferenceOfTheTwoFits) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  TrendFit whole, first, second;
  const int n = 7;
  Eigen::MatrixXd A_static = Eigen::MatrixXd::Zero(2 * n, 2), A_velocity = Eigen::MatrixXd::Zero(2 * n, 4);
  Eigen::VectorXd y(2 * n);
  Eigen::MatrixXd W = Eigen::MatrixXd::Zero(2 * n, 2 * n);
  for (int k = 0; k < n; ++k) {
    const double t = 10.0 + 0.7 * k + 0.1 * u(rng);
    const Eigen::Vector2d p(u(rng), u(rng));
    const Eigen::Matrix2d C = RandomCovariance(rng);
    whole.Add(t, p, C);
    (k < 3 ? first : second).Add(t, p, C);
    A_static.block<2, 2>(2 * k, 0).setIdentity();
    A_velocity.block<2, 2>(2 * k, 0).setIdentity();
    A_velocity.block<2, 2>(2 * k, 2) = (t - 10.0) * Eigen::Matrix2d::Identity();
    y.segment<2>(2 * k) = p;
    W.block<2, 2>(2 * k, 2 * k) = C.inverse();
  }
  const auto chi2 = [&](const Eigen::MatrixXd& A) {
    const Eigen::VectorXd x = (A.transpose() * W * A).ldlt().solve(A.transpose() * W * y);
    const Eigen::VectorXd r = y - A * x;
    return r.dot(W * r);
  };
  EXPECT_NEAR(whole.Statistic(), chi2(A_static) - chi2(A_velocity), 1e-8 * chi2(A_static));
  EXPECT_EQ(whole.points(), n);
  first += second;
  EXPECT_NEAR(first.Statistic(), whole.Statistic(), 1e-8 * chi2(A_static));
  EXPECT_EQ(TrendFit().Statistic(), 0.0);
  TrendFit degenerate;
  degenerate.Add(1.0, Eigen::Vector2d(1, 2), Eigen::Matrix2d::Zero());  // not positive definite: ignored
  EXPECT_EQ(degenerate.points(), 0);
}

// Detections of static points from a vehicle that moves and turns, with the sensor's noise
// (the pose known): the features taken to move number at most the binomial bound of the
// test's false-alarm rate 1 − probability, at 0.999. A point moving at 0.5 m/s, seen ten
// times over 4.5 s with the same noise, is taken to move every time.
TEST(MovingFeatureTest, StaticPointsPassAtTheTestsRateAndMovingOnesFail) {
  const models::RangeBearingConfig sensor = Sensor(0.1, 0.02);
  MovingFeatureTestOptions options;
  MovingFeatureTest test(options, sensor);
  const models::RangeBearingModel model(sensor);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> place(2.0, 8.0), count(3.0, 12.0);
  const int static_features = 2000, moving_features = 200;
  int static_flagged = 0, moving_flagged = 0;
  for (int f = 0; f < static_features + moving_features; ++f) {
    const bool moving = f >= static_features;
    const Eigen::Vector2d start(place(rng), place(rng) - 5.0);
    const Eigen::Vector2d velocity = moving ? Eigen::Vector2d(0.3, 0.4) : Eigen::Vector2d::Zero();  // 0.5 m/s
    const int n = moving ? 10 : static_cast<int>(count(rng));
    test.Reset();
    for (int k = 0; k < n; ++k) {
      const double t = 0.5 * k;
      const Pose2 pose(0.2 * t, 0.05 * t, 0.1 * t);
      Eigen::Vector2d z = model.Observe(pose, start + velocity * t);
      z += Eigen::Vector2d(sensor.sigma_range_m * noise(rng), sensor.sigma_bearing_rad * noise(rng));
      test.AddScan(t, pose, Eigen::Matrix3d::Zero(), {z}, {f});
    }
    (moving ? moving_flagged : static_flagged) += test.Moving(f) ? 1 : 0;
  }
  EXPECT_LE(static_flagged, BinomialBound(static_features, 1.0 - options.probability, 0.001));
  EXPECT_EQ(moving_flagged, moving_features);
}

// A feature hands over to the one that starts where its detections stopped, and the chain
// is tested as one track: three features of two detections each, along a line at 1 m/s,
// move together, though none has min_detections alone. A feature detected again after
// another started near it (a static landmark) hands over to nothing. Probability 0 turns
// the test off; options out of range are refused.
TEST(MovingFeatureTest, FeaturesHandOverAlongATrack) {
  const models::RangeBearingConfig sensor = Sensor(0.05, 0.005);
  MovingFeatureTestOptions options;
  MovingFeatureTest test(options, sensor);
  const models::RangeBearingModel model(sensor);
  const Pose2 pose;
  for (int k = 0; k < 6; ++k) {
    const double t = 0.1 * k;
    test.AddScan(t, pose, Eigen::Matrix3d::Zero(), {model.Observe(pose, Eigen::Vector2d(5.0, -1.0 + t))}, {10 + k / 2});
  }
  for (int f : {10, 11, 12}) {
    EXPECT_EQ(test.TrackDetections(f), 6) << f;
    EXPECT_TRUE(test.Moving(f)) << f;
  }
  // A landmark (feature 20) still detected after feature 21 began next to it.
  test.Reset();
  const Eigen::Vector2d landmark(4.0, 1.0);
  test.AddScan(0.0, pose, Eigen::Matrix3d::Zero(), {model.Observe(pose, landmark)}, {20});
  test.AddScan(0.1, pose, Eigen::Matrix3d::Zero(), {model.Observe(pose, landmark + Eigen::Vector2d(0.01, 0.0))}, {21});
  test.AddScan(0.2, pose, Eigen::Matrix3d::Zero(), {model.Observe(pose, landmark)}, {20});
  EXPECT_EQ(test.TrackDetections(20), 2);
  EXPECT_EQ(test.TrackDetections(21), 1);
  EXPECT_EQ(test.TrackDetections(99), 0);  // never seen
  EXPECT_FALSE(test.Moving(99));

  options.probability = 0.0;
  MovingFeatureTest off(options, sensor);
  for (int k = 0; k < 6; ++k) {
    off.AddScan(0.1 * k, pose, Eigen::Matrix3d::Zero(), {model.Observe(pose, Eigen::Vector2d(5.0, k))}, {1});
  }
  EXPECT_FALSE(off.Moving(1));

  for (const double p : {-0.1, 1.0, std::nan("")}) {
    MovingFeatureTestOptions bad;
    bad.probability = p;
    EXPECT_FALSE(bad.Validate().ok()) << p;
    bad = MovingFeatureTestOptions();
    bad.link_probability = p;
    EXPECT_FALSE(bad.Validate().ok()) << p;
  }
  MovingFeatureTestOptions short_tracks;
  short_tracks.min_detections = 1;
  EXPECT_FALSE(short_tracks.Validate().ok());
}

// An RBPF local mapper watching three static landmarks and an object that crosses the view
// at 0.2 m/s (the filter follows it with a chain of features) exports the three landmarks and not the object; with the
// test off it exports the object too.
TEST(MovingFeatureTest, TheLocalMapperDoesNotExportAMovingObject) {
  models::RangeBearingConfig sensor = Sensor(0.05, 0.01);
  sensor.max_range_m = 10.0;
  const models::RangeBearingModel model(sensor);
  const std::vector<Eigen::Vector2d> landmarks = {{4.0, 1.5}, {5.0, -1.0}, {6.0, 2.5}};
  for (const double probability : {0.999, 0.0}) {
    SubmapPolicyOptions policy;
    policy.max_duration_s = 0.0;
    policy.min_lineage_diversity = 0.0;
    policy.max_features = 0;
    policy.moving_features.probability = probability;
    FastSlamOptions fastslam;
    fastslam.num_particles = 20;
    models::ControlNoise noise;
    noise.sigma_u0 = 0.01;
    noise.sigma_u1 = 0.005;
    RbpfLocalMapper mapper(std::make_unique<models::UnicycleModel>(noise), sensor, fastslam, policy, 0.0);
    std::mt19937_64 rng(5);
    std::normal_distribution<double> n01(0.0, 1.0);
    Pose2 truth;
    for (int k = 1; k <= 40; ++k) {
      const Eigen::Vector2d u(0.1, 0.0);
      mapper.Predict(u, 0.25);
      truth = Pose2(truth.x + 0.025, truth.y, truth.theta);
      Scan scan;
      scan.t = 0.25 * k;
      std::vector<Eigen::Vector2d> points = landmarks;
      points.push_back(Eigen::Vector2d(3.0, -1.5 + 0.2 * scan.t));  // the moving object
      for (const Eigen::Vector2d& p : points) {
        const Eigen::Vector2d z = model.Observe(truth, p);
        scan.detections.push_back({z[0] + sensor.sigma_range_m * n01(rng), z[1] + sensor.sigma_bearing_rad * n01(rng)});
      }
      EXPECT_TRUE(mapper.Update(scan).ok());
    }
    mapper.Finish();
    const std::vector<ClosedLocalMap> closed = mapper.TakeClosed();
    ASSERT_EQ(closed.size(), 1u);
    const LocalSubmap& s = closed[0].submap;
    int static_exported = 0, other = 0;
    for (int i = 0; i < s.num_landmarks(); ++i) {
      const Eigen::Vector2d p = s.mean.segment<2>(3 + 2 * i);
      bool near = false;
      for (const Eigen::Vector2d& l : landmarks) near = near || (p - l).norm() < 0.3;
      (near ? static_exported : other) += 1;
    }
    EXPECT_EQ(static_exported, 3) << probability;
    if (probability > 0.0) {
      EXPECT_EQ(other, 0);
      EXPECT_GE(mapper.Counters().at("moving_features_not_exported"), 1.0);
    } else {
      EXPECT_GE(other, 1);
      EXPECT_EQ(mapper.Counters().at("moving_features_not_exported"), 0.0);
    }
  }
}

}  // namespace
}  // namespace subslam::frontend
