#include "subslam/calibration/odometry_interval.h"

#include <Eigen/Geometry>
#include <utility>

namespace subslam::calibration {
namespace {

Eigen::Vector2d Corrected(const Eigen::Vector2d& u, const ControlCorrection& c, double offset0) {
  return Eigen::Vector2d(c[0] * u[0] + offset0, c[1] * u[1] + c[2]);
}

}  // namespace

OdometryInterval::OdometryInterval(const models::MotionModel* model, std::vector<RecordedStep> steps, double offset0)
    : model_(model), steps_(std::move(steps)), offset0_(offset0) {}

Eigen::Vector3d OdometryInterval::Predict(const ControlCorrection& c, Eigen::Matrix3d* J_c) const {
  Pose2 p;
  double theta = 0.0;  // unwrapped
  Eigen::Matrix3d G = Eigen::Matrix3d::Zero();
  for (const RecordedStep& s : steps_) {
    Eigen::Matrix3d J_x;
    Matrix32d J_u;
    const Pose2 next =
        model_->Predict(p, Corrected(s.control, c, offset0_), s.dt, J_c ? &J_x : nullptr, J_c ? &J_u : nullptr);
    if (J_c) {
      Eigen::Matrix<double, 2, 3> D;  // ∂u'/∂c
      D << s.control[0], 0.0, 0.0, 0.0, s.control[1], 1.0;
      G = J_x * G + J_u * D;
    }
    theta += WrapAngle(next.theta - p.theta);
    p = next;
  }
  if (J_c) *J_c = G;
  return Eigen::Vector3d(p.x, p.y, theta);
}

std::array<Eigen::Matrix3d, 4> OdometryInterval::NoiseComponents(const ControlCorrection& c) const {
  std::array<Eigen::Matrix3d, 4> T;
  for (Eigen::Matrix3d& t : T) t.setZero();
  Pose2 p;
  for (const RecordedStep& s : steps_) {
    const Eigen::Vector2d u = Corrected(s.control, c, offset0_);
    Eigen::Matrix3d J_x;
    Matrix32d J_u;
    const Pose2 next = model_->Predict(p, u, s.dt, &J_x, &J_u);
    const std::array<Eigen::Vector2d, 4> m = {Eigen::Vector2d(1, 0), Eigen::Vector2d(u[0] * u[0], 0),
                                              Eigen::Vector2d(0, 1), Eigen::Vector2d(0, u[1] * u[1])};
    for (int k = 0; k < 4; ++k) {
      T[k] = J_x * T[k] * J_x.transpose() + J_u * m[k].asDiagonal() * J_u.transpose();
    }
    p = next;
  }
  return T;
}

Eigen::Vector3d IntervalResidual(const Eigen::Vector3d& x_a, const Eigen::Vector3d& x_b,
                                 const Eigen::Vector3d& predicted, Eigen::Matrix3d* J_a, Eigen::Matrix3d* J_b) {
  const double c = std::cos(x_a[2]), s = std::sin(x_a[2]);
  Eigen::Matrix2d Rt;
  Rt << c, s, -s, c;
  const Eigen::Vector2d d = x_b.head<2>() - x_a.head<2>();
  Eigen::Vector3d e;
  e.head<2>() = Rt * d - predicted.head<2>();
  e[2] = WrapAngle(x_b[2] - x_a[2] - predicted[2]);
  if (J_a) {
    Eigen::Matrix2d dRt;  // ∂Rᵀ/∂θ_a
    dRt << -s, c, -c, -s;
    J_a->setZero();
    J_a->topLeftCorner<2, 2>() = -Rt;
    J_a->block<2, 1>(0, 2) = dRt * d;
    (*J_a)(2, 2) = -1.0;
  }
  if (J_b) {
    J_b->setZero();
    J_b->topLeftCorner<2, 2>() = Rt;
    (*J_b)(2, 2) = 1.0;
  }
  return e;
}

}  // namespace subslam::calibration
