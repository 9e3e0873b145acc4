// Comparing a trajectory with GPS fixes in another frame (Victoria Park): the estimate
// is interpolated at each GPS time, the least-squares rigid 2-D transform (rotation +
// translation, no scale; Umeyama 1991 / Kabsch) that maps the estimated positions onto
// the GPS positions is found in closed form, and the residual RMS is reported.
#ifndef SUBSLAM_EVAL_GPS_ALIGNMENT_H_
#define SUBSLAM_EVAL_GPS_ALIGNMENT_H_

#include <vector>

#include "absl/status/statusor.h"
#include "subslam/graph/estimates.h"
#include "subslam/io/dataset.h"

namespace subslam::eval {

// The rigid transform T minimising Σ ‖T · source_i − target_i‖². Needs ≥ 2 points that
// are not all coincident.
absl::StatusOr<Pose2> RigidAlignment2D(const std::vector<Eigen::Vector2d>& source,
                                       const std::vector<Eigen::Vector2d>& target);

struct GpsComparison {
  int matched_fixes = 0;     // GPS fixes inside the trajectory's time span
  Pose2 gps_T_estimate;      // the aligning transform
  double rms_m = 0.0;        // √mean ‖residual‖²
  double rms_x_m = 0.0;      // per GPS axis
  double rms_y_m = 0.0;
  double max_m = 0.0;
};

// Fixes outside [trajectory.front().t, trajectory.back().t] are skipped.
absl::StatusOr<GpsComparison> CompareWithGps(const Trajectory& trajectory,
                                             const std::vector<io::TimedPoint>& gps);

}  // namespace subslam::eval

#endif  // SUBSLAM_EVAL_GPS_ALIGNMENT_H_
