#include "subslam/posegraph/measurement_residuals.h"

#include <gtest/gtest.h>

#include "test_util.h"

namespace subslam::posegraph {
namespace {

using testing::JacobianMatches;
using testing::TestPoses;

Eigen::VectorXd Stack(const Pose2& a, const Eigen::VectorXd& b) {
  Eigen::VectorXd x(3 + b.size());
  x << a.vector(), b;
  return x;
}

TEST(MeasurementResiduals, OdometryJacobiansMatchCentralDifferences) {
  const Pose2 z(0.7, -0.2, 0.3);
  for (const Pose2& from : TestPoses()) {
    const Pose2 to = Compose(from, Pose2(1.1, 0.4, -2.9));
    Eigen::Matrix3d J_from, J_to;
    OdometryResidual(z, from, to, &J_from, &J_to);
    const auto f = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd {
      return OdometryResidual(z, Pose2(x[0], x[1], x[2]), Pose2(x[3], x[4], x[5]));
    };
    Eigen::MatrixXd J(3, 6);
    J << J_from, J_to;
    EXPECT_TRUE(JacobianMatches(J, f, Stack(from, to.vector()), {2}));
  }
}

TEST(MeasurementResiduals, OdometryResidualIsZeroAtTheMeasurementAndG2oError) {
  const Pose2 from(1.0, 2.0, 0.5), z(0.3, -0.4, 0.2);
  EXPECT_NEAR(OdometryResidual(z, from, Compose(from, z)).norm(), 0.0, 1e-12);
  // g2o's EDGE_SE2 error: (z⁻¹ ∘ (from⁻¹ ∘ to)) as a vector.
  const Pose2 to(1.5, 2.1, 0.9);
  const Eigen::Vector3d expected = Compose(Inverse(z), Between(from, to)).vector();
  EXPECT_NEAR((OdometryResidual(z, from, to) - expected).norm(), 0.0, 1e-12);
}

TEST(MeasurementResiduals, PointBearingRangeAndBearingJacobiansMatchCentralDifferences) {
  const Eigen::Vector2d point_offset(3.0, -1.5);
  for (const Pose2& pose : TestPoses()) {
    const Eigen::Vector2d point = TransformFrom(pose, point_offset);
    const Eigen::VectorXd x = Stack(pose, point);
    Matrix23d Jp;
    Eigen::Matrix2d Jl;
    PointResidual(Eigen::Vector2d(0.1, 0.2), pose, point, &Jp, &Jl);
    Eigen::MatrixXd J(2, 5);
    J << Jp, Jl;
    EXPECT_TRUE(JacobianMatches(
        J,
        [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
          return PointResidual(Eigen::Vector2d(0.1, 0.2), Pose2(v[0], v[1], v[2]), v.tail<2>());
        },
        x));
    BearingRangeResidual(0.3, 2.0, pose, point, &Jp, &Jl);
    J << Jp, Jl;
    EXPECT_TRUE(JacobianMatches(J,
                                [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
                                  return BearingRangeResidual(0.3, 2.0, Pose2(v[0], v[1], v[2]), v.tail<2>());
                                },
                                x, {0}));
    Eigen::RowVector3d jp;
    Eigen::RowVector2d jl;
    BearingResidual(-0.2, pose, point, &jp, &jl);
    Eigen::MatrixXd Jb(1, 5);
    Jb << jp, jl;
    EXPECT_TRUE(JacobianMatches(Jb,
                                [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
                                  return Eigen::VectorXd::Constant(
                                      1, BearingResidual(-0.2, Pose2(v[0], v[1], v[2]), v.tail<2>()));
                                },
                                x, {0}));
  }
}

TEST(MeasurementResiduals, BearingRangeKnownValues) {
  // A point 2 m ahead and 2 m to the left of a pose heading along +y.
  const Pose2 pose(1.0, 1.0, kPi / 2);
  const Eigen::Vector2d point(-1.0, 3.0);
  const Eigen::Vector2d r = BearingRangeResidual(0.0, 0.0, pose, point);
  EXPECT_NEAR(r[0], kPi / 4, 1e-12);
  EXPECT_NEAR(r[1], std::sqrt(8.0), 1e-12);
  EXPECT_NEAR(BearingResidual(kPi / 4, pose, point), 0.0, 1e-12);
  // Wrapped across ±π.
  EXPECT_NEAR(BearingRangeResidual(kPi - 0.1, 0.0, Pose2(), Eigen::Vector2d(-1.0, -0.1))[0],
              WrapAngle(std::atan2(-0.1, -1.0) - (kPi - 0.1)), 1e-12);
  EXPECT_LT(std::abs(BearingRangeResidual(kPi - 0.1, 0.0, Pose2(), Eigen::Vector2d(-1.0, -0.1))[0]), 0.3);
}

}  // namespace
}  // namespace subslam::posegraph
