#include "subslam/frontend/internal/single_map_common.h"

#include <cmath>

namespace subslam::frontend::internal {
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
