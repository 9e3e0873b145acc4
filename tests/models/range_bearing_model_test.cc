#include "subslam/models/range_bearing_model.h"

#include <gtest/gtest.h>

#include <Eigen/LU>

#include "subslam/models/gating.h"
#include "test_util.h"

namespace subslam::models {
namespace {

using testing::JacobianMatches;
using testing::MatricesNear;
using testing::TestPoses;

TEST(RangeBearingModel, ObserveHandExample) {
  const RangeBearingModel model(RangeBearingConfig{});
  const Eigen::Vector2d z = model.Observe(Pose2(1, 1, kPi / 2), Eigen::Vector2d(1, 4));
  EXPECT_NEAR(z[0], 3.0, 1e-12);
  EXPECT_NEAR(z[1], 0.0, 1e-12);  // straight ahead
  const Eigen::Vector2d left = model.Observe(Pose2(0, 0, 0), Eigen::Vector2d(0, 2));
  EXPECT_NEAR(left[1], kPi / 2, 1e-12);  // bearing counter-clockwise
}

TEST(RangeBearingModel, JacobiansAndInverse) {
  const RangeBearingModel model(RangeBearingConfig{});
  for (const Pose2& p : TestPoses()) {
    const Eigen::Vector2d l(p.x + 3.0, p.y - 4.5);
    Matrix23d Jp;
    Eigen::Matrix2d Jl;
    const Eigen::Vector2d z = model.Observe(p, l, &Jp, &Jl);
    EXPECT_TRUE(JacobianMatches(
        Jp, [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return model.Observe(Pose2::FromVector(v), l); },
        p.vector(), {1}));
    EXPECT_TRUE(JacobianMatches(
        Jl, [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return model.Observe(p, Eigen::Vector2d(v)); }, l, {1}));
    Matrix23d Gp;
    Eigen::Matrix2d Gz;
    const Eigen::Vector2d back = model.InverseObserve(p, z, &Gp, &Gz);
    EXPECT_TRUE(MatricesNear(l, back, 1e-9));
    EXPECT_TRUE(JacobianMatches(
        Gp, [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return model.InverseObserve(Pose2::FromVector(v), z); },
        p.vector()));
    EXPECT_TRUE(JacobianMatches(
        Gz, [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return model.InverseObserve(p, Eigen::Vector2d(v)); },
        z));
    // The inverse Jacobian w.r.t. z is the inverse of the forward one w.r.t. l.
    EXPECT_TRUE(MatricesNear(Jl.inverse(), Gz, 1e-9));
  }
}

TEST(RangeBearingModel, VisibilityAndValidation) {
  RangeBearingConfig c;
  c.max_range_m = 30;
  c.fov_min_rad = -kPi / 2;
  c.fov_max_rad = kPi / 2;
  const RangeBearingModel model(c);
  EXPECT_TRUE(model.IsVisible(Eigen::Vector2d(10, 0.3)));
  EXPECT_FALSE(model.IsVisible(Eigen::Vector2d(31, 0.3)));
  EXPECT_FALSE(model.IsVisible(Eigen::Vector2d(10, 2.0)));
  EXPECT_FALSE(model.IsVisible(Eigen::Vector2d(29.5, 0.3), 1.0, 0.0));
  c.sigma_range_m = 0.0;
  EXPECT_FALSE(c.Validate().ok());
  c.sigma_range_m = 0.1;
  c.fov_min_rad = 1.0;
  c.fov_max_rad = 0.5;
  EXPECT_FALSE(c.Validate().ok());
}

TEST(Gating, ChiSquareQuantilesMatchTables) {
  EXPECT_NEAR(ChiSquareQuantile(0.95, 2), 5.991464547, 1e-8);
  EXPECT_NEAR(ChiSquareQuantile(0.95, 3), 7.814727903, 1e-8);
  EXPECT_NEAR(ChiSquareQuantile(0.99, 2), 9.210340372, 1e-8);
  EXPECT_NEAR(ChiSquareCdf(ChiSquareQuantile(0.3, 5), 5), 0.3, 1e-12);
}

TEST(Gating, MahalanobisDistance) {
  Eigen::Matrix2d S;
  S << 4, 1, 1, 2;
  const Eigen::Vector2d v(1, -2);
  const double expected = v.dot(S.inverse() * v);
  EXPECT_NEAR(*MahalanobisSquared2(v, S), expected, 1e-12);
  EXPECT_NEAR(*MahalanobisSquared(Eigen::VectorXd(v), Eigen::MatrixXd(S)), expected, 1e-12);
  S << 1, 2, 2, 1;  // indefinite
  EXPECT_FALSE(MahalanobisSquared2(v, S).has_value());
  EXPECT_FALSE(MahalanobisSquared(Eigen::VectorXd(v), Eigen::MatrixXd(S)).has_value());
}

}  // namespace
}  // namespace subslam::models
