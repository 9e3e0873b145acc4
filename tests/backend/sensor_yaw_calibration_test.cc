#include "subslam/backend/sensor_yaw_calibration.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "subslam/models/gating.h"

namespace subslam::backend {
namespace {

// A local map with `n` features at the given positions (start frame), an end pose, and a
// covariance with cross-terms (so that every block of the Jacobians is exercised).
LocalSubmap MakeMap(int id, const Pose2& end, const std::vector<Eigen::Vector2d>& features) {
  LocalSubmap m;
  m.id = id;
  m.t_start = id;
  m.t_end = id + 1;
  const int dim = 3 + 2 * static_cast<int>(features.size());
  m.mean.resize(dim);
  m.mean.head<3>() = end.vector();
  for (size_t k = 0; k < features.size(); ++k) {
    m.mean.segment<2>(3 + 2 * k) = features[k];
    LocalSubmapLandmark l;
    l.local_id = static_cast<int>(k);
    m.landmarks.push_back(l);
  }
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(dim, dim) * 0.1;
  for (int r = 1; r < dim; ++r) A(r, r - 1) = 0.02;
  A(2, 2) = 0.01;  // the heading's: 10 mrad
  A(2, 1) = 0.002;
  m.covariance = A * A.transpose();
  return m;
}

TEST(SensorYawCalibration, PairDifferenceJacobiansMatchNumericalDifferentiation) {
  const LocalSubmap earlier = MakeMap(0, Pose2(5.0, 1.0, 0.4), {{12.0, -3.0}, {8.0, 6.0}});
  const LocalSubmap later = MakeMap(1, Pose2(4.0, -0.5, -0.2), {{3.0, 2.0}, {9.0, -7.0}, {1.0, 1.0}});
  const double yaw = 0.03;
  const YawPairDifference p = PairDifference(earlier, 1, later, 2, yaw);
  const double h = 1e-6;
  const auto diff = [&](const LocalSubmap& e, const LocalSubmap& l, double y) {
    return PairDifference(e, 1, l, 2, y).d;
  };
  EXPECT_TRUE(p.d_yaw.isApprox((diff(earlier, later, yaw + h) - diff(earlier, later, yaw - h)) / (2 * h), 1e-6));
  const int earlier_rows[5] = {5, 6, 0, 1, 2};
  for (int c = 0; c < 5; ++c) {
    LocalSubmap plus = earlier, minus = earlier;
    plus.mean[earlier_rows[c]] += h;
    minus.mean[earlier_rows[c]] -= h;
    const Eigen::Vector2d numeric = (diff(plus, later, yaw) - diff(minus, later, yaw)) / (2 * h);
    EXPECT_LT((p.d_earlier.col(c) - numeric).norm(), 1e-7) << "earlier column " << c;
  }
  const int later_rows[4] = {7, 8, 0, 1};
  for (int c = 0; c < 4; ++c) {
    LocalSubmap plus = later, minus = later;
    plus.mean[later_rows[c]] += h;
    minus.mean[later_rows[c]] -= h;
    const Eigen::Vector2d numeric = (diff(earlier, plus, yaw) - diff(earlier, minus, yaw)) / (2 * h);
    EXPECT_LT((p.d_later.col(c) - numeric).norm(), 1e-7) << "later column " << c;
  }
}

TEST(SensorYawCalibration, RotatedTurnsFeaturesAboutThePathCentreAndTransformsTheCovariance) {
  const LocalSubmap map = MakeMap(0, Pose2(6.0, 2.0, 0.3), {{13.0, 2.0}, {-2.0, 9.0}});
  // Unchanged by a zero turn.
  const LocalSubmap same = SensorYawCalibration::Rotated(map, 0.0);
  EXPECT_EQ(same.mean, map.mean);
  EXPECT_EQ(same.covariance, map.covariance);
  const double yaw = 0.1;
  const LocalSubmap turned = SensorYawCalibration::Rotated(map, yaw);
  // The centre (3, 1); feature (13, 2) is 10 east and 1 north of it.
  const Eigen::Vector2d u(10.0, 1.0);
  const Eigen::Vector2d expected = Eigen::Vector2d(3.0, 1.0) + Eigen::Rotation2Dd(yaw).toRotationMatrix() * u;
  EXPECT_LT((turned.landmark(0) - expected).norm(), 1e-12);
  EXPECT_EQ(turned.mean.head<3>(), map.mean.head<3>());
  // Covariance: G P Gᵀ with G = ∂turned.mean/∂map.mean, numerical here.
  const int dim = static_cast<int>(map.mean.size());
  const double h = 1e-6;
  Eigen::MatrixXd G(dim, dim);
  for (int c = 0; c < dim; ++c) {
    LocalSubmap plus = map, minus = map;
    plus.mean[c] += h;
    minus.mean[c] -= h;
    G.col(c) =
        (SensorYawCalibration::Rotated(plus, yaw).mean - SensorYawCalibration::Rotated(minus, yaw).mean) / (2 * h);
  }
  const Eigen::MatrixXd expected_covariance = G * map.covariance * G.transpose();
  EXPECT_LT((turned.covariance - expected_covariance).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_TRUE(map.Validate().ok()) << map.Validate().message();
  EXPECT_TRUE(turned.Validate().ok()) << turned.Validate().message();
}

// Maps along a straight road through a field of trees, each map's features the trees within
// reach of its path turned by −`yaw` about the path's centre (what a sensor turned by −yaw
// gives in this model), then perturbed by the maps' own covariance (fixed seed).
std::vector<LocalSubmap> ModelMaps(double yaw, int maps, std::mt19937_64* rng) {
  std::vector<Eigen::Vector2d> trees;
  for (int i = 0; i < 12 * maps; ++i)
    trees.emplace_back(2.5 * i + 0.7 * (i % 3), (i % 2 == 0 ? 1 : -1) * (4.0 + (i % 5) * 3.0));
  const double step = 6.0;
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<LocalSubmap> out;
  for (int k = 0; k < maps; ++k) {
    const Eigen::Vector2d start(step * k, 0.0);
    const Eigen::Vector2d centre(0.5 * step, 0.0);
    std::vector<Eigen::Vector2d> features;
    for (const Eigen::Vector2d& t : trees) {
      const Eigen::Vector2d local = t - start;
      if ((local - centre).norm() < 20.0) {
        features.push_back(centre + Eigen::Rotation2Dd(-yaw).toRotationMatrix() * (local - centre));
      }
    }
    LocalSubmap m = MakeMap(k, Pose2(step, 0.0, 0.0), features);
    m.covariance.diagonal().tail(m.covariance.rows() - 3).array() += 0.01;  // 10 cm and more
    const Eigen::MatrixXd L = m.covariance.llt().matrixL();
    Eigen::VectorXd e(m.mean.size());
    for (int i = 0; i < e.size(); ++i) e[i] = normal(*rng);
    m.mean += L * e;
    out.push_back(m);
  }
  return out;
}

// Every map given to the calibration; what a joiner would hold at the end (a restart
// drops what was joined before it).
std::vector<LocalSubmap> RunThrough(SensorYawCalibration* calibration, const std::vector<LocalSubmap>& maps) {
  std::vector<LocalSubmap> joined;
  for (const LocalSubmap& m : maps) {
    SensorYawCalibration::Ready ready = calibration->Add(m);
    if (ready.restart) joined.clear();
    for (LocalSubmap& r : ready.maps) joined.push_back(std::move(r));
  }
  return joined;
}

TEST(SensorYawCalibration, EstimateIsUnbiasedAndItsSigmaHoldsOverMonteCarloRuns) {
  // Over N independent runs, Σ ((δ̂ − δ) / σ̂)² is χ²_N if the estimate is unbiased and its
  // sigma right; the bounds are its 0.1 % and 99.9 % quantiles.
  constexpr int kRuns = 40;
  for (double yaw : {0.0, 0.02}) {
    std::mt19937_64 rng(7);
    double chi2 = 0.0;
    for (int run = 0; run < kRuns; ++run) {
      SensorYawCalibration calibration({.prior_sigma_rad = 1.0});  // a prior that does not pull
      RunThrough(&calibration, ModelMaps(yaw, 12, &rng));
      ASSERT_GT(calibration.pairs(), 50);
      const double z = (calibration.estimate() - yaw) / calibration.sigma();
      chi2 += z * z;
    }
    EXPECT_LT(chi2, models::ChiSquareQuantile(0.999, kRuns)) << "yaw " << yaw;
    EXPECT_GT(chi2, models::ChiSquareQuantile(0.001, kRuns)) << "yaw " << yaw;
  }
}

TEST(SensorYawCalibration, WarmUpEndsWithTheFirstMapsTurnedThenTurnsEveryMapByTheEstimateOfItsTime) {
  std::mt19937_64 rng(3);
  const std::vector<LocalSubmap> maps = ModelMaps(0.03, 10, &rng);
  SensorYawCalibration calibration({});
  // The warm-up's maps go on as built, one at a time, until the estimate differs from zero.
  size_t k = 0;
  SensorYawCalibration::Ready ready;
  for (; k < maps.size(); ++k) {
    ready = calibration.Add(maps[k]);
    if (ready.restart) break;
    ASSERT_EQ(ready.maps.size(), 1u);
    EXPECT_EQ(ready.maps[0].mean, maps[k].mean);
  }
  // Then all of them again, from the first, turned by that estimate.
  ASSERT_LT(k, maps.size());
  EXPECT_GE(k, 1u);
  ASSERT_EQ(ready.maps.size(), k + 1);
  for (size_t i = 0; i <= k; ++i) {
    const LocalSubmap expected = SensorYawCalibration::Rotated(maps[i], calibration.estimate());
    EXPECT_EQ(ready.maps[i].mean, expected.mean);
    EXPECT_EQ(ready.maps[i].covariance, expected.covariance);
  }
  for (++k; k < maps.size(); ++k) {  // then each map by the estimate after its own pairs
    ready = calibration.Add(maps[k]);
    EXPECT_FALSE(ready.restart);
    ASSERT_EQ(ready.maps.size(), 1u);
    EXPECT_EQ(ready.maps[0].mean, SensorYawCalibration::Rotated(maps[k], calibration.estimate()).mean);
  }
  EXPECT_EQ(calibration.maps_turned(), 10);
  EXPECT_EQ(calibration.restarts(), 1);
  EXPECT_EQ(calibration.Counters().at("sensor_yaw_joiner_restarts"), 1.0);
  EXPECT_NEAR(calibration.estimate(), 0.03, 4.0 * calibration.sigma());
}

TEST(SensorYawCalibration, MapsWithoutMisalignmentAreJoinedAsBuilt) {
  std::mt19937_64 rng(11);
  const std::vector<LocalSubmap> maps = ModelMaps(0.0, 60, &rng);
  SensorYawCalibration calibration({});
  for (const LocalSubmap& m : maps) {
    const SensorYawCalibration::Ready ready = calibration.Add(m);
    EXPECT_FALSE(ready.restart);
    ASSERT_EQ(ready.maps.size(), 1u);
    EXPECT_EQ(ready.maps[0].mean, m.mean);
  }
  EXPECT_EQ(calibration.maps_turned(), 0);
}

TEST(SensorYawCalibration, OffPassesMapsOnAsBuilt) {
  std::mt19937_64 rng(3);
  SensorYawCalibration calibration({.enabled = false});
  for (const LocalSubmap& m : ModelMaps(0.03, 3, &rng)) {
    const SensorYawCalibration::Ready ready = calibration.Add(m);
    EXPECT_FALSE(ready.restart);
    ASSERT_EQ(ready.maps.size(), 1u);
    EXPECT_EQ(ready.maps[0].mean, m.mean);
    EXPECT_EQ(ready.maps[0].covariance, m.covariance);
  }
  EXPECT_EQ(calibration.pairs(), 0);
  EXPECT_EQ(calibration.estimate(), 0.0);
  EXPECT_TRUE(calibration.Counters().empty());
}

TEST(SensorYawCalibration, MapsWithoutFeaturesArePassedOn) {
  SensorYawCalibration calibration({});
  const LocalSubmap empty = MakeMap(0, Pose2(1.0, 0.0, 0.1), {});
  const LocalSubmap one = MakeMap(1, Pose2(1.0, 0.0, 0.0), {{3.0, 1.0}});
  const std::vector<LocalSubmap> joined = RunThrough(&calibration, {empty, one});
  ASSERT_EQ(joined.size(), 2u);
  EXPECT_EQ(joined[0].mean, empty.mean);
  EXPECT_EQ(joined[1].mean, one.mean);
  EXPECT_EQ(calibration.pairs(), 0);
}

TEST(SensorYawCalibrationOptions, BadValuesAreRefused) {
  EXPECT_TRUE(SensorYawCalibrationOptions{}.Validate().ok());
  for (double sigma : {0.0, -1.0, std::nan("")}) {
    const absl::Status s = SensorYawCalibrationOptions{.prior_sigma_rad = sigma}.Validate();
    EXPECT_FALSE(s.ok());
    EXPECT_NE(s.message().find("prior_sigma_rad"), std::string::npos);
  }
  for (double p : {0.0, 1.0, 1.5}) {
    EXPECT_FALSE(SensorYawCalibrationOptions{.gate_probability = p}.Validate().ok());
    EXPECT_FALSE(SensorYawCalibrationOptions{.significance = p}.Validate().ok());
  }
  EXPECT_FALSE(SensorYawCalibrationOptions{.settled_sigma_rad = -1.0}.Validate().ok());
  EXPECT_FALSE(SensorYawCalibrationOptions{.warm_up_maps = -1}.Validate().ok());
}

}  // namespace
}  // namespace subslam::backend
