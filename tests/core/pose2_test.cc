#include "subslam/core/pose2.h"

#include <gtest/gtest.h>

#include <functional>

#include "test_util.h"

namespace subslam {
namespace {

using testing::JacobianMatches;
using testing::kExactTolerance;
using testing::kJacobianTolerance;
using testing::MatricesNear;
using testing::TestPoses;

Eigen::VectorXd V(const Pose2& p) { return p.vector(); }

TEST(WrapAngle, MapsIntoHalfOpenInterval) {
  EXPECT_DOUBLE_EQ(WrapAngle(kPi), kPi);
  EXPECT_DOUBLE_EQ(WrapAngle(-kPi), kPi);
  EXPECT_NEAR(WrapAngle(3 * kPi), kPi, kExactTolerance);
  EXPECT_NEAR(WrapAngle(-3 * kPi + 0.1), -kPi + 0.1, kExactTolerance);
  EXPECT_NEAR(WrapAngle(7.0), 7.0 - kTwoPi, kExactTolerance);
  double J = 0;
  EXPECT_DOUBLE_EQ(WrapAngle(0.3, &J), 0.3);
  EXPECT_EQ(J, 1.0);
  // Numerical derivative away from the cut.
  for (double a : {-2.0, 0.0, 1.0, 4.0, -7.0}) {
    const double d = (WrapAngle(a + 1e-6) - WrapAngle(a - 1e-6)) / 2e-6;
    EXPECT_NEAR(d, 1.0, kJacobianTolerance);
  }
}

TEST(Pose2, ComposeInverseIdentity) {
  for (const Pose2& a : TestPoses()) {
    const Pose2 id = Compose(Inverse(a), a);
    EXPECT_NEAR(id.x, 0, 1e-9);
    EXPECT_NEAR(id.y, 0, 1e-9);
    EXPECT_NEAR(id.theta, 0, 1e-12);
    const Pose2 b(0.3, -1.2, 2.0);
    const Pose2 rel = Between(a, Compose(a, b));
    EXPECT_NEAR(rel.x, b.x, 1e-9);
    EXPECT_NEAR(rel.y, b.y, 1e-9);
    EXPECT_NEAR(rel.theta, b.theta, 1e-12);
  }
}

TEST(Pose2, ComposeMatchesHandComputedExample) {
  // Frame a at (1, 2) rotated by 90°: its x axis is the world's y axis.
  const Pose2 ab = Compose(Pose2(1, 2, kPi / 2), Pose2(3, 0, kPi / 2));
  EXPECT_NEAR(ab.x, 1, kExactTolerance);
  EXPECT_NEAR(ab.y, 5, kExactTolerance);
  EXPECT_NEAR(ab.theta, kPi, kExactTolerance);
  const Eigen::Vector2d q = TransformFrom(Pose2(1, 2, kPi / 2), Eigen::Vector2d(1, 0));
  EXPECT_NEAR(q.x(), 1, kExactTolerance);
  EXPECT_NEAR(q.y(), 3, kExactTolerance);
}

TEST(Pose2, JacobiansMatchNumericalDifferentiation) {
  const std::vector<Pose2> poses = TestPoses();
  for (size_t i = 0; i < poses.size(); ++i) {
    const Pose2& a = poses[i];
    const Pose2& b = poses[(i + 3) % poses.size()];
    // Functions of the first (a) or second (b) argument, as plain vectors.
    using Fn = std::function<Eigen::VectorXd(const Eigen::VectorXd&)>;
    auto of_a = [&](auto op) -> Fn {
      return [=](const Eigen::VectorXd& v) -> Eigen::VectorXd { return op(Pose2::FromVector(v), b); };
    };
    auto of_b = [&](auto op) -> Fn {
      return [=](const Eigen::VectorXd& v) -> Eigen::VectorXd { return op(a, Pose2::FromVector(v)); };
    };
    auto compose = [](const Pose2& x, const Pose2& y) { return V(Compose(x, y)); };
    auto between = [](const Pose2& x, const Pose2& y) { return V(Between(x, y)); };
    Eigen::Matrix3d Ja, Jb, Ji;
    Compose(a, b, &Ja, &Jb);
    EXPECT_TRUE(JacobianMatches(Ja, of_a(compose), a.vector(), {2}));
    EXPECT_TRUE(JacobianMatches(Jb, of_b(compose), b.vector(), {2}));
    Between(a, b, &Ja, &Jb);
    EXPECT_TRUE(JacobianMatches(Ja, of_a(between), a.vector(), {2}));
    EXPECT_TRUE(JacobianMatches(Jb, of_b(between), b.vector(), {2}));
    Inverse(a, &Ji);
    EXPECT_TRUE(JacobianMatches(
        Ji, [](const Eigen::VectorXd& v) -> Eigen::VectorXd { return V(Inverse(Pose2::FromVector(v))); }, a.vector(),
        {2}));

    const Eigen::Vector2d p(b.x, b.y);
    for (auto transform : {&TransformFrom, &TransformTo}) {
      Matrix23d Jf;
      Eigen::Matrix2d Jp;
      transform(a, p, &Jf, &Jp);
      EXPECT_TRUE(JacobianMatches(
          Jf,
          [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
            return transform(Pose2::FromVector(v), p, nullptr, nullptr);
          },
          a.vector()));
      EXPECT_TRUE(JacobianMatches(
          Jp,
          [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
            return transform(a, Eigen::Vector2d(v), nullptr, nullptr);
          },
          p));
    }
  }
}

// The first-order covariance of a ∘ b, propagated through central-difference Jacobians
// (not Compose's analytic ones); the output may be one of the inputs.
TEST(Pose2, ComposeWithCovarianceMatchesNumericalPropagation) {
  const std::vector<Pose2> poses = TestPoses();
  Eigen::Matrix3d cov_a, cov_b;
  cov_a << 0.04, 0.01, 0.002, 0.01, 0.09, -0.003, 0.002, -0.003, 0.0025;
  cov_b << 0.01, -0.002, 0.0, -0.002, 0.02, 0.001, 0.0, 0.001, 0.0004;
  using Fn = std::function<Eigen::VectorXd(const Eigen::VectorXd&)>;
  for (size_t i = 0; i < poses.size(); ++i) {
    const Pose2& a = poses[i];
    const Pose2& b = poses[(i + 2) % poses.size()];
    const Fn of_a = [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return V(Compose(Pose2::FromVector(v), b)); };
    const Fn of_b = [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return V(Compose(a, Pose2::FromVector(v))); };
    const Eigen::MatrixXd Ja = testing::NumericalJacobian(of_a, a.vector(), {2});
    const Eigen::MatrixXd Jb = testing::NumericalJacobian(of_b, b.vector(), {2});
    const Eigen::Matrix3d expected = Ja * cov_a * Ja.transpose() + Jb * cov_b * Jb.transpose();
    Eigen::Matrix3d cov_ab;
    const Pose2 ab = ComposeWithCovariance(a, cov_a, b, cov_b, &cov_ab);
    EXPECT_TRUE(MatricesNear(V(Compose(a, b)), V(ab), kExactTolerance));
    EXPECT_TRUE(MatricesNear(expected, cov_ab, kJacobianTolerance));
    Eigen::Matrix3d in_place = cov_a;
    ComposeWithCovariance(a, in_place, b, cov_b, &in_place);
    EXPECT_TRUE(MatricesNear(cov_ab, in_place, kExactTolerance));
  }
}

TEST(Pose2, TransformToInvertsTransformFrom) {
  for (const Pose2& a : TestPoses()) {
    const Eigen::Vector2d p(3.5, -2.25);
    EXPECT_TRUE(MatricesNear(p, TransformTo(a, TransformFrom(a, p)), 1e-9));
  }
}

}  // namespace
}  // namespace subslam
