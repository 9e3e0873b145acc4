// One scan of a range-bearing sensor: the detections taken at one time, in the vehicle
// frame (docs/conventions.md). What the data-set readers produce, the simulator writes and
// every estimator consumes.
#ifndef SUBSLAM_MODELS_SCAN_H_
#define SUBSLAM_MODELS_SCAN_H_

#include <Eigen/Core>
#include <limits>
#include <vector>

#include "absl/status/status.h"

namespace subslam {

inline constexpr int kFalseAlarmId = -1;    // truth id of a false alarm
inline constexpr int kUnknownTruthId = -2;  // no truth id in the data set

struct Detection {
  double range_m = 0.0;
  double bearing_rad = 0.0;                                     // in the vehicle frame (offset applied)
  double signature = std::numeric_limits<double>::quiet_NaN();  // NaN when absent
  // Evaluation; read by estimators only under their known-association study option.
  int truth_id = kUnknownTruthId;

  Eigen::Vector2d z() const { return {range_m, bearing_rad}; }
};

// All detections with one time stamp.
struct Scan {
  double t = 0.0;
  std::vector<Detection> detections;
};

// OK, or InvalidArgument naming the scan's time and the first detection whose range is not
// finite and positive or whose bearing is not finite. The data-set reader refuses such
// lines in a file (with file, line and field); the estimators check a caller's scans here
// and leave a bad one unused. A finite range outside the sensor's limits is no error: the
// estimators leave that detection out.
absl::Status CheckScan(const Scan& scan);

}  // namespace subslam

#endif  // SUBSLAM_MODELS_SCAN_H_
