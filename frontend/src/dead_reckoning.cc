#include "subslam/frontend/dead_reckoning.h"

#include "absl/time/clock.h"

namespace subslam::frontend {

DeadReckoning::DeadReckoning(std::unique_ptr<models::MotionModel> motion, const Pose2& initial_pose)
    : motion_(std::move(motion)), pose_(initial_pose) {}

void DeadReckoning::Predict(const Eigen::Vector2d& u, double dt) {
  if (dt <= 0.0) return;
  const absl::Time start = absl::Now();
  Eigen::Matrix3d F;
  Matrix32d G;
  pose_ = motion_->Predict(pose_, u, dt, &F, &G);
  covariance_ = F * covariance_ * F.transpose() + G * motion_->noise().Covariance(u) * G.transpose();
  predict_seconds_ += absl::ToDoubleSeconds(absl::Now() - start);
}

}  // namespace subslam::frontend
