#include "subslam/association/submap_association.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "association_gating.h"
#include "grouped_association.h"
#include "recent_rotation_fit.h"
#include "subslam/association/data_association.h"
#include "subslam/association/local_map_rotation.h"
#include "subslam/models/gating.h"

namespace subslam::association {

absl::Status SubmapAssociationOptions::Validate() const {
  if (!(anchor_search_radius_m >= 0 && landmark_search_radius_m >= 0)) {
    return absl::InvalidArgumentError("search radii must be >= 0");
  }
  if (!(gate_probability > 0 && gate_probability < 1)) {
    return absl::InvalidArgumentError("gate_probability must be in (0, 1)");
  }
  if (!(sigma_signature >= 0 && std::isfinite(sigma_signature))) {
    return absl::InvalidArgumentError("sigma_signature must be finite and >= 0");
  }
  if (jcbb_max_nodes < 1) return absl::InvalidArgumentError("jcbb_max_nodes must be >= 1");
  if (recent_maps < 0 || !(loop_test_min_sigma_radius_m >= 0)) {
    return absl::InvalidArgumentError("recent_maps and loop_test_min_sigma_radius_m must be >= 0");
  }
  if (loop_confirmation_maps < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("loop_confirmation_maps must be >= 0, got ", loop_confirmation_maps));
  }
  if (!(loop_confirmation_min_sigma_radius_m >= 0 && std::isfinite(loop_confirmation_min_sigma_radius_m))) {
    return absl::InvalidArgumentError(
        absl::StrCat("loop_confirmation_min_sigma_radius_m must be finite and >= 0 [m], got ",
                     loop_confirmation_min_sigma_radius_m));
  }
  if (!(map_rotation_probability > 0 && map_rotation_probability < 1)) {
    return absl::InvalidArgumentError(
        absl::StrCat("map_rotation_probability must be in (0, 1), got ", map_rotation_probability));
  }
  if (!(map_rotation_spread_probability >= 0 && map_rotation_spread_probability < 1)) {
    return absl::InvalidArgumentError(
        absl::StrCat("map_rotation_spread_probability must be in [0, 1), got ", map_rotation_spread_probability));
  }
  if (!(map_rotation_sigma_rad >= 0 && std::isfinite(map_rotation_sigma_rad))) {
    return absl::InvalidArgumentError(
        absl::StrCat("map_rotation_sigma_rad must be finite and >= 0 [rad], got ", map_rotation_sigma_rad));
  }
  return absl::OkStatus();
}

std::vector<std::vector<int>> WholeMapGroups(const SubmapGraph& graph) {
  std::vector<std::vector<int>> groups;
  groups.reserve(graph.factors().size());
  for (const SubmapFactor& f : graph.factors()) groups.push_back(f.landmark_of_feature);
  return groups;
}

std::optional<LocalSubmap> RotatedBack(const LocalSubmap& s, const SubmapAssociation& a) {
  if (!a.map_rotated || s.rotation_widening_rad > 0) return std::nullopt;
  return WidenedByRotation(RotatedAboutStart(s, a.map_rotation_rad), a.map_widening_rad);
}

SubmapAssociator::SubmapAssociator(const SubmapAssociationOptions& options)
    : options_(options),
      rotation_spread_(options.map_rotation_sigma_rad > 0 && options.map_rotation_spread_probability > 0 &&
                               options.map_rotation_spread_probability < 1
                           ? options.map_rotation_spread_probability
                           : 0.0,
                       options.map_rotation_probability > 0 && options.map_rotation_probability < 1
                           ? options.map_rotation_probability
                           : 0.99) {}

LocalSubmap SubmapAssociator::WithRotationSpread(const LocalSubmap& s) const { return rotation_spread_.Widened(s); }

void SubmapAssociator::RecordRotationFit(const LocalSubmap& joined) {
  rotation_spread_.Add(joined.rotation_fit_rad, joined.rotation_fit_variance_rad2, joined.rotation_spread_rad);
}

void StampRotationFit(const SubmapAssociation& a, LocalSubmap* s) {
  if (std::isfinite(s->rotation_fit_rad)) return;
  s->rotation_fit_rad = a.map_rotation_fit_rad;
  s->rotation_fit_variance_rad2 = a.map_rotation_fit_variance_rad2;
}

double SubmapAssociator::MeanSignature(int landmark) const {
  if (landmark >= static_cast<int>(signature_count_.size()) || signature_count_[landmark] == 0) return NAN;
  return signature_sum_[landmark] / signature_count_[landmark];
}

std::vector<int> SubmapAssociator::TruthIds(int num_landmarks) const {
  std::vector<int> out(num_landmarks, -1);
  for (const auto& [truth, landmark] : landmark_of_truth_) {
    if (landmark < num_landmarks) out[landmark] = truth;
  }
  return out;
}

void SubmapAssociator::Record(const LocalSubmap& s, const std::vector<int>& landmark_of_feature, int first_new_landmark,
                              bool define_truth) {
  int needed = 0;
  for (int j : landmark_of_feature) needed = std::max(needed, j + 1);
  if (needed > static_cast<int>(signature_sum_.size())) {
    signature_sum_.resize(needed, 0.0);
    signature_count_.resize(needed, 0);
  }
  for (int i = 0; i < s.num_landmarks(); ++i) {
    const int j = landmark_of_feature[i];
    if (std::isfinite(s.landmarks[i].signature)) {
      signature_sum_[j] += s.landmarks[i].signature;
      ++signature_count_[j];
    }
    const std::optional<int>& t = s.landmarks[i].truth_id;
    if (define_truth && j >= first_new_landmark && t.has_value() && *t >= 0) landmark_of_truth_[*t] = j;
  }
}

void SubmapAssociator::MergeLandmarks(int keep, int drop) {
  if (drop < static_cast<int>(signature_sum_.size())) {
    if (keep >= static_cast<int>(signature_sum_.size())) {
      signature_sum_.resize(keep + 1, 0.0);
      signature_count_.resize(keep + 1, 0);
    }
    signature_sum_[keep] += signature_sum_[drop];
    signature_count_[keep] += signature_count_[drop];
    signature_sum_.erase(signature_sum_.begin() + drop);
    signature_count_.erase(signature_count_.begin() + drop);
  }
  for (auto& [truth, landmark] : landmark_of_truth_) landmark = SubmapGraph::RenumberAfterMerge(landmark, keep, drop);
}

void SubmapAssociator::SplitFeature(int from, int to, double signature) {
  const int needed = std::max(from, to) + 1;
  if (needed > static_cast<int>(signature_sum_.size())) {
    signature_sum_.resize(needed, 0.0);
    signature_count_.resize(needed, 0);
  }
  if (std::isfinite(signature)) {
    signature_sum_[from] -= signature;
    --signature_count_[from];
    signature_sum_[to] += signature;
    ++signature_count_[to];
  }
}

using submap_matching::AddRecentCandidates;
using submap_matching::ApplyLoopPairingTest;
using submap_matching::CandidateGeometry;
using submap_matching::FitRecentRotation;
using submap_matching::FlagLoopLandmarks;
using submap_matching::GateTest;
using submap_matching::Geometry;
using submap_matching::IndividualCompatibility;
using submap_matching::InnovationCovariance;
using submap_matching::JointlyCompatible;
using submap_matching::LoopFlags;
using submap_matching::NearbyLandmarks;
using submap_matching::Place;
using submap_matching::PlacedMap;
using submap_matching::PossiblyCompatible;
using submap_matching::RecentLandmarks;
using submap_matching::Relinearization;
using submap_matching::RotationFit;
using submap_matching::TimedCovariance;

SubmapAssociation SubmapAssociator::AssociateByTruth(const LocalSubmap& s) const {
  SubmapAssociation out;
  out.landmark_of_feature.assign(s.num_landmarks(), -1);
  for (int i = 0; i < s.num_landmarks(); ++i) {
    const std::optional<int>& t = s.landmarks[i].truth_id;
    if (!t.has_value() || *t < 0) continue;  // unknown or false alarm: a new landmark
    auto it = landmark_of_truth_.find(*t);
    if (it != landmark_of_truth_.end()) out.landmark_of_feature[i] = it->second;
  }
  return out;
}

SubmapAssociation SubmapAssociator::Associate(const LocalSubmap& s, int start_anchor, const SubmapGraph& graph,
                                              const JointCovarianceFn& joint_covariance, bool anchor_prefilter,
                                              const PairCovarianceFn& pair_covariance, const PairBoundFn& pair_bound,
                                              const std::vector<std::vector<int>>* groups) const {
  if (options_.known_association) return AssociateByTruth(s);
  const int n = s.num_landmarks();
  SubmapAssociation out;
  out.landmark_of_feature.assign(n, -1);
  const TimedCovariance timed_covariance(joint_covariance, &out.covariance_seconds);
  const Eigen::Matrix3d Sigma_s = timed_covariance({start_anchor}, {});
  out.start_anchor_covariance = Sigma_s;
  const PlacedMap placed = Place(s, graph.anchors()[start_anchor], Sigma_s, options_.landmark_search_radius_m);
  out.start_position_sigma_m = placed.sigma_xy;
  std::vector<int> candidates = NearbyLandmarks(graph, placed, anchor_prefilter, options_.anchor_search_radius_m);
  // The rotation test (map_rotation_sigma_rad) looks for the recent landmarks as far as the
  // widened map's features reach. (A map joined widened once, and associated again after an
  // undone loop closure, is not tested again.)
  const double sigma_rotation = options_.map_rotation_sigma_rad;
  const bool test_rotation =
      sigma_rotation > 0 && options_.joint_compatibility && groups == nullptr && !(s.rotation_widening_rad > 0);
  std::optional<PlacedMap> placed_widened;
  Eigen::Matrix3d Sigma_widened = Sigma_s;
  Sigma_widened(2, 2) += sigma_rotation * sigma_rotation;  // the search radii grow as for the start heading
  std::vector<char> recent;
  if (test_rotation) {
    placed_widened = Place(s, placed.P_s, Sigma_widened, options_.landmark_search_radius_m);
    recent = RecentLandmarks(graph, std::max(1, options_.recent_maps));
    AddRecentCandidates(graph, *placed_widened, recent, &candidates);
  }
  out.candidates = static_cast<int>(candidates.size());
  const GateTest gate(s, *this);
  if (pair_bound && pair_covariance) {
    const absl::Time t0 = absl::Now();
    const std::vector<std::optional<Matrix5d>> bounds = pair_bound(start_anchor, candidates);
    out.covariance_seconds += absl::ToDoubleSeconds(absl::Now() - t0);
    std::vector<int> kept =
        test_rotation ? PossiblyCompatible(candidates, bounds, placed, graph, s, gate, &*placed_widened, &recent)
                      : PossiblyCompatible(candidates, bounds, placed, graph, s, gate);
    out.candidates_bounded_out = static_cast<int>(candidates.size() - kept.size());
    candidates.swap(kept);
  }
  if (candidates.empty()) return out;
  const CandidateGeometry geometry =
      Geometry(start_anchor, candidates, placed.P_s, graph, pair_covariance, timed_covariance, &out.covariance_seconds);
  const LoopFlags loop = FlagLoopLandmarks(options_, graph, placed.sigma_xy, candidates, geometry);
  const bool by_group = groups != nullptr && options_.joint_compatibility;
  // Steps 3-5 for the map `m` (the local map, or it widened by a rotation) placed as `placed_m`.
  const auto associate_features = [&](const LocalSubmap& m, const PlacedMap& placed_m, SubmapAssociation* a) {
    association::AssociationProblem problem = IndividualCompatibility(m, candidates, placed_m, graph, geometry, gate);
    std::optional<Relinearization> relinearization;
    if (by_group) {
      relinearization.emplace(m, start_anchor, candidates, graph, geometry, placed_m.P_s, Sigma_s,
                              options_.landmark_search_radius_m, gate, timed_covariance);
    }
    association::AssociationResult result =
        options_.joint_compatibility
            ? JointlyCompatible(options_, m, start_anchor, candidates, geometry, loop, timed_covariance,
                                by_group ? groups : nullptr, relinearization ? &*relinearization : nullptr, &problem, a)
            : association::NearestNeighbour(problem);
    for (int i = 0; i < n; ++i) {
      if (result.landmark_of_detection[i] >= 0) a->landmark_of_feature[i] = candidates[result.landmark_of_detection[i]];
    }
    if (!by_group) ApplyLoopPairingTest(options_, loop, a);  // the grouped search applied it per group
  };
  associate_features(s, placed, &out);
  if (!test_rotation) return out;
  const RotationFit fit = FitRecentRotation(options_, s, placed, Sigma_widened, start_anchor, candidates, graph,
                                            geometry, gate, timed_covariance, recent, out.landmark_of_feature);
  out.map_rotation_statistic = fit.statistic;
  if (std::isfinite(fit.statistic)) {
    out.map_rotation_fit_rad = fit.delta_rad;
    out.map_rotation_fit_variance_rad2 = fit.variance_rad2;
  }
  if (!(fit.statistic >= models::ChiSquareQuantile(options_.map_rotation_probability, 1))) return out;
  // The map is rotated beyond its covariance: associated, and joined, widened.
  SubmapAssociation again;
  again.landmark_of_feature.assign(n, -1);
  again.map_rotated = true;
  again.map_rotation_rad = fit.delta_rad;
  // The rotation's spread, as the data show it: δ̂ ~ N(0, σ² + var δ̂) for a map rotated by
  // N(0, σ²) gives σ̂² = δ̂² − var δ̂ (positive: the test passed).
  again.map_widening_rad = std::sqrt(std::max(0.0, fit.delta_rad * fit.delta_rad - fit.variance_rad2));
  again.map_rotation_statistic = fit.statistic;
  again.map_rotation_fit_rad = out.map_rotation_fit_rad;
  again.map_rotation_fit_variance_rad2 = out.map_rotation_fit_variance_rad2;
  const LocalSubmap joined = *RotatedBack(s, again);
  associate_features(joined, Place(joined, placed.P_s, Sigma_widened, options_.landmark_search_radius_m), &again);
  again.jcbb_truncated = again.jcbb_truncated || out.jcbb_truncated;
  again.covariance_seconds = out.covariance_seconds;
  again.candidates = out.candidates;
  again.candidates_bounded_out = out.candidates_bounded_out;
  again.start_anchor_covariance = out.start_anchor_covariance;
  again.start_position_sigma_m = out.start_position_sigma_m;
  return again;
}

}  // namespace subslam::association
