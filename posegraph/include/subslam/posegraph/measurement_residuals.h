// The residual of each measurement kind of a PoseGraph (pose_graph.h gives the
// definitions), with analytic Jacobians with respect to the plain (x, y, θ) pose and
// (x, y) point vectors (docs/conventions.md). Checked against central differences in
// tests/posegraph/measurement_residuals_test.cc. Pure functions; Jacobian pointers may be
// nullptr.
#ifndef SUBSLAM_POSEGRAPH_MEASUREMENT_RESIDUALS_H_
#define SUBSLAM_POSEGRAPH_MEASUREMENT_RESIDUALS_H_

#include <Eigen/Core>

#include "subslam/core/pose2.h"

namespace subslam::posegraph {

// (z⁻¹ ∘ (from⁻¹ ∘ to)) as (x, y, θ), θ wrapped.
Eigen::Vector3d OdometryResidual(const Pose2& z, const Pose2& from, const Pose2& to, Eigen::Matrix3d* J_from = nullptr,
                                 Eigen::Matrix3d* J_to = nullptr);

// pose⁻¹ · point − z.
Eigen::Vector2d PointResidual(const Eigen::Vector2d& z, const Pose2& pose, const Eigen::Vector2d& point,
                              Matrix23d* J_pose = nullptr, Eigen::Matrix2d* J_point = nullptr);

// (wrap(b̂ − b), r̂ − r), b̂ and r̂ the bearing and range of the point from the pose.
Eigen::Vector2d BearingRangeResidual(double bearing, double range, const Pose2& pose, const Eigen::Vector2d& point,
                                     Matrix23d* J_pose = nullptr, Eigen::Matrix2d* J_point = nullptr);

// wrap(b̂ − b).
double BearingResidual(double bearing, const Pose2& pose, const Eigen::Vector2d& point,
                       Eigen::RowVector3d* J_pose = nullptr, Eigen::RowVector2d* J_point = nullptr);

}  // namespace subslam::posegraph

#endif  // SUBSLAM_POSEGRAPH_MEASUREMENT_RESIDUALS_H_
