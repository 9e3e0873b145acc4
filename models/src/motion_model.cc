#include "subslam/models/motion_model.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace subslam::models {

absl::Status ControlNoise::Validate() const {
  const double values[] = {sigma_u0, sigma_u1, scale_u0, scale_u1};
  const char* names[] = {"sigma_u0", "sigma_u1", "scale_u0", "scale_u1"};
  for (int i = 0; i < 4; ++i) {
    if (!std::isfinite(values[i]) || values[i] < 0.0) {
      return absl::InvalidArgumentError(
          absl::StrCat("ControlNoise.", names[i], " must be finite and >= 0, got ", values[i]));
    }
  }
  return absl::OkStatus();
}

Eigen::Matrix2d ControlNoise::Covariance(const Eigen::Vector2d& u) const {
  const double s0 = scale_u0 * std::abs(u[0]);
  const double s1 = scale_u1 * std::abs(u[1]);
  Eigen::Matrix2d m = Eigen::Matrix2d::Zero();
  m(0, 0) = sigma_u0 * sigma_u0 + s0 * s0;
  m(1, 1) = sigma_u1 * sigma_u1 + s1 * s1;
  return m;
}

Eigen::Matrix3d MotionModel::ProcessCovariance(const Pose2& x, const Eigen::Vector2d& u, double dt) const {
  Matrix32d J_next_u;
  Predict(x, u, dt, nullptr, &J_next_u);
  return J_next_u * noise_.Covariance(u) * J_next_u.transpose();
}

}  // namespace subslam::models
