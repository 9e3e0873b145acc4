// Plain estimate records shared by estimators, metrics and writers.
#ifndef SUBSLAM_CORE_ESTIMATES_H_
#define SUBSLAM_CORE_ESTIMATES_H_

#include <Eigen/Core>
#include <vector>

#include "subslam/core/pose2.h"

namespace subslam {

// A pose estimate at time t [s] with its 3×3 covariance over (x, y, θ).
struct PoseEstimate {
  double t = 0.0;
  Pose2 pose;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
};

// A landmark estimate (x, y) [m] with its 2×2 covariance; `id` is the estimator's own.
struct LandmarkEstimate {
  int id = 0;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
};

using Trajectory = std::vector<PoseEstimate>;

}  // namespace subslam

#endif  // SUBSLAM_CORE_ESTIMATES_H_
