#include "subslam/frontend/internal/single_map_common.h"

#include <cmath>

namespace subslam::frontend::internal {
namespace {

bool InOpenUnit(double p) { return std::isfinite(p) && p > 0.0 && p < 1.0; }

}  // namespace

absl::Status ValidateAssociationAndExistence(double gate_probability, double new_landmark_probability,
                                             const ExistenceModel& existence, long jcbb_max_nodes,
                                             double expect_range_margin_m,
                                             double expect_bearing_margin_rad, int cull_every_scans) {
  if (!InOpenUnit(gate_probability) || !InOpenUnit(new_landmark_probability) ||
      new_landmark_probability < gate_probability) {
    return absl::InvalidArgumentError("need 0 < gate_probability <= new_landmark_probability < 1");
  }
  if (absl::Status s = existence.Validate(); !s.ok()) return s;
  if (jcbb_max_nodes < 1 || !(expect_range_margin_m >= 0) || !(expect_bearing_margin_rad >= 0) ||
      cull_every_scans < 1) {
    return absl::InvalidArgumentError(
        "jcbb_max_nodes >= 1, cull_every_scans >= 1 and margins >= 0 required");
  }
  return absl::OkStatus();
}

UsableDetections DetectionsInRange(const Scan& scan, const models::RangeBearingConfig& sensor) {
  UsableDetections out;
  for (size_t k = 0; k < scan.detections.size(); ++k) {
    const Detection& d = scan.detections[k];
    if (d.range_m < sensor.min_range_m || d.range_m > sensor.max_range_m) continue;
    out.z.push_back(d.z());
    out.index.push_back(static_cast<int>(k));
  }
  return out;
}

}  // namespace subslam::frontend::internal
