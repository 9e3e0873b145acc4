#include "subslam/models/range_bearing_model.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "subslam/core/check.h"

namespace subslam::models {

absl::Status RangeBearingConfig::Validate() const {
  if (!(std::isfinite(sigma_range_m) && sigma_range_m > 0.0)) {
    return absl::InvalidArgumentError(absl::StrCat("sigma_range must be finite and > 0, got ", sigma_range_m));
  }
  if (!(std::isfinite(sigma_bearing_rad) && sigma_bearing_rad > 0.0)) {
    return absl::InvalidArgumentError(absl::StrCat("sigma_bearing must be finite and > 0, got ", sigma_bearing_rad));
  }
  if (!(std::isfinite(min_range_m) && min_range_m >= 0.0 && std::isfinite(max_range_m) && max_range_m > min_range_m)) {
    return absl::InvalidArgumentError(
        absl::StrCat("need 0 <= min_range < max_range, got ", min_range_m, " and ", max_range_m));
  }
  if (!(std::isfinite(fov_min_rad) && std::isfinite(fov_max_rad) && fov_min_rad < fov_max_rad &&
        fov_min_rad >= -kPi - 1e-9 && fov_max_rad <= kPi + 1e-9)) {
    return absl::InvalidArgumentError(absl::StrCat("field of view must satisfy -pi <= fov_min < fov_max <= pi, got [",
                                                   fov_min_rad, ", ", fov_max_rad, "]"));
  }
  return absl::OkStatus();
}

Eigen::Vector2d RangeBearingModel::Observe(const Pose2& p, const Eigen::Vector2d& l, Matrix23d* J_z_pose,
                                           Eigen::Matrix2d* J_z_landmark) const {
  return {ObserveRange(p, l, J_z_pose, J_z_landmark), Bearing(p, l)};
}

double RangeBearingModel::ObserveRange(const Pose2& p, const Eigen::Vector2d& l, Matrix23d* J_z_pose,
                                       Eigen::Matrix2d* J_z_landmark) const {
  const double dx = l.x() - p.x, dy = l.y() - p.y;
  const double q = dx * dx + dy * dy;
  SUBSLAM_CHECK(q > 0.0) << "landmark coincides with the sensor position";
  const double r = std::sqrt(q);
  if (J_z_landmark != nullptr) {
    *J_z_landmark << dx / r, dy / r,  //
        -dy / q, dx / q;
  }
  if (J_z_pose != nullptr) {
    *J_z_pose << -dx / r, -dy / r, 0.0,  //
        dy / q, -dx / q, -1.0;
  }
  return r;
}

double RangeBearingModel::Bearing(const Pose2& p, const Eigen::Vector2d& l) {
  return WrapAngle(std::atan2(l.y() - p.y, l.x() - p.x) - p.theta);
}

Eigen::Vector2d RangeBearingModel::InverseObserve(const Pose2& p, const Eigen::Vector2d& z, Matrix23d* J_landmark_pose,
                                                  Eigen::Matrix2d* J_landmark_z) const {
  const double r = z[0];
  const double angle = p.theta + z[1];
  const double c = std::cos(angle), s = std::sin(angle);
  if (J_landmark_pose != nullptr) {
    *J_landmark_pose << 1.0, 0.0, -r * s,  //
        0.0, 1.0, r * c;
  }
  if (J_landmark_z != nullptr) {
    *J_landmark_z << c, -r * s,  //
        s, r * c;
  }
  return {p.x + r * c, p.y + r * s};
}

Eigen::Matrix2d RangeBearingModel::NoiseCovariance() const {
  Eigen::Matrix2d r = Eigen::Matrix2d::Zero();
  r(0, 0) = config_.sigma_range_m * config_.sigma_range_m;
  r(1, 1) = config_.sigma_bearing_rad * config_.sigma_bearing_rad;
  return r;
}

bool RangeBearingModel::IsVisible(const Eigen::Vector2d& z, double range_margin_m, double bearing_margin_rad) const {
  return z[0] >= config_.min_range_m + range_margin_m && z[0] <= config_.max_range_m - range_margin_m &&
         z[1] >= config_.fov_min_rad + bearing_margin_rad && z[1] <= config_.fov_max_rad - bearing_margin_rad;
}

}  // namespace subslam::models
