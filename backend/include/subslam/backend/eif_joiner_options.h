// The options of the incremental EIF joiner (eif_joiner.h): association, its revision,
// relinearisation, the factor's ordering and refactorisation policy, loop closures held
// for confirmation. Each field says what it does and its default.
#ifndef SUBSLAM_BACKEND_EIF_JOINER_OPTIONS_H_
#define SUBSLAM_BACKEND_EIF_JOINER_OPTIONS_H_

#include "absl/status/status.h"
#include "subslam/association/landmark_revision.h"
#include "subslam/association/submap_association.h"
#include "subslam/backend/fill_reducing_ordering.h"

namespace subslam::backend {

struct EifJoinerOptions {
  association::SubmapAssociationOptions association;
  // Revisable association: landmark merges and feature splits (landmark_revision.h),
  // tested after each relinearisation that follows a join, every revision.every_joins
  // joins, after a whole-map join and at the end; each applied change re-keys the
  // factors and solves again (Gauss-Newton where the joiner relinearises). Not while a
  // loop closure waits for confirmation, nor under known association.
  association::LandmarkRevisionOptions revision;
  // Join validation (beyond the papers): after the update, the new factor's normalised
  // residual rᵀQ⁻¹r at the new estimate is tested against χ²_{2m}(validation_probability),
  // m the features matched to existing landmarks; a join that fails is undone and the
  // local map joined again without associations (its odometry still links the chain),
  // counted and its id reported. Off by default: the residual of a single linearisation
  // after a large correction also rejects correct loop-closing joins.
  bool validate_joins = false;
  double validation_probability = 0.999;
  // Loop-closure confirmation: association.loop_confirmation_maps and confirm_thin_loops
  // (submap_association.h). The sequential EIF undoes an unconfirmed closure's joins and
  // joins the maps again (one under a lost anchor still waiting at Finish() or at a
  // whole-map join stands, a thin one is undone). Confirmation needs the estimate after
  // the closure to be right, so it runs only while the joiner relinearises after joins
  // (RelinearizesAfterJoins()): with a single linearisation the estimate after a
  // correction of a hundred metres is too far off for the next maps to find the old map,
  // and correct closures would be undone. While a closure waits, the online
  // anchor (LastAnchor) does not carry it: a decision not yet taken must not move the pose
  // a navigation stack reads, nor shrink its covariance (a thin closure by a chance fit
  // would put it metres off with centimetres of σ).
  // Relinearisation.
  int relinearize_every = 0;  // every K joins (0: not on a schedule)
  // At Finish(): Gauss-Newton to convergence, so that the final anchors and map are the
  // optimum for the associations made. Between relinearisations the factors stay
  // linearised where each join left them, and over a long run the final anchors are
  // over-confident without it, for a few Gauss-Newton iterations with it
  // (docs/design/eif.md). The Ceres back-end turns it off (Ceres solves there).
  bool relinearize_at_end = true;
  // A relinearisation's Gauss-Newton iterations stop when the last step Δx is small
  // either way: max |Δx| below `relinearize_tolerance` (m, rad), or ΔxᵀΛΔx below
  // `relinearize_step_chi2` (0: off), Λ the information of the linearisation that gave the
  // step — its length in units of the estimate's own uncertainty (χ² units; it is the
  // decrease of Cost() that the step predicts). The second test is ISEIF's adaptive stop
  // (ISEIF §2.3) with the Mahalanobis distance between iterates: Gauss-Newton
  // converges linearly here (each step a fixed fraction of the last), and millimetre
  // steps of landmarks known to a metre are not worth another iteration.
  double relinearize_tolerance = 1e-3;
  double relinearize_step_chi2 = 1e-3;
  int max_relinearizations = 20;
  // Before each Gauss-Newton iteration after the first, predict its step without
  // factorising: relinearise, and solve for the step with the factor of the previous
  // linearisation, a step away (the factor is nonlinear only through the headings, which
  // that step moved by a few mrad). When that step is below half
  // `relinearize_tolerance` or a quarter of `relinearize_step_chi2` (the steps still to
  // come sum to less than twice it), Gauss-Newton stops there and keeps the previous
  // linearisation, whose solution the estimate is; counter
  // relinearizations_predicted_converged. It trades the last, confirming iteration's
  // factorisation for one solve and two passes over the factors per iteration; a
  // prediction that does not stop costs only those.
  bool predict_convergence = true;
  // Relinearise after a join when some factor's linear model is off, at the current
  // estimate, by more than its own noise: ‖L_Q⁻¹ (h(x) − h(x₀) − J(x₀)(x − x₀))‖² above
  // this (χ² units; x₀ the factor's linearisation point, Q = L Lᵀ its local map's
  // covariance; MaxLinearizationError()); 0: off. After a relinearisation stopped at its
  // best iterate or at max_relinearizations (or on a predicted step) the error can stay
  // above the threshold, and the next joins relinearise again, which carries
  // Gauss-Newton on. It is the default rather than the heading trigger below: it measures
  // what matters — how far the linear model is off, in the factor's own noise — where a
  // small turn under long levers can leave a linear model far off without any heading
  // moving much (docs/design/eif.md).
  double relinearize_linearization_chi2 = 1.0;
  // Also relinearise after a join when an anchor's heading has moved this far [rad] from
  // where one of its factors was linearised (the submap factor is nonlinear in the
  // headings only); 0: off (by default the linearisation-error trigger above covers it).
  double relinearize_heading_change = 0.0;
  // Gauss-Newton may raise the cost once on its way to a lower minimum, but this many
  // rises in a row end a relinearisation at its best iterate (counter
  // relinearizations_diverged); 1 is monotone Gauss-Newton, 0 never stops on the cost.
  int divergence_rises = 2;
  // State recovery after an incremental update (beyond the papers): instead of solving
  // Λx = η afresh, the change the new factor makes is carried from its variables — a
  // forward solve along the elimination-tree paths from them (exact), then a back
  // substitution that goes down the tree only while the change exceeds this [m, rad]
  // (SparseCholesky::SolveChange; iSAM2's partial state update). A join that extends the
  // map moves nothing far behind it, so the join costs about its own size instead of the
  // whole map's; only the factors on moved variables are tested by the relinearisation
  // trigger. The changes left out are each below this; they are made good by the exact
  // solves: at every full factorisation and relinearisation, at Finish(), and at the
  // guarded joins (below). 0: every join solves Λx = η afresh and the trigger tests every
  // factor.
  // The guard on the updated factor (Λx = η, or refactorise) runs after the 1st, 2nd,
  // 4th, … update since the last full factorisation, with an exact solve: a broken update
  // (CHOLMOD's rank update keeps a positive definite factor, so this is a belt-and-braces
  // check) is still caught while the factor lives, at O(N log N) in all instead of O(N)
  // per join.
  double recovery_change_threshold = 1e-9;
  // Factorisation: each join updates the sparse LDLᵀ factor of Λ by the new factor's
  // rank-(3+2n) update (CHOLMOD update/downdate; new variables last in the ordering)
  // instead of refactorising Λ; a full factorisation (with a fresh ordering) is done
  // when the spare slots run out, when L's fill has grown by `refactorize_fill_ratio`
  // since the last one, at every relinearisation, or if an update fails. Off, every join
  // refactorises, with neither spare slots nor the last anchor ordered last (ForTreeNode).
  bool incremental_factorization = true;
  double refactorize_fill_ratio = 1.5;
  // The fill-reducing ordering of a full factorisation (fill_reducing_ordering.h). The
  // default takes METIS nested dissection where AMD's factor is costly: on maps revisited
  // at random its balanced elimination tree makes the factor sparser and the joins'
  // updates cheaper; where AMD's factor is cheap (a long loop) it stays.
  FillReducingOrdering ordering = FillReducingOrdering::kAmdOrNestedDissection;
  // Association's covariance recovery: drop the candidates that fail individual
  // compatibility even under an upper bound on their [start anchor, landmark] marginal,
  // before recovering theirs (submap_association.h, step 2). The bound keeps the exact
  // anchor block and cross-covariance (the anchor's three columns of Λ⁻¹ on the candidates' rows)
  // and bounds the landmark's own block by its marginal when it was last recovered, or,
  // for a landmark never recovered, by its marginal from the start anchor's and its
  // feature's covariances when it was created. Both stay upper bounds while Λ only grows,
  // so they are dropped whenever the factors are relinearised; a relinearisation after a
  // join then sets them to every landmark's exact marginal at the new linearisation, all
  // at once (the sparse-inverse recursion).
  // Association decisions are the same either way (tested); only the work differs.
  bool bound_candidate_marginals = true;

  absl::Status Validate() const;
  // Whether a trigger relinearises after joins (relinearize_linearization_chi2 or
  // relinearize_heading_change > 0).
  bool RelinearizesAfterJoins() const;
  // These options with every relinearisation off (both triggers, the schedule and the
  // one at the end) and no association revision (it relinearises every factor): the
  // single-linearisation EIF of Combined SLAM.
  EifJoinerOptions SingleLinearization() const;
  // These options for a node of a binary tree (backend/tree_joiner.h): a node is one
  // local map, or two nodes joined and relinearised whole, never a rank update of its
  // factor, so it keeps no spare slots and no constrained ordering
  // (incremental_factorization off).
  EifJoinerOptions ForTreeNode() const;
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_EIF_JOINER_OPTIONS_H_
