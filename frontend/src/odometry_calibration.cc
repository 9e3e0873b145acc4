#include "subslam/frontend/odometry_calibration.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"

namespace subslam::frontend {

absl::Status OdometryCalibrationOptions::Validate() const {
  if (!(scale_prior_sigma >= 0.0 && scale_prior_sigma < 1.0)) {
    return absl::InvalidArgumentError(absl::StrCat("scale_prior_sigma must be in [0, 1), got ", scale_prior_sigma));
  }
  if (!(offset_prior_sigma >= 0.0 && std::isfinite(offset_prior_sigma))) {
    return absl::InvalidArgumentError(
        absl::StrCat("offset_prior_sigma must be finite and >= 0, got ", offset_prior_sigma));
  }
  return absl::OkStatus();
}

Eigen::Matrix3d OdometryCalibrationOptions::PriorCovariance() const {
  return Eigen::Vector3d(scale_prior_sigma * scale_prior_sigma, scale_prior_sigma * scale_prior_sigma,
                         offset_prior_sigma * offset_prior_sigma)
      .asDiagonal();
}

Eigen::Vector2d CalibratedControl(const Eigen::Vector2d& u, const Eigen::Vector3d& c,
                                  Eigen::Matrix<double, 2, 3>* J_c) {
  if (J_c != nullptr) *J_c << u[0], 0.0, 0.0, 0.0, u[1], 1.0;
  return Eigen::Vector2d(c[0] * u[0], c[1] * u[1] + c[2]);
}

void OdometryCalibrationEstimate::AddCounters(std::map<std::string, double>* out) const {
  const char* names[] = {"odometry_scale_0", "odometry_scale_1", "odometry_offset_1"};
  for (int i = 0; i < 3; ++i) {
    (*out)[names[i]] = value[i];
    (*out)[absl::StrCat(names[i], "_sigma")] = std::sqrt(std::max(0.0, covariance(i, i)));
  }
}

}  // namespace subslam::frontend
