// EifJoiner's gate on what a join may leave standing: snapshots of the joiner and their
// restoration, validated joins (a join whose factor fits its new estimate worse than χ² is
// undone and joined again without associations), and loop closures held pending until
// later maps confirm them (else undone and the maps since joined again, the closing one
// without loop pairings); the online anchor leaves a pending closure out.

#include <algorithm>
#include <utility>
#include <vector>

#include "eif_joiner_impl.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/models/gating.h"

namespace subslam::backend {

EifJoiner::Impl::Snapshot EifJoiner::Impl::TakeSnapshot() const {
  return Snapshot{estimate_, factors_, eta_, associator_, marginal_bound_, counters_};
}

void EifJoiner::Impl::Restore(Snapshot before) {
  estimate_ = std::move(before.estimate);
  factors_ = std::move(before.factors);
  information_matrix_.Forget();  // Λ is assembled again from the kept factors when needed
  eta_ = std::move(before.eta);
  associator_ = std::move(before.associator);
  marginal_bound_ = std::move(before.marginal_bound);  // bounds for the smaller Λ
  relative_bounds_.Clear();                            // computed for a larger Λ
  solver_.stale = true;                                // it absorbed the undone factors
  linearization_watch_.Reset();
  estimate_exact_ = false;  // the snapshot's estimate may be a partial one
  converged_ = false;
  counters_ = before.counters;
  touched_.assign(estimate_.graph.num_landmarks(), 1);
}

absl::Status EifJoiner::Impl::JoinOne(const LocalSubmap& s) {
  if (!options_.validate_joins) return JoinWith(s, /*associate=*/true);
  // Validated join: keep what a rejected join would have to undo.
  Snapshot before = TakeSnapshot();
  const long associated_before = counters_.associated;
  if (absl::Status st = JoinWith(s, /*associate=*/true); !st.ok()) return st;
  const int matched = static_cast<int>(counters_.associated - associated_before);
  if (matched == 0) return absl::OkStatus();
  // The new factor's normalised residual at the new estimate, against χ² with 2 dof per
  // matched feature (the end pose and new landmarks fit exactly).
  const double d2 = factors_.back().NormalizedResidual(estimate_);
  const double bound = models::ChiSquareQuantile(options_.validation_probability, 2 * matched);
  if (d2 <= bound) return absl::OkStatus();
  // Rejected: undo, and join the local map again without associations (its odometry
  // still links the chain; its features become new landmarks).
  if (pending_loop_ && pending_loop_->factor >= static_cast<int>(estimate_.graph.factors().size()) - 1) {
    pending_loop_.reset();  // the closure was this join's, now undone
  }
  Restore(std::move(before));
  ++counters_.rejected_joins;
  rejected_.push_back(s.id);
  return JoinWith(s, /*associate=*/false);
}

void EifJoiner::Impl::AnchorWithoutPendingClosure(Pose2* pose, Eigen::Matrix3d* covariance) const {
  const PendingLoopClosure& pending = *pending_loop_;
  *pose = pending.before.estimate.graph.anchors().back();  // the closing map's start anchor
  if (covariance != nullptr) *covariance = pending.association.start_anchor_covariance;
  for (int f = pending.factor; f < static_cast<int>(estimate_.graph.factors().size()); ++f) {
    const LocalSubmap& m = estimate_.graph.factors()[f].submap;
    *pose = covariance != nullptr ? ComposeWithCovariance(*pose, *covariance, m.end_pose(),
                                                          m.covariance.topLeftCorner<3, 3>(), covariance)
                                  : Compose(*pose, m.end_pose());
  }
}

Pose2 EifJoiner::Impl::LastAnchor() const {
  if (!pending_loop_) return estimate_.graph.anchors().back();
  Pose2 p;
  AnchorWithoutPendingClosure(&p, nullptr);
  return p;
}

Eigen::Matrix3d EifJoiner::Impl::LastAnchorCovariance() const {
  if (!pending_loop_) return JointCovariance({estimate_.graph.num_anchors() - 1}, {});
  Pose2 p;
  Eigen::Matrix3d c;
  AnchorWithoutPendingClosure(&p, &c);
  return c;
}

absl::Status EifJoiner::Impl::CheckPendingLoopClosure() {
  if (!pending_loop_) return absl::OkStatus();
  const int last = static_cast<int>(estimate_.graph.factors().size()) - 1;
  const int closing = pending_loop_->factor;
  if (last <= closing) return absl::OkStatus();  // the closing map itself was just joined
  // Old landmarks the closure did not use: they existed before the closing map, the
  // recent maps before it did not see them, and no map since has seen them.
  const int old_landmarks = pending_loop_->before.estimate.graph.num_landmarks();
  std::vector<char> used(old_landmarks, 0);
  const int first = std::max(0, closing - options_.association.recent_maps);
  for (int f = first; f < last; ++f) {
    for (int j : estimate_.graph.factors()[f].landmark_of_feature) {
      if (j < old_landmarks) used[j] = 1;
    }
  }
  for (int j : estimate_.graph.factors()[last].landmark_of_feature) {
    if (j < old_landmarks && !used[j]) {
      used[j] = 1;  // counted once
      ++pending_loop_->confirmations;
    }
  }
  if (pending_loop_->confirmations >= pending_loop_->needed) {
    pending_loop_.reset();
    ++counters_.loop_closures_confirmed;
    return absl::OkStatus();
  }
  if (last - closing < options_.association.loop_confirmation_maps) return absl::OkStatus();
  return UndoPendingLoopClosure();
}

absl::Status EifJoiner::Impl::UndoPendingLoopClosure() {
  const int last = static_cast<int>(estimate_.graph.factors().size()) - 1;
  const int closing = pending_loop_->factor;
  // Unconfirmed: back to the joiner before the closing map, whose work stays counted,
  // and the maps since joined again, the closing one without loop pairings.
  PendingLoopClosure pending = std::move(*pending_loop_);
  pending_loop_.reset();
  std::vector<LocalSubmap> maps;
  for (int f = closing; f <= last; ++f) maps.push_back(estimate_.graph.factors()[f].submap);
  const JoinerCounters work = counters_;
  Restore(std::move(pending.before));
  rejected_.resize(pending.rejected);
  // Decisions (thin, ambiguous, truncated) count those of the joins that stand; work and
  // confirmations count everything done.
  counters_.relinearizations = work.relinearizations;
  counters_.relinearizations_diverged = work.relinearizations_diverged;
  counters_.relinearizations_predicted_converged = work.relinearizations_predicted_converged;
  counters_.relinearized_on_heading = work.relinearized_on_heading;
  counters_.relinearized_on_linearization_error = work.relinearized_on_linearization_error;
  counters_.loop_closures_confirmed = work.loop_closures_confirmed;
  counters_.loop_closures_unconfirmed = work.loop_closures_unconfirmed + 1;
  counters_.associations_replayed = work.associations_replayed;
  counters_.incremental_updates = work.incremental_updates;
  counters_.full_factorizations = work.full_factorizations;
  counters_.nested_dissection_factorizations = work.nested_dissection_factorizations;
  counters_.reused_analyses = work.reused_analyses;
  counters_.failed_updates = work.failed_updates;
  counters_.candidates = work.candidates;
  counters_.candidates_bounded_out = work.candidates_bounded_out;
  counters_.covariance_columns = work.covariance_columns;
  counters_.covariance_reach = work.covariance_reach;
  // The closing map is associated again before any join refactorises: the factor must be
  // the restored Λ's (the restored estimate is already its solution). Counted on top of
  // the work above.
  if (absl::Status st = FullFactorization(); !st.ok()) return st;
  solver_.stale = false;
  for (size_t m = 0; m < maps.size(); ++m) {
    suppress_loop_closure_ = m == 0;
    if (m == 0) replayed_association_ = std::move(pending.association);
    const absl::Status st = JoinOne(maps[m]);
    suppress_loop_closure_ = false;
    replayed_association_.reset();
    if (!st.ok()) return st;
    // A closure made again by a later map waits for its own confirmation; its window
    // cannot end within these maps.
    if (m > 0) {
      if (absl::Status c = CheckPendingLoopClosure(); !c.ok()) return c;
    }
  }
  return absl::OkStatus();
}

void EifJoiner::Impl::GateLoopPairings(association::SubmapAssociation a, const JoinerCounters& counters_before,
                                       std::vector<int>* assoc_out) {
  std::vector<int>& assoc = *assoc_out;
  if (suppress_loop_closure_) {
    // The closing map of an unconfirmed loop closure: without its loop pairings.
    for (int i : a.uncertain_loop_features) assoc[i] = -1;
  } else if (!a.thin_loop_pairings.empty() && options_.association.confirm_thin_loops &&
             options_.association.loop_confirmation_maps > 0 && options_.RelinearizesAfterJoins() &&
             3.0 * a.start_position_sigma_m < options_.association.loop_confirmation_min_sigma_radius_m) {
    // A thin closure, held for confirmation; or, while a closure is held, more of the
    // same evidence (this map was associated given it).
    a.uncertain_loop_features.clear();
    for (const auto& [feature, landmark] : a.thin_loop_pairings) {
      assoc[feature] = landmark;
      a.uncertain_loop_features.push_back(feature);
    }
    if (!pending_loop_) {
      // It needs a full closure's worth of other old landmarks: the later maps are gated
      // given the held pairings, so those lend them no evidence.
      pending_loop_ = PendingLoopClosure{TakeSnapshot(),
                                         static_cast<int>(estimate_.graph.factors().size()),
                                         rejected_.size(),
                                         std::move(a),
                                         options_.association.min_loop_pairings,
                                         0,
                                         /*thin=*/true};
      pending_loop_->before.counters = counters_before;
    }
  } else if (!a.uncertain_loop_features.empty() && options_.association.loop_confirmation_maps > 0 &&
             options_.RelinearizesAfterJoins() && !pending_loop_ &&
             3.0 * a.start_position_sigma_m >= options_.association.loop_confirmation_min_sigma_radius_m) {
    pending_loop_ = PendingLoopClosure{TakeSnapshot(), static_cast<int>(estimate_.graph.factors().size()),
                                       rejected_.size(), std::move(a)};
    // Its decisions are counted again on an undo (its work is not): not twice.
    pending_loop_->before.counters = counters_before;
  }
}

}  // namespace subslam::backend
