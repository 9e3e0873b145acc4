// EifJoiner: revisable association — merge and split passes (landmark_revision.h) and
// how their decisions re-key the factors.

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "eif_joiner_impl.h"
#include "state_blocks.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/internal/sparse_cholesky.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/core/check.h"
#include "subslam/core/stage_timer.h"
#include "subslam/models/gating.h"

namespace subslam::backend {

absl::Status EifJoiner::Impl::ReviseAssociation(bool full) {
  // In-run passes test the pairs a join touched (and the splits after a relinearisation);
  // a full pass every pair.
  const bool with_splits = full || relinearized_since_revision_;
  const bool all_pairs = full;
  relinearized_since_revision_ = false;
  if (!options_.revision.enabled() || options_.association.known_association || pending_loop_ || factors_.empty()) {
    return absl::OkStatus();
  }
  ++counters_.revision_passes;
  StageTimer timer(&times_, "revision");
  std::vector<association::FeatureSplit> splits;
  if (with_splits) {
    splits = association::FindFeatureSplits(
        estimate_.graph,
        [this](int anchor, const std::vector<int>& landmarks) { return FactorMarginals(anchor, landmarks); },
        options_.revision);
  }
  // The pre-filter's marginals: the bounds association keeps (upper bounds keep it exact),
  // recovered where there is none.
  std::vector<Eigen::Matrix2d> marginals = marginal_bound_;
  int missing = 0;
  for (const Eigen::Matrix2d& m : marginals) missing += m.allFinite() ? 0 : 1;
  if (missing > 0) {
    // A few by their own solves, many (a relinearisation forgot them) all at once.
    constexpr int kBulkFrom = 16;
    std::vector<Eigen::Matrix2d> exact;
    if (missing >= kBulkFrom) exact = LandmarkCovariances();
    for (int j = 0; j < estimate_.graph.num_landmarks(); ++j) {
      if (!marginals[j].allFinite()) marginals[j] = exact.empty() ? LandmarkCovariance(j) : exact[j];
    }
    // Today's exact marginals bound every later one until the next relinearisation.
    if (options_.bound_candidate_marginals) marginal_bound_ = marginals;
  }
  touched_.resize(estimate_.graph.num_landmarks(), 1);
  std::vector<Eigen::Matrix2d> own(estimate_.graph.num_landmarks(),
                                   Eigen::Matrix2d::Constant(NAN));  // Λ is fixed in the pass
  std::vector<association::LandmarkMerge> merges = association::FindLandmarkMerges(
      estimate_.graph, marginals, [this, &own](int a, int b) { return LandmarkPairCovariance(a, b, &own); },
      options_.revision, options_.association.loop_test_min_sigma_radius_m, all_pairs ? std::vector<char>() : touched_,
      association::LoopMergeTests{options_.association.min_loop_pairings,
                                  options_.association.loop_confirmation_min_sigma_radius_m,
                                  [this](const std::vector<int>& landmarks) { return JointCovariance({}, landmarks); }},
      &relative_bounds_);
  touched_.assign(estimate_.graph.num_landmarks(), 0);
  // A landmark a split leaves is not merged in the same pass (its estimate will move).
  std::vector<char> split_from(estimate_.graph.num_landmarks(), 0);
  for (const association::FeatureSplit& sp : splits)
    split_from[estimate_.graph.factors()[sp.factor].landmark_of_feature[sp.feature]] = 1;
  std::erase_if(merges, [&](const association::LandmarkMerge& m) { return split_from[m.keep] || split_from[m.drop]; });
  if (splits.empty() && merges.empty()) return absl::OkStatus();
  StageTimer solve(&times_, "revision_solve");  // (within "revision")
  return ApplyRevisions(splits, merges);
}

absl::Status EifJoiner::Impl::MergeLandmarks(int keep, int drop) {
  if (absl::Status st = estimate_.graph.ValidateMerge(keep, drop); !st.ok()) return st;
  return ApplyRevisions({}, {association::LandmarkMerge{std::min(keep, drop), std::max(keep, drop), NAN}});
}

absl::Status EifJoiner::Impl::SplitFeature(int factor, int feature) {
  if (absl::Status st = estimate_.graph.ValidateSplit(factor, feature); !st.ok()) return st;
  return ApplyRevisions({association::FeatureSplit{factor, feature, NAN}}, {});
}

absl::Status EifJoiner::Impl::ApplyRevisions(const std::vector<association::FeatureSplit>& splits,
                                             const std::vector<association::LandmarkMerge>& merges) {
  for (const association::FeatureSplit& sp : splits) {
    const SubmapFactor& record = estimate_.graph.factors()[sp.factor];
    const int from = record.landmark_of_feature[sp.feature];
    const double signature = record.submap.landmarks[sp.feature].signature;
    absl::StatusOr<int> to = estimate_.graph.SplitFeature(sp.factor, sp.feature);
    if (!to.ok()) return to.status();
    associator_.SplitFeature(from, *to, signature);
    touched_.resize(estimate_.graph.num_landmarks(), 1);
    touched_[from] = touched_[*to] = 1;
    estimate_.AddRowsOfNewestLandmark();
    marginal_bound_.push_back(Eigen::Matrix2d::Constant(NAN));
    ++counters_.features_split;
  }
  for (const association::LandmarkMerge& m : merges) {
    if (absl::Status st = estimate_.graph.MergeLandmarks(m.keep, m.drop); !st.ok()) return st;
    associator_.MergeLandmarks(m.keep, m.drop);
    if (m.drop < static_cast<int>(touched_.size())) touched_.erase(touched_.begin() + m.drop);
    if (m.keep < static_cast<int>(touched_.size())) touched_[m.keep] = 1;
    estimate_.RemoveRowsOfLandmark(m.drop);
    marginal_bound_.erase(marginal_bound_.begin() + m.drop);
    for (int& j : last_association_) j = SubmapGraph::RenumberAfterMerge(j, m.keep, m.drop);
    ++counters_.landmarks_merged;
  }
  // Every factor's variables where they now sit. Its linear model stays valid: the factor
  // is affine in the landmarks (nonlinear only through the start heading), so re-keying a
  // landmark column is exact, and the re-keyed Λ is the revised problem's at the same
  // linearisation. Then Gauss-Newton from there where the joiner relinearises.
  for (EifFactor& f : factors_) f.SetLayout(estimate_);
  information_matrix_.Forget();
  solver_.stale = true;
  if (absl::Status st = Rebuild(/*only_last_factor=*/false); !st.ok()) return st;
  if (options_.RelinearizesAfterJoins() || options_.relinearize_at_end) return GaussNewton();
  return absl::OkStatus();
}

}  // namespace subslam::backend
