#include "subslam/posegraph/measurement_residuals.h"

#include <cmath>

namespace subslam::posegraph {

Eigen::Vector3d OdometryResidual(const Pose2& z, const Pose2& from, const Pose2& to, Eigen::Matrix3d* J_from,
                                 Eigen::Matrix3d* J_to) {
  Eigen::Matrix3d J_rel_from, J_rel_to, J_e_rel;
  const Pose2 rel = Between(from, to, J_from != nullptr ? &J_rel_from : nullptr, J_to != nullptr ? &J_rel_to : nullptr);
  const Pose2 e = Between(z, rel, nullptr, &J_e_rel);
  if (J_from != nullptr) *J_from = J_e_rel * J_rel_from;
  if (J_to != nullptr) *J_to = J_e_rel * J_rel_to;
  return e.vector();
}

Eigen::Vector2d PointResidual(const Eigen::Vector2d& z, const Pose2& pose, const Eigen::Vector2d& point,
                              Matrix23d* J_pose, Eigen::Matrix2d* J_point) {
  return TransformTo(pose, point, J_pose, J_point) - z;
}

Eigen::Vector2d BearingRangeResidual(double bearing, double range, const Pose2& pose, const Eigen::Vector2d& point,
                                     Matrix23d* J_pose, Eigen::Matrix2d* J_point) {
  const double dx = point.x() - pose.x, dy = point.y() - pose.y;
  const double q = dx * dx + dy * dy;
  const double r = std::sqrt(q);
  const Eigen::Vector2d residual(WrapAngle(std::atan2(dy, dx) - pose.theta - bearing), r - range);
  // d bearing / d point = (−dy, dx) / q; d range / d point = (dx, dy) / r.
  Eigen::Matrix2d J_p;
  J_p << -dy / q, dx / q, dx / r, dy / r;
  if (J_point != nullptr) *J_point = J_p;
  if (J_pose != nullptr) {
    J_pose->leftCols<2>() = -J_p;
    J_pose->col(2) << -1.0, 0.0;
  }
  return residual;
}

double BearingResidual(double bearing, const Pose2& pose, const Eigen::Vector2d& point, Eigen::RowVector3d* J_pose,
                       Eigen::RowVector2d* J_point) {
  const double dx = point.x() - pose.x, dy = point.y() - pose.y;
  const double q = dx * dx + dy * dy;
  if (J_point != nullptr) *J_point << -dy / q, dx / q;
  if (J_pose != nullptr) *J_pose << dy / q, -dx / q, -1.0;
  return WrapAngle(std::atan2(dy, dx) - pose.theta - bearing);
}

}  // namespace subslam::posegraph
