#include "subslam/frontend/existence_model.h"

#include <algorithm>
#include <cmath>

#include "subslam/frontend/landmark_options.h"

namespace subslam::frontend {
namespace {

bool InOpenUnit(double p) { return std::isfinite(p) && p > 0.0 && p < 1.0; }

}  // namespace

absl::Status ExistenceModel::Validate() const {
  if (!InOpenUnit(detection_probability) || !InOpenUnit(false_alarm_probability)) {
    return absl::InvalidArgumentError("existence model: detection and false-alarm probabilities must be in (0, 1)");
  }
  if (!(InOpenUnit(prior_existence) && InOpenUnit(confirm_existence) && InOpenUnit(delete_existence) &&
        InOpenUnit(max_existence) && delete_existence < confirm_existence && confirm_existence < max_existence)) {
    return absl::InvalidArgumentError("existence thresholds must satisfy 0 < delete < confirm < max < 1");
  }
  return absl::OkStatus();
}

double ExistenceModel::Update(double p, bool detected) const {
  const double a = detection_probability, b = false_alarm_probability;
  const double q = detected ? p * a / (p * a + (1 - p) * b) : p * (1 - a) / (p * (1 - a) + (1 - p) * (1 - b));
  return std::clamp(q, 1e-9, max_existence);
}

absl::Status LandmarkOptions::Validate() const {
  const auto in_open_unit = [](double p) { return std::isfinite(p) && p > 0.0 && p < 1.0; };
  if (!in_open_unit(gate_probability) || !in_open_unit(new_landmark_probability) ||
      new_landmark_probability < gate_probability) {
    return absl::InvalidArgumentError("need 0 < gate_probability <= new_landmark_probability < 1");
  }
  if (absl::Status s = existence.Validate(); !s.ok()) return s;
  if (!(expect_range_margin_m >= 0) || !(expect_bearing_margin_rad >= 0) || cull_every_scans < 1) {
    return absl::InvalidArgumentError("cull_every_scans >= 1 and margins >= 0 required");
  }
  return absl::OkStatus();
}

}  // namespace subslam::frontend
