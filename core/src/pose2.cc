#include "subslam/core/pose2.h"

#include <cmath>

namespace subslam {

Eigen::Matrix2d Pose2::rotation() const {
  const double c = std::cos(theta), s = std::sin(theta);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}

std::ostream& operator<<(std::ostream& os, const Pose2& p) {
  return os << "(" << p.x << ", " << p.y << ", " << p.theta << ")";
}

Pose2 Compose(const Pose2& a, const Pose2& b, Eigen::Matrix3d* J_ab_a, Eigen::Matrix3d* J_ab_b) {
  const double c = std::cos(a.theta), s = std::sin(a.theta);
  const Pose2 ab(a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, WrapAngle(a.theta + b.theta));
  if (J_ab_a != nullptr) {
    *J_ab_a << 1, 0, -s * b.x - c * b.y,  //
        0, 1, c * b.x - s * b.y,          //
        0, 0, 1;
  }
  if (J_ab_b != nullptr) {
    *J_ab_b << c, -s, 0,  //
        s, c, 0,          //
        0, 0, 1;
  }
  return ab;
}

Pose2 ComposeWithCovariance(const Pose2& a, const Eigen::Matrix3d& cov_a, const Pose2& b, const Eigen::Matrix3d& cov_b,
                            Eigen::Matrix3d* cov_ab) {
  Eigen::Matrix3d J_a, J_b;
  const Pose2 ab = Compose(a, b, &J_a, &J_b);
  *cov_ab = J_a * cov_a * J_a.transpose() + J_b * cov_b * J_b.transpose();
  return ab;
}

Pose2 Inverse(const Pose2& a, Eigen::Matrix3d* J_inv_a) {
  const double c = std::cos(a.theta), s = std::sin(a.theta);
  const Pose2 inv(-c * a.x - s * a.y, s * a.x - c * a.y, WrapAngle(-a.theta));
  if (J_inv_a != nullptr) {
    *J_inv_a << -c, -s, s * a.x - c * a.y,  //
        s, -c, c * a.x + s * a.y,           //
        0, 0, -1;
  }
  return inv;
}

Pose2 Between(const Pose2& a, const Pose2& b, Eigen::Matrix3d* J_ab_a, Eigen::Matrix3d* J_ab_b) {
  const double c = std::cos(a.theta), s = std::sin(a.theta);
  const double dx = b.x - a.x, dy = b.y - a.y;
  const Pose2 rel(c * dx + s * dy, -s * dx + c * dy, WrapAngle(b.theta - a.theta));
  if (J_ab_a != nullptr) {
    *J_ab_a << -c, -s, -s * dx + c * dy,  //
        s, -c, -c * dx - s * dy,          //
        0, 0, -1;
  }
  if (J_ab_b != nullptr) {
    *J_ab_b << c, s, 0,  //
        -s, c, 0,        //
        0, 0, 1;
  }
  return rel;
}

Eigen::Vector2d TransformFrom(const Pose2& frame, const Eigen::Vector2d& p, Matrix23d* J_out_frame,
                              Eigen::Matrix2d* J_out_point) {
  const double c = std::cos(frame.theta), s = std::sin(frame.theta);
  if (J_out_frame != nullptr) {
    *J_out_frame << 1, 0, -s * p.x() - c * p.y(),  //
        0, 1, c * p.x() - s * p.y();
  }
  if (J_out_point != nullptr) *J_out_point << c, -s, s, c;
  return {frame.x + c * p.x() - s * p.y(), frame.y + s * p.x() + c * p.y()};
}

Eigen::Vector2d TransformTo(const Pose2& frame, const Eigen::Vector2d& q, Matrix23d* J_out_frame,
                            Eigen::Matrix2d* J_out_point) {
  const double c = std::cos(frame.theta), s = std::sin(frame.theta);
  const double dx = q.x() - frame.x, dy = q.y() - frame.y;
  if (J_out_frame != nullptr) {
    *J_out_frame << -c, -s, -s * dx + c * dy,  //
        s, -c, -c * dx - s * dy;
  }
  if (J_out_point != nullptr) *J_out_point << c, s, -s, c;
  return {c * dx + s * dy, -s * dx + c * dy};
}

Eigen::Vector3d PoseDifference(const Pose2& a, const Pose2& b) {
  return {a.x - b.x, a.y - b.y, WrapAngle(a.theta - b.theta)};
}

}  // namespace subslam
