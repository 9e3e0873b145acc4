#include <gtest/gtest.h>

#include <cmath>

#include "subslam/models/ackermann_model.h"
#include "subslam/models/unicycle_model.h"
#include "test_util.h"

namespace subslam::models {
namespace {

using testing::JacobianMatches;
using testing::MatricesNear;
using testing::TestPoses;

void CheckJacobians(const MotionModel& model, const Pose2& x, const Eigen::Vector2d& u, double dt) {
  Eigen::Matrix3d Jx;
  Matrix32d Ju;
  model.Predict(x, u, dt, &Jx, &Ju);
  EXPECT_TRUE(JacobianMatches(
      Jx,
      [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return model.Predict(Pose2::FromVector(v), u, dt).vector(); },
      x.vector(), {2}))
      << model.Name() << " J_x at " << x << " u " << u.transpose();
  EXPECT_TRUE(JacobianMatches(
      Ju,
      [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return model.Predict(x, Eigen::Vector2d(v), dt).vector(); }, u,
      {2}))
      << model.Name() << " J_u at " << x << " u " << u.transpose();
}

TEST(UnicycleModel, JacobiansMatchNumericalDifferentiation) {
  const UnicycleModel model;
  for (const Pose2& x : TestPoses()) {
    for (const Eigen::Vector2d& u : {Eigen::Vector2d(1.0, 0.5), Eigen::Vector2d(3.0, -2.0), Eigen::Vector2d(2.0, 0.0),
                                     Eigen::Vector2d(2.0, 1e-6), Eigen::Vector2d(0.0, 0.3)}) {
      CheckJacobians(model, x, u, 0.1);
    }
  }
}

TEST(UnicycleModel, ExactArcAndStraightLineLimit) {
  const UnicycleModel model;
  // Quarter circle of radius 2: v = 2 m/s, ω = 1 rad/s for π/2 s.
  const Pose2 end = model.Predict(Pose2(), Eigen::Vector2d(2.0, 1.0), kPi / 2);
  EXPECT_NEAR(end.x, 2.0, 1e-12);
  EXPECT_NEAR(end.y, 2.0, 1e-12);
  EXPECT_NEAR(end.theta, kPi / 2, 1e-12);
  // ω = 0 is a straight line and the series branch is continuous with the closed form.
  const Pose2 straight = model.Predict(Pose2(1, 1, 0.5), Eigen::Vector2d(2.0, 0.0), 1.0);
  EXPECT_NEAR(straight.x, 1 + 2 * std::cos(0.5), 1e-12);
  EXPECT_NEAR(straight.y, 1 + 2 * std::sin(0.5), 1e-12);
  const Pose2 below = model.Predict(Pose2(), Eigen::Vector2d(2.0, 0.99e-4), 1.0);
  const Pose2 above = model.Predict(Pose2(), Eigen::Vector2d(2.0, 1.01e-4), 1.0);
  EXPECT_NEAR(below.y, 0.99e-4, 1e-9);  // y ≈ v·dt·φ/2
  EXPECT_NEAR(above.y, 1.01e-4, 1e-9);
}

TEST(AckermannModel, JacobiansMatchNumericalDifferentiation) {
  const AckermannModel vp({2.83, 0.76, 3.78, 0.50}, {0.5, 0.05, 0, 0});
  const AckermannModel bicycle({4.0, 0.0, 0.0, 0.0}, {0.3, 0.03, 0, 0});
  for (const Pose2& x : TestPoses()) {
    for (const Eigen::Vector2d& u : {Eigen::Vector2d(2.0, 0.3), Eigen::Vector2d(3.0, -0.5), Eigen::Vector2d(1.0, 0.0),
                                     Eigen::Vector2d(0.0, 0.2)}) {
      CheckJacobians(vp, x, u, 0.025);
      CheckJacobians(bicycle, x, u, 0.025);
    }
  }
}

TEST(AckermannModel, MatchesVictoriaParkEquations) {
  // One Euler step against the README's continuous-time model written out directly.
  const double L = 2.83, H = 0.76, a = 3.78, b = 0.50;
  const AckermannModel model({L, H, a, b}, {0.5, 0.05, 0, 0});
  const Pose2 x(1.0, -2.0, 0.7);
  const double v = 2.5, steer = 0.2, dt = 0.025;
  const double vc = v / (1 - std::tan(steer) * H / L);
  const double phi_dot = vc / L * std::tan(steer);
  const double xd = vc * std::cos(x.theta) - phi_dot * (a * std::sin(x.theta) + b * std::cos(x.theta));
  const double yd = vc * std::sin(x.theta) + phi_dot * (a * std::cos(x.theta) - b * std::sin(x.theta));
  const Pose2 next = model.Predict(x, Eigen::Vector2d(v, steer), dt);
  EXPECT_NEAR(next.x, x.x + dt * xd, 1e-12);
  EXPECT_NEAR(next.y, x.y + dt * yd, 1e-12);
  EXPECT_NEAR(next.theta, x.theta + dt * phi_dot, 1e-12);
}

TEST(MotionModel, ProcessCovarianceIsPropagatedControlNoise) {
  const UnicycleModel model({0.1, 0.02, 0.25, 0.35});
  const Eigen::Vector2d u(2.0, 0.5);
  const Eigen::Matrix2d M = model.noise().Covariance(u);
  EXPECT_NEAR(M(0, 0), 0.1 * 0.1 + 0.5 * 0.5, 1e-15);
  EXPECT_NEAR(M(1, 1), 0.02 * 0.02 + 0.175 * 0.175, 1e-15);
  Matrix32d Ju;
  model.Predict(Pose2(), u, 0.1, nullptr, &Ju);
  EXPECT_TRUE(MatricesNear(Ju * M * Ju.transpose(), model.ProcessCovariance(Pose2(), u, 0.1), 1e-15));
  EXPECT_FALSE((ControlNoise{-1.0, 0.1, 0, 0}).Validate().ok());
}

// The particle filter shares the motion since the last scan between particles, which
// needs f(a ∘ r, u) = a ∘ f(r, u) with the matching noise Jacobians J_u(a ∘ r) = A J_u(r),
// A = ∂(a ∘ ·)/∂r.
TEST(MotionModel, ModelsAreSe2Equivariant) {
  const UnicycleModel unicycle({0.1, 0.02, 0.25, 0.35});
  const AckermannModel vp({2.83, 0.76, 3.78, 0.50}, {0.5, 0.05, 0, 0});
  for (const MotionModel* model : std::initializer_list<const MotionModel*>{&unicycle, &vp}) {
    for (const Pose2& a : TestPoses()) {
      const Pose2 r(0.3, -0.2, 0.4);
      const Eigen::Vector2d u(2.0, 0.3);
      Matrix32d J_direct, J_relative;
      const Pose2 direct = model->Predict(Compose(a, r), u, 0.05, nullptr, &J_direct);
      Eigen::Matrix3d A;
      const Pose2 relative = Compose(a, model->Predict(r, u, 0.05, nullptr, &J_relative), nullptr, &A);
      EXPECT_TRUE(MatricesNear(direct.vector(), relative.vector(), 1e-12)) << model->Name() << a;
      EXPECT_TRUE(MatricesNear(J_direct, A * J_relative, 1e-12)) << model->Name() << a;
    }
  }
}

}  // namespace
}  // namespace subslam::models
