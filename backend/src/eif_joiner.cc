// EifJoiner: options, joining a local map (association, the factor), the end of the run,
// copies and whole-map (tree) joins. The loop-closure gate is eif_loop_closure.cc.

#include "subslam/backend/eif_joiner.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "eif_joiner_impl.h"
#include "state_blocks.h"
#include "subslam/backend/internal/sparse_cholesky.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/core/check.h"
#include "subslam/core/stage_timer.h"
#include "subslam/models/gating.h"

namespace subslam::backend {

absl::Status EifJoinerOptions::Validate() const {
  if (absl::Status s = association.Validate(); !s.ok()) return s;
  if (absl::Status s = revision.Validate(); !s.ok()) return s;
  if (!(validation_probability > 0 && validation_probability < 1)) {
    return absl::InvalidArgumentError("validation_probability must be in (0, 1)");
  }
  if (relinearize_every < 0) {
    return absl::InvalidArgumentError(absl::StrCat("relinearize_every must be >= 0, got ", relinearize_every));
  }
  if (!(recovery_change_threshold >= 0 && std::isfinite(recovery_change_threshold))) {
    return absl::InvalidArgumentError(
        absl::StrCat("recovery_change_threshold must be finite and >= 0, got ", recovery_change_threshold));
  }
  if (max_relinearizations < 1) {
    return absl::InvalidArgumentError(absl::StrCat("max_relinearizations must be >= 1, got ", max_relinearizations));
  }
  if (!(relinearize_step_chi2 >= 0)) {
    return absl::InvalidArgumentError(absl::StrCat("relinearize_step_chi2 must be >= 0, got ", relinearize_step_chi2));
  }
  if (!(relinearize_tolerance > 0)) {
    return absl::InvalidArgumentError(absl::StrCat("relinearize_tolerance must be > 0, got ", relinearize_tolerance));
  }
  if (divergence_rises < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("divergence_rises (--relinearize_max_rises) must be >= 0, got ", divergence_rises));
  }
  if (!(relinearize_linearization_chi2 >= 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("relinearize_linearization_chi2 must be >= 0, got ", relinearize_linearization_chi2));
  }
  if (!(relinearize_heading_change >= 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("relinearize_heading_change must be >= 0 [rad], got ", relinearize_heading_change));
  }
  return absl::OkStatus();
}

bool EifJoinerOptions::RelinearizesAfterJoins() const {
  return relinearize_linearization_chi2 > 0 || relinearize_heading_change > 0;
}

EifJoinerOptions EifJoinerOptions::SingleLinearization() const {
  EifJoinerOptions o = *this;
  o.relinearize_heading_change = 0.0;
  o.relinearize_linearization_chi2 = 0.0;
  o.relinearize_every = 0;
  o.relinearize_at_end = false;
  o.revision.merge = o.revision.split = false;  // a revision relinearises every factor
  return o;
}

EifJoinerOptions EifJoinerOptions::ForTreeNode() const {
  EifJoinerOptions o = *this;
  o.incremental_factorization = false;
  return o;
}

EifJoiner::Impl::Impl(const Pose2& initial_pose, const EifJoinerOptions& options)
    : options_(options), estimate_(initial_pose), associator_(options.association) {
  SUBSLAM_CHECK(options_.Validate().ok()) << options_.Validate().message();
  for (const char* stage : {"association", "covariance_recovery", "update", "factorization", "recovery"}) {
    times_[stage] = 0.0;
  }
}

absl::Status EifJoiner::Impl::JoinLocalMap(const LocalSubmap& s) {
  if (absl::Status v = s.Validate(); !v.ok()) return v;
  if (s.t_start < last_t_end_ - 1e-9) {
    return absl::InvalidArgumentError(absl::StrCat("local map ", s.id, " starts at ", s.t_start,
                                                   " before the previous one ended (", last_t_end_, ")"));
  }
  // Widened by the maps' rotation spread as measured so far (a map joined again after an
  // undone loop closure is taken back from the graph as it was joined).
  if (absl::Status st = JoinOne(associator_.WithRotationSpread(s)); !st.ok()) return st;
  return CheckPendingLoopClosure();
}

void EifJoiner::Impl::CountDecisions(const association::SubmapAssociation& a) {
  if (a.jcbb_truncated) ++counters_.jcbb_truncated;
  if (a.loop_pairings_dropped > 0) ++counters_.loop_closures_thin;
  if (a.loop_ambiguous) ++counters_.loop_closures_ambiguous;
  counters_.loop_closures_confirmed += a.loop_closures_confirmed;
  counters_.loop_closures_unconfirmed += a.loop_closures_unconfirmed;
  if (a.map_rotated) ++counters_.maps_widened;
}

association::SubmapAssociation EifJoiner::Impl::AssociateAt(const LocalSubmap& s, int start,
                                                            const std::vector<std::vector<int>>* whole_map_groups) {
  StageTimer timer(&times_, "association");
  const long columns_before = solver_.factor.columns_solved(), reach_before = solver_.factor.reach_solved();
  // Each recovered landmark marginal is today's, so it bounds every later one (Λ grows).
  const auto pair_covariance = [this](int anchor, const std::vector<int>& landmarks) {
    std::vector<association::Matrix5d> blocks = AnchorLandmarkCovariances(anchor, landmarks);
    for (size_t c = 0; c < landmarks.size(); ++c) {
      marginal_bound_[landmarks[c]] = blocks[c].bottomRightCorner<2, 2>();
    }
    return blocks;
  };
  const auto bound = [this](int anchor, const std::vector<int>& landmarks) {
    return AnchorLandmarkBounds(anchor, landmarks);
  };
  association::SubmapAssociation a = associator_.Associate(
      s, start, estimate_.graph,
      [this](const std::vector<int>& anchors, const std::vector<int>& landmarks) {
        return JointCovariance(anchors, landmarks);
      },
      /*anchor_prefilter=*/whole_map_groups == nullptr, pair_covariance,
      options_.bound_candidate_marginals ? association::SubmapAssociator::PairBoundFn(bound) : nullptr,
      whole_map_groups);
  times_["covariance_recovery"] += a.covariance_seconds;
  innovation_d2_ += a.pairings_d2;
  innovation_dof_ += a.pairings_dof;
  CountDecisions(a);
  counters_.candidates += a.candidates;
  counters_.candidates_bounded_out += a.candidates_bounded_out;
  counters_.covariance_columns += solver_.factor.columns_solved() - columns_before;
  counters_.covariance_reach += solver_.factor.reach_solved() - reach_before;
  return a;
}

int EifJoiner::Impl::AddEndAnchorAndLandmarks(const LocalSubmap& m, int start, const Eigen::Matrix3d& start_covariance,
                                              std::vector<int>* assoc) {
  // Initialise the end anchor and the new landmarks through the start anchor.
  const Pose2 P_s(estimate_.graph.anchors()[start].x, estimate_.graph.anchors()[start].y,
                  estimate_.anchor_theta[start]);
  const Pose2 end_local = m.end_pose();
  const Pose2 end = Compose(P_s, end_local);
  const int end_anchor =
      estimate_.AddAnchor(Pose2(end.x, end.y, WrapAngle(end.theta)), estimate_.anchor_theta[start] + end_local.theta);
  for (int i = 0; i < m.num_landmarks(); ++i) {
    if ((*assoc)[i] >= 0) {
      ++counters_.associated;
    } else {
      Matrix23d J_frame;
      Eigen::Matrix2d J_point;
      (*assoc)[i] = estimate_.AddLandmark(TransformFrom(P_s, m.landmark(i), &J_frame, &J_point));
      ++counters_.new_landmarks;
      // Its marginal given the data before this join and its own feature alone — the
      // start anchor's marginal carried through the feature — bounds its marginal given
      // everything (in the linearised model, more data never widens a marginal).
      const Eigen::Matrix2d Q = m.covariance.block<2, 2>(3 + 2 * i, 3 + 2 * i);
      marginal_bound_.push_back(J_frame * start_covariance * J_frame.transpose() + J_point * Q * J_point.transpose());
    }
  }
  return end_anchor;
}

bool EifJoiner::Impl::RelinearizationDue() {
  bool relinearize = false;
  if (options_.relinearize_every > 0 && counters_.joins % options_.relinearize_every == 0) {
    relinearize = true;
  } else if (options_.relinearize_heading_change > 0 && MaxHeadingDrift() > options_.relinearize_heading_change) {
    ++counters_.relinearized_on_heading;
    relinearize = true;
  } else if (options_.relinearize_linearization_chi2 > 0) {
    StageTimer timer(&times_, "linearization_check");
    relinearize = LinearizationErrorAbove(options_.relinearize_linearization_chi2);
    linearization_watch_.MarkTested(estimate_.dim);
    if (relinearize) ++counters_.relinearized_on_linearization_error;
  }
  return relinearize;
}

absl::Status EifJoiner::Impl::JoinWith(const LocalSubmap& s, bool associate) {
  const int start = estimate_.graph.num_anchors() - 1;
  std::vector<int> assoc(s.num_landmarks(), -1);
  // The start anchor's marginal before this join (NaN without one: no bounds then).
  Eigen::Matrix3d start_covariance = Eigen::Matrix3d::Constant(NAN);
  std::optional<LocalSubmap> rotated_back;
  association::SubmapAssociation fit;  // the rotation test's fit alone (its association may be moved on)
  if (associate) {
    const JoinerCounters counters_before = counters_;  // a pending closure's snapshot keeps these
    association::SubmapAssociation a;
    if (replayed_association_) {
      // Joined again after its loop closure went unconfirmed, from the state it was
      // first associated in: that association, not a second search to the same result.
      a = *std::move(replayed_association_);
      replayed_association_.reset();
      CountDecisions(a);
      ++counters_.associations_replayed;
    } else {
      a = AssociateAt(s, start);
    }
    fit.map_rotation_fit_rad = a.map_rotation_fit_rad;
    fit.map_rotation_fit_variance_rad2 = a.map_rotation_fit_variance_rad2;
    assoc = a.landmark_of_feature;
    start_covariance = a.start_anchor_covariance;
    rotated_back = association::RotatedBack(s, a);  // a map the rotation test found rotated
    GateLoopPairings(std::move(a), counters_before, &assoc);
  }
  LocalSubmap m = rotated_back ? *rotated_back : s;  // the map joined
  if (m.rotation_spread_rad > 0) ++counters_.maps_spread;
  // After the snapshot a held loop closure takes, so that its undo and replay record the
  // closing map's fit once.
  if (associate) {
    association::StampRotationFit(fit, &m);
    associator_.RecordRotationFit(m);
  }
  const int first_new_landmark = estimate_.graph.num_landmarks();
  const int end_anchor = AddEndAnchorAndLandmarks(m, start, start_covariance, &assoc);
  // A rejected map joined again (associate false) must not redefine its landmarks.
  associator_.Record(m, assoc, first_new_landmark, /*define_truth=*/associate);
  touched_.resize(estimate_.graph.num_landmarks(), 1);
  for (int j : assoc) touched_[j] = 1;
  estimate_.graph.AddFactor({std::move(m), start, end_anchor, assoc});
  EifFactor f = EifFactor::Make(estimate_, static_cast<int>(estimate_.graph.factors().size()) - 1,
                                /*screened=*/options_.relinearize_linearization_chi2 > 0);
  {
    StageTimer timer(&times_, "update");
    f.Linearize(estimate_, &solver_.last_whitened_jacobian);
  }
  factors_.push_back(std::move(f));
  last_association_ = assoc;
  last_t_end_ = s.t_end;
  ++counters_.joins;
  if (absl::Status st = Rebuild(/*only_last_factor=*/true); !st.ok()) return st;
  const bool relinearize = RelinearizationDue();
  if (relinearize) {
    if (absl::Status st = Relinearize(); !st.ok()) return st;
  }
  const int every = options_.revision.every_joins;
  if (associate && (relinearize || (every > 0 && counters_.joins % every == 0))) {
    relinearized_since_revision_ = relinearize;
    return ReviseAssociation(/*full=*/false);
  }
  return absl::OkStatus();
}

absl::Status EifJoiner::Impl::Finish() {
  // A closure under a lost anchor still waiting at the end stands (no more maps to ask);
  // a thin one has not brought the pairings it lacks and is undone.
  while (pending_loop_ && pending_loop_->thin) {  // (a map joined again may hold a later one)
    if (absl::Status st = UndoPendingLoopClosure(); !st.ok()) return st;
  }
  pending_loop_.reset();
  if (!estimate_exact_ && !factors_.empty() && !(options_.relinearize_at_end)) {
    // The changes the partial recoveries left out, made good: Λx = η exactly (Gauss-Newton
    // at the end solves exactly anyway).
    if (absl::Status st = Rebuild(/*only_last_factor=*/false); !st.ok()) return st;
  }
  // No association follows: the marginal bounds are not refreshed. An estimate already
  // converged (a tree's last join iterates to convergence) is not iterated again.
  if (options_.relinearize_at_end && !factors_.empty() && !converged_) {
    if (absl::Status st = GaussNewton(); !st.ok()) return st;
  }
  return absl::OkStatus();
}

absl::Status EifJoiner::Impl::JoinMap(const EifJoiner& right_joiner) {
  const Impl& right = *right_joiner.impl_;
  if (right.estimate_.graph.factors().empty()) return absl::OkStatus();
  // A loop closure still waiting for confirmation stands: once whole maps are joined the
  // maps after it are no longer a sequence to replay (and right's own is right's).
  pending_loop_.reset();
  // Association by truth ids reads no covariance: the joint marginal is not recovered.
  absl::StatusOr<LocalSubmap> summary =
      SummarizeForJoin(right_joiner, last_t_end_, /*with_covariance=*/!options_.association.known_association);
  if (!summary.ok()) return summary.status();
  const int start = estimate_.graph.num_anchors() - 1;
  const int n = right.estimate_.graph.num_landmarks();
  std::vector<int> assoc(n, -1);
  if (!estimate_.graph.factors().empty()) {
    const std::vector<std::vector<int>> groups = association::WholeMapGroups(right.estimate_.graph);
    assoc = AssociateAt(*summary, start, &groups).landmark_of_feature;
  }
  // Right's anchors and unmatched landmarks, through the last anchor (headings continuous).
  const Pose2 P_s(estimate_.graph.anchors()[start].x, estimate_.graph.anchors()[start].y,
                  estimate_.anchor_theta[start]);
  std::vector<int> anchor_map = {start};
  for (int k = 1; k < right.estimate_.graph.num_anchors(); ++k) {
    const Pose2& a = right.estimate_.graph.anchors()[k];
    const Pose2 local(a.x, a.y, right.estimate_.anchor_theta[k]);
    const Pose2 p = Compose(P_s, local);
    anchor_map.push_back(estimate_.AddAnchor(p, P_s.theta + local.theta));
  }
  const int first_new_landmark = estimate_.graph.num_landmarks();
  long matched = 0;
  for (int l = 0; l < n; ++l) {
    if (assoc[l] >= 0) {
      ++matched;
      continue;
    }
    assoc[l] = estimate_.AddLandmark(TransformFrom(P_s, right.estimate_.graph.landmarks()[l]));
  }
  {
    StageTimer timer(&times_, "update");
    for (const EifFactor& right_factor : right.factors_) {
      const SubmapFactor& f = right.estimate_.graph.factors()[right_factor.index];
      std::vector<int> landmarks;
      for (int l : f.landmark_of_feature) landmarks.push_back(assoc[l]);
      estimate_.graph.AddFactor({f.submap, anchor_map[f.start_anchor], anchor_map[f.end_anchor], landmarks});
      // The local map's own terms (its covariance's factor, information and smallest
      // eigenvalue) carry over; the layout and linearisation are this map's.
      EifFactor factor =
          EifFactor::WithTermsOf(right_factor, estimate_, static_cast<int>(estimate_.graph.factors().size()) - 1);
      factor.Linearize(estimate_);
      factors_.push_back(std::move(factor));
    }
  }
  associator_.Record(*summary, assoc, first_new_landmark, /*define_truth=*/true);
  last_association_.clear();
  for (int l : right.last_association_) last_association_.push_back(assoc[l]);
  counters_ += right.counters_;  // its joins, then this join's merges
  counters_.associated += matched;
  counters_.new_landmarks -= matched;
  for (const auto& [stage, seconds] : right.times_) times_[stage] += seconds;
  last_t_end_ = right.last_t_end_;
  // Right's factors were linearised at an estimate made without this map's information:
  // after a long right map, one step is far from the joint optimum (on combined-2km the
  // tree's anchors were 74 m off, NEES 3,800), so a tree join is iterated to convergence.
  // Its first iteration linearises every factor at the joined estimate and solves (Λ is
  // factorised there first).
  if (absl::Status st = Relinearize(); !st.ok()) return st;
  return ReviseAssociation(/*full=*/true);
}

// The public interface: each call handed to the implementation (eif_joiner_impl.h).

EifJoiner::EifJoiner(const Pose2& initial_pose, const EifJoinerOptions& options)
    : impl_(std::make_unique<Impl>(initial_pose, options)) {}
EifJoiner::~EifJoiner() = default;
EifJoiner::EifJoiner(const EifJoiner& other) = default;

EifJoiner::ImplHolder::ImplHolder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
EifJoiner::ImplHolder::ImplHolder(const ImplHolder& other) : impl_(std::make_unique<Impl>(*other)) {}
EifJoiner::ImplHolder::~ImplHolder() = default;

void EifJoiner::RecordInnovation() {
  RecordAssociationInnovation(impl_->innovation_d2_, impl_->innovation_dof_);
  impl_->innovation_d2_ = 0.0;
  impl_->innovation_dof_ = 0;
}

absl::Status EifJoiner::JoinLocalMap(const LocalSubmap& submap) {
  const absl::Status status = impl_->JoinLocalMap(submap);
  RecordInnovation();
  return status;
}

absl::Status EifJoiner::JoinMap(const MapJoiner& right) {
  const auto* eif = dynamic_cast<const EifJoiner*>(&right);
  if (eif == nullptr) return absl::InvalidArgumentError("EIF JoinMap: the right map is not an EIF map");
  const absl::Status status = impl_->JoinMap(*eif);
  RecordInnovation();
  return status;
}

absl::Status EifJoiner::Finish() {
  const absl::Status status = impl_->Finish();  // (a thin closure undone there associates again)
  RecordInnovation();
  if (!status.ok()) return status;
  // Revise at the converged estimate (each pass that changes something solves again).
  return ReviseUntilSettled(*this);
}

std::unique_ptr<MapJoiner> EifJoiner::NewEmpty(const Pose2& initial_pose) const {
  return std::make_unique<EifJoiner>(initial_pose, impl_->options_);
}
std::unique_ptr<MapJoiner> EifJoiner::Clone() const { return std::unique_ptr<MapJoiner>(new EifJoiner(*this)); }

absl::Status EifJoiner::AdoptEstimate(const SubmapGraph& solved) { return impl_->AdoptEstimate(solved); }
absl::Status EifJoiner::ReviseAssociation(bool full) { return impl_->ReviseAssociation(full); }
absl::Status EifJoiner::MergeLandmarks(int keep, int drop) { return impl_->MergeLandmarks(keep, drop); }
absl::Status EifJoiner::SplitFeature(int factor, int feature) { return impl_->SplitFeature(factor, feature); }
double EifJoiner::MaxLinearizationError() const { return impl_->MaxLinearizationError(); }
double EifJoiner::Cost() const { return impl_->Cost(); }
const SubmapGraph& EifJoiner::graph() const { return impl_->estimate_.graph; }
Pose2 EifJoiner::LastAnchor() const { return impl_->LastAnchor(); }
Eigen::Matrix3d EifJoiner::LastAnchorCovariance() const { return impl_->LastAnchorCovariance(); }
Eigen::MatrixXd EifJoiner::JointCovariance(const std::vector<int>& anchors, const std::vector<int>& landmarks) const {
  return impl_->JointCovariance(anchors, landmarks);
}
std::vector<Eigen::Matrix3d> EifJoiner::AnchorCovariances() const { return impl_->AnchorCovariances(); }
std::vector<Eigen::Matrix2d> EifJoiner::LandmarkCovariances() const { return impl_->LandmarkCovariances(); }
std::vector<association::Matrix5d> EifJoiner::AnchorLandmarkCovariances(int anchor,
                                                                        const std::vector<int>& landmarks) const {
  return impl_->AnchorLandmarkCovariances(anchor, landmarks);
}
Eigen::Matrix4d EifJoiner::LandmarkPairCovariance(int a, int b, std::vector<Eigen::Matrix2d>* own) const {
  return impl_->LandmarkPairCovariance(a, b, own);
}
std::vector<std::optional<association::Matrix5d>> EifJoiner::AnchorLandmarkBounds(
    int anchor, const std::vector<int>& landmarks) const {
  return impl_->AnchorLandmarkBounds(anchor, landmarks);
}
const std::vector<int>& EifJoiner::last_association() const { return impl_->last_association_; }
const std::vector<int>& EifJoiner::rejected() const { return impl_->rejected_; }
const Eigen::SparseMatrix<double>& EifJoiner::information() const { return impl_->information(); }
int EifJoiner::state_dimension() const { return impl_->estimate_.dim; }
long EifJoiner::factor_nonzeros() const { return impl_->factor_nonzeros(); }
FillReducingOrdering EifJoiner::factor_ordering() const { return impl_->factor_ordering(); }
int EifJoiner::anchor_offset(int k) const { return impl_->estimate_.anchor_offset[k]; }
int EifJoiner::landmark_offset(int j) const { return impl_->estimate_.landmark_offset[j]; }
std::map<std::string, double> EifJoiner::stage_times() const { return impl_->times_; }
const JoinerCounters& EifJoiner::counters() const { return impl_->counters_; }
const association::SubmapAssociator& EifJoiner::associator() const { return impl_->associator_; }

}  // namespace subslam::backend
