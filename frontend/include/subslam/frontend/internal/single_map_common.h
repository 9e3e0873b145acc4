// Pieces shared by the single-map filters EkfSlam and SeifSlam: validation of their
// common association and existence options, and the detections a scan can use.
#ifndef SUBSLAM_FRONTEND_INTERNAL_SINGLE_MAP_COMMON_H_
#define SUBSLAM_FRONTEND_INTERNAL_SINGLE_MAP_COMMON_H_

#include <vector>

#include "absl/status/status.h"
#include "subslam/frontend/existence_model.h"
#include "subslam/models/range_bearing_model.h"
#include "subslam/models/scan.h"

namespace subslam::frontend::internal {

// The detections inside the sensor's valid range, as measurements z = (range, bearing),
// with their index in the scan.
struct UsableDetections {
  std::vector<Eigen::Vector2d> z;
  std::vector<int> index;
};
UsableDetections DetectionsInRange(const Scan& scan, const models::RangeBearingConfig& sensor);

}  // namespace subslam::frontend::internal

#endif  // SUBSLAM_FRONTEND_INTERNAL_SINGLE_MAP_COMMON_H_
