// When to close a local map (Combined SLAM §6.1, Fast Map Joining, HybridSLAM §6). The
// local mapper asks after every scan; any enabled criterion closes the map, once it is at
// least `min_duration_s` old:
//  * elapsed time: the map is older than `max_duration_s`;
//  * pose uncertainty (Combined SLAM §6.1, whose printed formula is garbled; our
//    reading): the local pose's standard deviations measured in sensor-noise units,
//    max(σ_x / σ_r, σ_y / σ_r, σ_θ / σ_b), exceed `max_pose_sigma_ratio` — the map
//    ends before the pose error dominates the sensor's;
//  * particle diversity (RBPF only): the share of distinct ancestors the particles have
//    at the map's first scan (FastSlam::LineageDiversity) fell below
//    `min_lineage_diversity` — resampling has collapsed the early path hypotheses, so
//    the particles no longer represent the map's uncertainty; or the effective sample
//    size ratio N_eff / N after the last scan's weight update fell below `min_ess_ratio`;
//  * feature count: the map holds `max_features` confirmed features (the rule of
//    thumb of Combined SLAM: 5-20 × the pose dimension, 15-60);
//  * landmark density (Fast Map Joining sizes local maps by the density of features; it
//    gives no formula, our reading): the map holds at least `density_min_features`
//    confirmed features and at least `density_min_visible` of them are within sensor
//    range of the vehicle now — closing where landmarks are dense gives the next map
//    many common features to join on.
// Delay (HybridSLAM §6, option): while the particles disagree about the last scan's
// identities (the weight voting against the winner exceeds `ambiguity_threshold`),
// closing is postponed, at most by `max_delay_s` after a criterion first fired.
// With `enabled` false the map is never closed (single-map FastSLAM / EKF-SLAM).
#ifndef SUBSLAM_FRONTEND_SUBMAP_POLICY_H_
#define SUBSLAM_FRONTEND_SUBMAP_POLICY_H_

#include <Eigen/Core>

#include "absl/status/status.h"
#include "subslam/frontend/moving_feature_test.h"

namespace subslam::frontend {

struct SubmapPolicyOptions {
  bool enabled = true;
  double min_duration_s = 1.0;
  double max_duration_s = 10.0;        // 0: off (10 s: HybridSLAM §5)
  double max_pose_sigma_ratio = 0.0;   // 0: off
  double min_lineage_diversity = 0.5;  // 0: off (our choice, bench/RESULTS.md)
  double min_ess_ratio = 0.0;          // 0: off
  int max_features = 30;               // 0: off (10 × the pose dimension)
  int density_min_features = 0;        // 0: off
  int density_min_visible = 8;
  bool delay_while_ambiguous = false;
  double ambiguity_threshold = 0.2;
  double max_delay_s = 5.0;
  // What a closed map exports (both mappers): not a feature that, relative to the map's
  // end pose (its covariance conditioned on the end pose), along its widest axis, is more
  // uncertain than this many times one detection at the sensor's maximum range
  // (max(σ_r, σ_b · max range)). Such a feature carries less than one detection's
  // information, and in an RBPF map it is usually one the particles place apart (two
  // trees the sensor cannot separate, say); its wide gate lets the back-end join it to a
  // landmark metres away (bench/RESULTS.md). Conditioning on the end pose
  // keeps the features that are uncertain only through the drift they share with it.
  // 0: export all.
  double max_feature_sigma_ratio = 1.0;
  // Nor a feature whose detections a static point does not explain (moving_feature_test.h:
  // another robot carrying a landmark's marker, a walking person).
  MovingFeatureTestOptions moving_features;

  absl::Status Validate() const;
};

// What the policy looks at, measured by the local mapper after a scan.
struct SubmapStatus {
  double elapsed_s = 0.0;
  Eigen::Matrix3d pose_covariance = Eigen::Matrix3d::Zero();  // local pose
  double ess_ratio = 1.0;
  double lineage_diversity = 1.0;
  int confirmed_features = 0;
  int visible_features = 0;    // confirmed and within sensor range now
  double disagreement = 0.0;   // weight voting against the winner, last scan
  double delayed_for_s = 0.0;  // how long closing has been postponed already
};

enum class CloseReason {
  kKeepOpen,
  kElapsedTime,
  kPoseUncertainty,
  kDiversity,
  kFeatureCount,
  kLandmarkDensity,
  kEndOfRun,
};
const char* ToString(CloseReason reason);

struct SubmapDecision {
  CloseReason reason = CloseReason::kKeepOpen;
  bool delayed = false;  // a criterion fired but closing was postponed (ambiguity)
};

class SubmapPolicy {
 public:
  // σ_r [m] and σ_b [rad] of the sensor scale the pose-uncertainty criterion.
  SubmapPolicy(const SubmapPolicyOptions& options, double sigma_range_m, double sigma_bearing_rad);

  SubmapDecision Decide(const SubmapStatus& status) const;
  const SubmapPolicyOptions& options() const { return options_; }

 private:
  SubmapPolicyOptions options_;
  double sigma_range_m_, sigma_bearing_rad_;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_SUBMAP_POLICY_H_
