// Dead reckoning: the motion model alone, with the pose covariance propagated
// (P ← F P Fᵀ + Q). Detections are ignored. The "odometry" baseline of `subslam run`.
#ifndef SUBSLAM_FRONTEND_DEAD_RECKONING_H_
#define SUBSLAM_FRONTEND_DEAD_RECKONING_H_

#include <memory>

#include "subslam/frontend/online_estimator.h"
#include "subslam/models/motion_model.h"

namespace subslam::frontend {

class DeadReckoning final : public OnlineEstimator {
 public:
  DeadReckoning(std::unique_ptr<models::MotionModel> motion, const Pose2& initial_pose);

  std::string Name() const override { return "odometry"; }
  void Predict(const Eigen::Vector2d& u, double dt) override;
  absl::Status Update(const Scan& scan) override { return CheckScan(scan); }  // the scan is not used
  Pose2 pose() const override { return pose_; }
  Eigen::Matrix3d pose_covariance() const override { return covariance_; }
  std::vector<LandmarkEstimate> Map() const override { return {}; }
  StageTimes stage_times() const override { return {{"predict", predict_seconds_}}; }

 private:
  std::unique_ptr<models::MotionModel> motion_;
  Pose2 pose_;
  Eigen::Matrix3d covariance_ = Eigen::Matrix3d::Zero();
  double predict_seconds_ = 0.0;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_DEAD_RECKONING_H_
