// Landmark existence (HybridSLAM §3.2, Eq. 11), shared by EKF-SLAM and FastSLAM.
//
// Each landmark carries P(exists). With detection probability α and false-alarm
// probability β (the filter's, not the simulator's):
//   detected:                 p ← pα / (pα + (1 − p)β)
//   expected but not detected: p ← p(1 − α) / (p(1 − α) + (1 − p)(1 − β))
// clamped to [1e-9, max_existence] so the log-odds stay finite. A landmark is confirmed —
// reported and kept for good — once p exceeds `confirm_existence`; tentative landmarks
// below `delete_existence` are removed by the filters' periodic cull.
#ifndef SUBSLAM_FRONTEND_EXISTENCE_MODEL_H_
#define SUBSLAM_FRONTEND_EXISTENCE_MODEL_H_

#include "absl/status/status.h"

namespace subslam::frontend {

struct ExistenceModel {
  double detection_probability = 0.9;     // α
  double false_alarm_probability = 0.05;  // β
  double prior_existence = 0.5;           // before the creating detection is applied
  double confirm_existence = 0.95;        // confirmed (reported, never deleted) above this
  double delete_existence = 0.05;         // tentative landmarks below this are removed
  double max_existence = 0.9999;          // keeps the log-odds finite

  absl::Status Validate() const;
  // The updated existence after a detection (detected) or an expected miss.
  double Update(double existence, bool detected) const;
  // A new landmark's existence: the prior updated by its creating detection.
  double Initial() const { return Update(prior_existence, true); }
  bool Confirms(double existence) const { return existence > confirm_existence; }
  // Whether a landmark should be culled (never a confirmed one).
  bool Deletes(double existence, bool confirmed) const { return !confirmed && existence < delete_existence; }
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_EXISTENCE_MODEL_H_
