#include "subslam/frontend/submap_policy.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "subslam/core/check.h"
#include "subslam/core/enum_names.h"

namespace subslam::frontend {

absl::Status SubmapPolicyOptions::Validate() const {
  const auto nonnegative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!nonnegative(min_duration_s) || !nonnegative(max_duration_s) || !nonnegative(max_pose_sigma_ratio) ||
      !nonnegative(max_delay_s)) {
    return absl::InvalidArgumentError("submap policy: durations and ratios must be >= 0");
  }
  if (!nonnegative(max_feature_sigma_ratio)) {
    return absl::InvalidArgumentError(
        absl::StrCat("submap policy: max_feature_sigma_ratio must be >= 0 (0: export every feature), got ",
                     max_feature_sigma_ratio));
  }
  if (!(min_ess_ratio >= 0.0 && min_ess_ratio <= 1.0) ||
      !(min_lineage_diversity >= 0.0 && min_lineage_diversity <= 1.0) ||
      !(ambiguity_threshold >= 0.0 && ambiguity_threshold <= 1.0)) {
    return absl::InvalidArgumentError(
        "submap policy: min_ess_ratio, min_lineage_diversity and ambiguity_threshold must be "
        "in [0, 1]");
  }
  if (absl::Status s = moving_features.Validate(); !s.ok()) return s;
  if (max_features < 0 || density_min_features < 0 || density_min_visible < 1) {
    return absl::InvalidArgumentError("submap policy: feature counts must be >= 0 (density_min_visible >= 1)");
  }
  return absl::OkStatus();
}

namespace {
constexpr EnumName<CloseReason> kCloseReasonNames[] = {{CloseReason::kKeepOpen, "keep_open"},
                                                       {CloseReason::kElapsedTime, "elapsed_time"},
                                                       {CloseReason::kPoseUncertainty, "pose_uncertainty"},
                                                       {CloseReason::kDiversity, "particle_diversity"},
                                                       {CloseReason::kFeatureCount, "feature_count"},
                                                       {CloseReason::kLandmarkDensity, "landmark_density"},
                                                       {CloseReason::kEndOfRun, "end_of_run"}};
}  // namespace

const char* ToString(CloseReason reason) { return NameOf(kCloseReasonNames, reason); }

SubmapPolicy::SubmapPolicy(const SubmapPolicyOptions& options, double sigma_range_m, double sigma_bearing_rad)
    : options_(options), sigma_range_m_(sigma_range_m), sigma_bearing_rad_(sigma_bearing_rad) {
  SUBSLAM_CHECK(options_.Validate().ok()) << options_.Validate().message();
  SUBSLAM_CHECK(sigma_range_m > 0 && sigma_bearing_rad > 0) << "sensor sigmas must be > 0";
}

SubmapDecision SubmapPolicy::Decide(const SubmapStatus& s) const {
  const SubmapPolicyOptions& o = options_;
  if (!o.enabled || s.elapsed_s < o.min_duration_s) return {};
  CloseReason reason = CloseReason::kKeepOpen;
  const Eigen::Vector3d sigma = s.pose_covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  const double pose_ratio =
      std::max({sigma.x() / sigma_range_m_, sigma.y() / sigma_range_m_, sigma.z() / sigma_bearing_rad_});
  if (o.max_duration_s > 0 && s.elapsed_s >= o.max_duration_s) {
    reason = CloseReason::kElapsedTime;
  } else if (o.max_pose_sigma_ratio > 0 && pose_ratio > o.max_pose_sigma_ratio) {
    reason = CloseReason::kPoseUncertainty;
  } else if ((o.min_ess_ratio > 0 && s.ess_ratio < o.min_ess_ratio) ||
             (o.min_lineage_diversity > 0 && s.lineage_diversity < o.min_lineage_diversity)) {
    reason = CloseReason::kDiversity;
  } else if (o.max_features > 0 && s.confirmed_features >= o.max_features) {
    reason = CloseReason::kFeatureCount;
  } else if (o.density_min_features > 0 && s.confirmed_features >= o.density_min_features &&
             s.visible_features >= o.density_min_visible) {
    reason = CloseReason::kLandmarkDensity;
  }
  if (reason == CloseReason::kKeepOpen) return {};
  if (o.delay_while_ambiguous && s.disagreement > o.ambiguity_threshold && s.delayed_for_s < o.max_delay_s) {
    return {CloseReason::kKeepOpen, true};
  }
  return {reason, false};
}

}  // namespace subslam::frontend
