// Comparing a trajectory with GPS fixes in another frame (Victoria Park): the estimate
// is interpolated at each GPS time, the least-squares rigid 2-D transform (rotation +
// translation, no scale; Umeyama 1991 / Kabsch) that maps the estimated positions onto
// the GPS positions is found in closed form, and the residual RMS is reported.
#ifndef SUBSLAM_EVAL_GPS_ALIGNMENT_H_
#define SUBSLAM_EVAL_GPS_ALIGNMENT_H_

#include <vector>

#include "absl/status/statusor.h"
#include "subslam/core/estimates.h"
#include "subslam/io/dataset.h"

namespace subslam::eval {

// The rigid transform T minimising Σ ‖T · source_i − target_i‖². Needs ≥ 2 points that
// are not all coincident.
absl::StatusOr<Pose2> RigidAlignment2D(const std::vector<Eigen::Vector2d>& source,
                                       const std::vector<Eigen::Vector2d>& target);

// Gross GPS faults, judged from the GPS alone: a fix is dropped when it lies farther than
// base_m + speed_mps · Δt from the component-wise median of its `neighbours` fixes on each
// side (fewer at the ends), Δt the longest time from it to one of them — farther than
// the vehicle could have driven. Victoria Park's fix at t = 1,223.284 s lies about 130 m
// off its neighbours; a slow drive (below 6 m/s) at 25 m of receiver noise keeps every
// other fix.
struct GpsFaultRule {
  double base_m = 25.0;
  double speed_mps = 6.0;
  int neighbours = 2;  // per side
};

// Indices of the fixes the rule drops.
std::vector<int> GrossGpsFaults(const std::vector<io::TimedPoint>& gps, const GpsFaultRule& rule = {});

struct GpsComparison {
  int matched_fixes = 0;   // GPS fixes inside the trajectory's time span (faults dropped)
  int rejected_fixes = 0;  // of those, gross faults dropped (GrossGpsFaults)
  Pose2 gps_T_estimate;    // the aligning transform
  double rms_m = 0.0;      // √mean ‖residual‖²
  double rms_x_m = 0.0;    // per GPS axis
  double rms_y_m = 0.0;
  double max_m = 0.0;
};

// Fixes outside [trajectory.front().t, trajectory.back().t] are skipped, and gross
// faults (GrossGpsFaults with `rule`) are dropped and counted.
absl::StatusOr<GpsComparison> CompareWithGps(const Trajectory& trajectory, const std::vector<io::TimedPoint>& gps,
                                             const GpsFaultRule& rule = {});

}  // namespace subslam::eval

#endif  // SUBSLAM_EVAL_GPS_ALIGNMENT_H_
