// What the single-map filters and the local mappers (EkfSlam, FastSlam, SeifSlam) share
// about a scan's detections and their landmarks: the gates that pair a detection with a
// landmark or start a new one, the known-association study option, and the existence
// model with its culls. Embedded as `landmarks` in EkfSlamOptions, FastSlamOptions and
// SeifOptions.
#ifndef SUBSLAM_FRONTEND_LANDMARK_OPTIONS_H_
#define SUBSLAM_FRONTEND_LANDMARK_OPTIONS_H_

#include "absl/status/status.h"
#include "subslam/frontend/existence_model.h"

namespace subslam::frontend {

struct LandmarkOptions {
  // Individual-compatibility gate, P(χ²₂ ≤ gate) (also JCBB's joint gate level).
  double gate_probability = 0.99;
  // A detection outside this gate for every landmark starts a new landmark.
  double new_landmark_probability = 0.9999;
  // Known association (simulations; a study option, as in Combined SLAM §7): each
  // detection is paired with the landmark of the same Detection::truth_id, without
  // gating, or starts one; false alarms (no true id) and repeated ids in a scan are
  // dropped. A true id settles that the landmark exists: a miss does not lower its
  // existence and no landmark is culled, so a sensor that detects less often than
  // `existence` assumes does not drop true landmarks from the map; a landmark is
  // confirmed (reported, exported) by its detections as with unknown association. The
  // exported maps then carry each feature's true id.
  bool known_association = false;
  // Existence model (HybridSLAM Eq. 11): the filter's α and β (not the simulator's).
  ExistenceModel existence;
  // A landmark is "expected" (a miss lowers its existence) only this far inside the
  // sensor's range [m] and field of view [rad], to allow for its position uncertainty.
  double expect_range_margin_m = 1.0;
  double expect_bearing_margin_rad = 0.05;
  // Tentative landmarks below existence.delete_existence are removed every this many
  // scans (removal compacts a dense state, so batching it saves time on big maps).
  int cull_every_scans = 10;

  absl::Status Validate() const;

  // A landmark's existence after a detection or an expected miss: the existence model's
  // update, except that under known association a miss leaves it as it is.
  double UpdatedExistence(double current, bool detected) const {
    return known_association && !detected ? current : existence.Update(current, detected);
  }
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_LANDMARK_OPTIONS_H_
