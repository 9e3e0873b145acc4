#include "subslam/models/ackermann_model.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"

namespace subslam::models {

absl::Status AckermannGeometry::Validate() const {
  if (!(std::isfinite(wheelbase_m) && wheelbase_m > 0.0)) {
    return absl::InvalidArgumentError(absl::StrCat("AckermannGeometry.wheelbase_m must be > 0, got ", wheelbase_m));
  }
  if (!std::isfinite(encoder_offset_m) || !std::isfinite(sensor_forward_m) || !std::isfinite(sensor_left_m)) {
    return absl::InvalidArgumentError("AckermannGeometry offsets must be finite");
  }
  return absl::OkStatus();
}

Pose2 AckermannModel::Predict(const Pose2& x, const Eigen::Vector2d& u, double dt, Eigen::Matrix3d* J_next_x,
                              Matrix32d* J_next_u) const {
  const double L = geometry_.wheelbase_m, H = geometry_.encoder_offset_m;
  const double a = geometry_.sensor_forward_m, b = geometry_.sensor_left_m;
  const double v = u[0];
  double r = std::tan(u[1]);
  double dr_ds = 1.0 + r * r;
  // Keep 1 − r·H/L away from zero (outside the model's validity anyway).
  const double r_limit = H != 0.0 ? 0.99 * L / std::abs(H) : INFINITY;
  if (std::abs(r) > r_limit) {
    r = std::copysign(r_limit, r);
    dr_ds = 0.0;
  }
  const double k = 1.0 - r * H / L;
  const double vc = v / k;
  const double w = vc * r / L;  // heading rate φ̇
  const double c = std::cos(x.theta), s = std::sin(x.theta);
  const double ax = a * s + b * c;  // lever-arm terms
  const double ay = a * c - b * s;

  const Pose2 next(x.x + dt * (vc * c - w * ax), x.y + dt * (vc * s + w * ay), WrapAngle(x.theta + dt * w));
  if (J_next_x != nullptr) {
    // d ax / dφ = ay, d ay / dφ = −ax.
    *J_next_x << 1, 0, dt * (-vc * s - w * ay),  //
        0, 1, dt * (vc * c - w * ax),            //
        0, 0, 1;
  }
  if (J_next_u != nullptr) {
    const double dvc_dv = 1.0 / k, dw_dv = r / (k * L);
    const double dk_ds = -(H / L) * dr_ds;
    const double dvc_ds = -v / (k * k) * dk_ds;
    const double dw_ds = (dvc_ds * r + vc * dr_ds) / L;
    *J_next_u << dt * (dvc_dv * c - dw_dv * ax), dt * (dvc_ds * c - dw_ds * ax),  //
        dt * (dvc_dv * s + dw_dv * ay), dt * (dvc_ds * s + dw_ds * ay),           //
        dt * dw_dv, dt * dw_ds;
  }
  return next;
}

}  // namespace subslam::models
