// The incremental, exactly sparse extended information filter that joins local maps
// into the global map (Combined SLAM §5; docs/conventions.md, "The submap factor").
//
// State: the anchors P1 … Pk (P0, the initial pose, is fixed and not a variable) and the
// global landmarks, in the order they were created. Each local map adds one factor,
// linearised at the current estimate x̂_f:
//   Λ += Jᵀ Q⁻¹ J,   η += Jᵀ Q⁻¹ (J x̂_f − r(x̂_f)),     r = h(x̂_f) ⊖ z,
// so Λ stays exactly sparse (a factor touches its two anchors and its landmarks; nothing
// is marginalised). Λ's sparse LDLᵀ factor (CHOLMOD, simplicial) is kept up to date
// incrementally: each join is a rank-(3+2n) update of the factor (cholmod_updown), its
// new variables taking spare slots kept last in the fill-reducing ordering (AMD, or METIS
// nested dissection where AMD's factor gets costly: `ordering`); a full
// factorisation with a fresh ordering happens when the slots run out or the fill has
// grown, and at every relinearisation (whose Gauss-Newton iterations after the first
// refactorise the same pattern: the symbolic analysis and Λ's pattern are reused). The
// estimate is Λ⁻¹η by one solve, checked by its residual (an update that fails the check
// is replaced by a full factorisation).
// Headings are kept continuous in the state (never wrapped between linearisations) so
// every stored linear model stays valid; they are wrapped in the outputs.
//
// Per local map, in order (Combined SLAM, Algorithm 1):
//  1. data association (backend/submap_association.h), with the marginal covariances it
//     needs — [start anchor, candidate] blocks for individual compatibility, the joint of
//     the start anchor and the compatible candidates for JCBB — recovered from the factor
//     by forward solves limited to each column's reach (never the dense inverse);
//  2. the end anchor and the new landmarks are initialised through the start anchor;
//  3. the information update above;
//  4. state recovery by one solve.
// Relinearisation (ISEIF's adaptive stop, ISEIF §2.3): rebuild every factor at the
// current estimate and re-solve while the step exceeds `relinearize_tolerance` or its χ²
// length exceeds `relinearize_step_chi2` (or, with `predict_convergence`, until the next
// step, solved with the factor at hand, is below them) — after a join that left a
// factor's linear model more than its noise off (`relinearize_linearization_chi2`, on by
// default) or moved an anchor's heading `relinearize_heading_change` from a factor's
// linearisation (off by default), every `relinearize_every` joins and/or at Finish() (on
// by default); iterated to convergence this is Gauss-Newton over the submap graph. Without the
// triggers and the relinearisation at the end (all 0 / false: SingleLinearization()) it
// is the single-linearisation EIF of Combined SLAM.
// Time per stage (association, covariance recovery — association's, plus the marginal
// bounds recomputed after a relinearisation —, update, factorisation — of which
// full_factorization —, recovery, recovery_check, and linearization_check, the
// relinearisation trigger's test) is accumulated as in Table 1 of Combined SLAM.
// Not thread-safe.
#ifndef SUBSLAM_BACKEND_EIF_JOINER_H_
#define SUBSLAM_BACKEND_EIF_JOINER_H_

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/backend/eif_joiner_options.h"
#include "subslam/backend/landmark_revision.h"
#include "subslam/backend/map_joiner.h"
#include "subslam/backend/relative_covariance_bounds.h"
#include "subslam/backend/submap_association.h"
#include "subslam/graph/local_submap.h"
#include "subslam/graph/submap_graph.h"

namespace subslam::backend {

struct SparseLowerTriangle;  // backend/internal/sparse_cholesky.h

class EifJoiner final : public MapJoiner {
 public:
  EifJoiner(const Pose2& initial_pose, const EifJoinerOptions& options);
  ~EifJoiner();

  // Relinearises to convergence if relinearize_at_end.
  absl::Status Finish() override;
  std::string Name() const override { return "eif"; }
  // Takes the anchors and landmarks of `solved` (the same graph, optimised elsewhere —
  // e.g. by Ceres) as the estimate, relinearises every factor there and re-solves, so the
  // information form and the marginals follow the better estimate.
  absl::Status AdoptEstimate(const SubmapGraph& solved);

  // Revisable association (MapJoiner, landmark_revision.h). A full pass (at the end,
  // after a whole-map join, and when asked for) runs the split test and the merge test
  // on every pair; a pass during the run (after a relinearisation, and every
  // revision.every_joins joins) the merge test on the pairs with a landmark that a join
  // touched since the last pass, and the split test after a relinearisation.
  absl::Status ReviseAssociation() override { return ReviseAssociation(/*full=*/true); }
  absl::Status ReviseAssociation(bool full);
  absl::Status MergeLandmarks(int keep, int drop) override;
  absl::Status SplitFeature(int factor, int feature) override;

  // The largest whitened linearisation error of a factor at the current estimate,
  // ‖L_Q⁻¹ (r(x) − r(x₀) − J(x₀)(x − x₀))‖² over the factors, x₀ a factor's
  // linearisation point and Q = L Lᵀ its local map's covariance: how far the information
  // form's linear model is from the estimate it holds (what
  // relinearize_linearization_chi2 tests; after Gauss-Newton, the error of its last
  // linearisation at the final iterate: small once it has converged).
  double MaxLinearizationError() const;

  const SubmapGraph& graph() const override { return graph_; }
  // The last anchor; while a loop closure waits for confirmation, the start anchor of its
  // map as estimated before it (and that anchor's marginal), composed with the end poses
  // of the local maps joined since (first order, their end-pose covariances): the
  // estimate without the closure, to first order, less what those maps share with the
  // maps before them (conservative).
  Pose2 LastAnchor() const override;
  Eigen::Matrix3d LastAnchorCovariance() const override;
  // Marginal covariances by sparse solves with the factor.
  Eigen::MatrixXd JointCovariance(const std::vector<int>& anchors, const std::vector<int>& landmarks) const override;
  // All marginals from Λ⁻¹ on the factor's pattern (one sparse-inverse recursion).
  std::vector<Eigen::Matrix3d> AnchorCovariances() const override;
  std::vector<Eigen::Matrix2d> LandmarkCovariances() const override;
  // For each landmark, the 5 × 5 marginal of [anchor, landmark] (what individual
  // compatibility needs), without the landmarks' cross-covariances.
  std::vector<Matrix5d> AnchorLandmarkCovariances(int anchor, const std::vector<int>& landmarks) const;
  // The joint marginal of landmarks a and b (a's rows first), entry by entry as
  // JointCovariance({}, {a, b}) gives it, each landmark's own block taken from `own` (NaN:
  // recovered now and kept there), so that a merge pass pays each pair's cross terms only.
  Eigen::Matrix4d LandmarkPairCovariance(int a, int b, std::vector<Eigen::Matrix2d>* own) const;
  // For each landmark, an upper bound on that 5 × 5 marginal: the exact anchor block and
  // cross-covariance (one solve for the anchor's columns) with the landmark's block
  // replaced by its marginal bound (see bound_candidate_marginals); nullopt for a
  // landmark without one.
  std::vector<std::optional<Matrix5d>> AnchorLandmarkBounds(int anchor, const std::vector<int>& landmarks) const;
  const std::vector<int>& last_association() const override { return last_association_; }
  // The nonlinear least-squares cost Σ_f r_fᵀ Q_f⁻¹ r_f of every local map's factor at
  // the current estimate (whitened, dimensionless).
  double Cost() const;
  // Ids of the local maps whose association failed validation.
  const std::vector<int>& rejected() const { return rejected_; }
  // The information matrix and vector (for tests and tools).
  // Assembled on demand from the factors (a join updates only the factor of Λ and η).
  const Eigen::SparseMatrix<double>& information() const;
  int state_dimension() const { return dim_; }
  // Entries of the sparse LDLᵀ factor of Λ (its fill; 0 before the first join).
  long factor_nonzeros() const;
  // The ordering of that factor's last full factorisation (kAmd or kNestedDissection).
  FillReducingOrdering factor_ordering() const;
  // Where a variable sits in Λ and η (−1 for the fixed P0).
  int anchor_offset(int k) const { return anchor_offset_[k]; }
  int landmark_offset(int j) const { return landmark_offset_[j]; }
  std::map<std::string, double> stage_times() const override { return times_; }
  const JoinerCounters& counters() const override { return counters_; }
  const SubmapAssociator& associator() const override { return associator_; }
  // Tree joining: `right` (an EifJoiner) is associated with this map, its anchors and new
  // landmarks are brought into this frame through the last anchor, its factors are
  // relinearised there and added, and Gauss-Newton is iterated from the merged estimate
  // to convergence (relinearize_tolerance, max_relinearizations): a whole map's factors
  // were linearised without this map's information, so one step is not enough.
  std::unique_ptr<MapJoiner> NewEmpty(const Pose2& initial_pose) const override;
  std::unique_ptr<MapJoiner> Clone() const override;
  absl::Status JoinMap(const MapJoiner& right) override;

 protected:
  // Joins the next local map (its start anchor is the last anchor). Errors: an invalid
  // local map, a start time before the previous end, or a numerically failed factorisation.
  absl::Status JoinLocalMap(const LocalSubmap& submap) override;

 private:
  struct Factor {
    int index = 0;                              // into graph_.factors()
    std::vector<int> offsets;                   // state offset of each variable block (−1: fixed P0)
    std::vector<int> sizes;                     // 3 or 2
    Eigen::MatrixXd H;                          // Jᵀ Q⁻¹ J over the stacked variable blocks
    Eigen::VectorXd b;                          // Jᵀ Q⁻¹ (J x̂ − r)
    double start_theta = 0.0, end_theta = 0.0;  // the anchors' headings at the linearisation
    // The levers from the start anchor to the end anchor and to each landmark at the
    // linearisation (what LinearizationError needs).
    std::vector<Eigen::Vector2d> levers;
    // rᵀ Q⁻¹ r at the linearisation point (the factor's term of Cost() there).
    double cost = 0.0;
    double covariance_min_eigenvalue = 0.0;  // of Q (set while relinearize_linearization_chi2 > 0)
    // L of the local map's covariance Q = L Lᵀ (lower triangular), which whitens the
    // factor; computed once, shared by copies.
    std::shared_ptr<const Eigen::MatrixXd> covariance_sqrt;
    // Q⁻¹, computed on the factor's first relinearisation (copies made before that compute
    // their own).
    std::shared_ptr<const Eigen::MatrixXd> information;
  };

  EifJoiner(const EifJoiner& other);  // every member copied (the factor too), for Clone()
  friend class CeresJoiner;           // whose copies copy their EIF
  // The factor record of graph factor `index`: its variables' offsets and sizes.
  Factor MakeFactor(int index) const;
  // Its variables' offsets and sizes, from the graph's factor record.
  void SetLayout(Factor* f) const;
  // The factor's linearisation error at the current estimate, whitened (see
  // MaxLinearizationError).
  double LinearizationError(const Factor& f) const;
  // Its error before whitening, e (3 + 2n; the heading row 0).
  void UnwhitenedLinearizationError(const Factor& f, Eigen::VectorXd* e) const;
  // Whether some factor's is above chi2 (most factors settled by a bound, without it):
  // every factor after an exact solve, else the factors on the variables the last
  // partial recovery moved.
  bool LinearizationErrorAbove(double chi2) const;
  // The last anchor's state rows, which a full factorisation orders last (the next join
  // starts there); none before the first join.
  std::vector<int> LastAnchorVariables() const;
  // factors_of_row_ from every factor, when not valid.
  void EnsureFactorsOfRow() const;
  // The headings and levers of the factor's linearisation at (start, end) and the
  // current landmarks.
  void RecordLinearizationPoint(Factor* f, const Pose2& start, const Pose2& end) const;
  // H and b of the factor at the current estimate, and (if asked) its whitened Jacobian
  // L_Q⁻¹ J, the newest factor's rank update of the incremental factor.
  void Linearize(Factor* f, Eigen::MatrixXd* whitened_jacobian = nullptr) const;
  // The same H and b from the Jacobian's block structure and Q⁻¹ (no whitening).
  void LinearizeStructured(Factor* f) const;
  // visit(row, col, value) for each entry of the factor's H, at its place in the state.
  template <typename Visit>
  static void ForEachEntry(const Factor& f, Visit visit);
  // Adds a factor's b to η, or H_f x_f to y.
  void AddToEta(const Factor& f, Eigen::VectorXd* eta) const;
  void AddInformationTimes(const Factor& f, const Eigen::VectorXd& x, Eigen::VectorXd* y) const;
  // xᵀΛx over the factors' current H (Λ need not be assembled).
  double InformationNorm(const Eigen::VectorXd& x) const;
  // Λ, η from every factor (or only the newest, added to the existing ones); factorise;
  // solve; write the estimate back.
  absl::Status Rebuild(bool only_last_factor);
  // After an incremental update of the factor: the estimate carried over the newest factor
  // by a partial solve (the rows it moves by more than recovery_change_threshold), the
  // variables added since `old_dim` starting at 0.
  absl::Status RecoverAcrossNewestFactor(Eigen::Index old_dim);
  // Factorises Λ afresh (the symbolic analysis reused while Λ's pattern is unchanged),
  // with spare slots for the next joins' new variables; counted.
  absl::Status FullFactorization();
  // The factorisation itself: with incremental_factorization, spare slots and the last
  // anchor ordered last (for the rank updates of the next joins); without, neither.
  absl::Status FactorizeLambda();
  // Λ's lower triangle (its pattern, values left unset) and lambda_slots_ from the
  // factors' variable blocks.
  void BuildLambdaPattern() const;
  // Λ's lower triangle, assembled from the factors as needed (what a full factorisation
  // takes).
  const SparseLowerTriangle& LowerInformation() const;
  // values = Σ over factors from first_factor on of their H entries in the lower
  // triangle, at their slots (lambda_slots_ must be this pattern's).
  void FillLambdaValues(size_t first_factor, std::vector<double>* values) const;
  // The variable offsets of every factor, concatenated (what Λ's pattern depends on).
  std::vector<int> FactorOffsets() const;
  // Gauss-Newton over every factor from the current estimate, until a step (taken, or
  // predicted with predict_convergence) is below relinearize_tolerance or
  // relinearize_step_chi2, or max_relinearizations; stopped at the best iterate after
  // divergence_rises cost rises in a row.
  // Gauss-Newton to convergence (GaussNewton), then the marginal bounds from the new
  // factor for the joins that follow.
  absl::Status Relinearize();
  absl::Status GaussNewton();
  // A factor's linearisation (H, b, the headings and levers it was taken at: every
  // Factor field Linearize sets), set aside while Gauss-Newton tries the next one.
  struct Linearization {
    Eigen::MatrixXd H;
    Eigen::VectorXd b;
    double start_theta = 0.0, end_theta = 0.0;
    std::vector<Eigen::Vector2d> levers;
    double cost = 0.0;
  };
  static void SwapLinearization(Factor* f, Linearization* l);
  // With the factors linearised at the estimate x, and the factor (and x) still of the
  // previous linearisation: whether the Gauss-Newton step from x, solved with that factor,
  // is below the stopping thresholds (see predict_convergence).
  bool PredictedStepConverged(const Eigen::VectorXd& x);
  // One factor's term of Cost().
  double NormalizedResidual(const Factor& f) const;
  // max over factors of |heading now − heading at the factor's linearisation| of its anchors.
  double MaxHeadingDrift() const;
  // Anchor k with its continuous (unwrapped) heading; a factor's landmarks, in its order.
  Pose2 AnchorPose(int k) const;
  std::vector<Eigen::Vector2d> FactorLandmarks(const SubmapFactor& record) const;
  absl::Status JoinWith(const LocalSubmap& submap, bool associate);
  // Adds the end anchor of map `m` (returned) and its new landmarks (features `assoc`
  // leaves at −1, which it sets), initialised through the start anchor, with each new
  // landmark's marginal bound from the start anchor's marginal before the join (NaN: none).
  int AddEndAnchorAndLandmarks(const LocalSubmap& m, int start, const Eigen::Matrix3d& start_covariance,
                               std::vector<int>* assoc);
  // Whether the join just made calls for relinearisation (EifJoinerOptions::relinearize_*).
  bool RelinearizationDue();
  // Applies splits (landmarks appended) then merges (in `drop` descending order) to the
  // graph, the associator and the state layout, relinearises every factor at the
  // current estimate and solves again (to convergence where the joiner relinearises).
  absl::Status ApplyRevisions(const std::vector<FeatureSplit>& splits, const std::vector<LandmarkMerge>& merges);
  // For each landmark, the 5 × 5 marginal of [anchor, landmark] where a factor couples
  // the two (read off the sparse inverse on the factor's pattern).
  std::vector<Matrix5d> FactorMarginals(int anchor, const std::vector<int>& landmarks) const;
  // Association of `s` (starting at anchor `start`) with the map, timed and counted: a
  // local map, or with `whole_map_groups` a whole map's summary (SubmapAssociator::Associate).
  SubmapAssociation AssociateAt(const LocalSubmap& s, int start,
                                const std::vector<std::vector<int>>* whole_map_groups = nullptr);
  Eigen::VectorXd StateVector() const;
  void SetState(const Eigen::VectorXd& x);
  // The same for the listed state rows only (the rest already hold x).
  void SetStateRows(const Eigen::VectorXd& x, const std::vector<int>& rows);

  EifJoinerOptions options_;
  SubmapGraph graph_;
  std::vector<int> anchor_offset_;  // −1 for P0
  std::vector<int> landmark_offset_;
  std::vector<double> anchor_theta_;  // continuous (unwrapped) headings
  int dim_ = 0;
  std::vector<Factor> factors_;
  // Λ's lower triangle (Solver::lambda_lower) as the sum of the first `lambda_factors_`
  // factors' H (0: none, or relinearised since): LowerInformation() adds the newer
  // factors, or refills or assembles it again. Lambda_: both triangles, built from it
  // for information().
  mutable size_t lambda_factors_ = 0;
  mutable Eigen::SparseMatrix<double> Lambda_;
  mutable bool lambda_full_valid_ = false;
  // Where each factor's H entries (in ForEachEntry's order, factors in order) sit in the
  // lower triangle's values (−1: above the diagonal), and the factors' variable offsets
  // they were found for: while those are the same, a relinearised Λ is only refilled
  // (same pattern), not assembled again.
  mutable std::vector<int> lambda_slots_;
  mutable std::vector<int> lambda_slot_offsets_;
  Eigen::VectorXd eta_;
  // Per state row, the factors on it (valid while factors_of_row_valid_); the rows whose
  // factors the relinearisation trigger must test next: those that have moved by more than
  // kLinearizationRecheckDrift since their factors were last tested (drift_ accumulates
  // each row's changes since; changed_all_: an exact solve since the last test — test every
  // factor); incremental updates since the last full factorisation (the guard's schedule).
  // A factor's linearisation error moves by a negligible amount when its variables move
  // by less than this [m, rad] (levers of 100 m and headings 0.1 rad off their
  // linearisation change it by 10⁻⁵ m against local-map noise of centimetres and more).
  static constexpr double kLinearizationRecheckDrift = 1e-6;
  std::vector<double> drift_;
  // Per state row, its anchor k (≥ 1) or landmark j (as −j − 1); valid while
  // owner_of_row_valid_, extended as variables are added.
  mutable std::vector<int> owner_of_row_;
  mutable bool owner_of_row_valid_ = false;
  void EnsureOwnerOfRow() const;
  mutable std::vector<std::vector<int>> factors_of_row_;
  mutable bool factors_of_row_valid_ = false;
  mutable std::vector<int> candidate_stamp_;  // LinearizationErrorAbove()'s factors seen, by walk
  mutable int candidate_walks_ = 0;
  std::vector<int> changed_rows_;
  bool changed_all_ = true;
  // Whether the estimate is Λ⁻¹η exactly (no partial recovery since the last exact solve).
  bool estimate_exact_ = true;
  // Whether the estimate is a converged Gauss-Newton's (set where GaussNewton() stops on
  // its tolerances, cleared by every rebuild of Λ): Finish() then has nothing to iterate.
  bool converged_ = false;
  // After the trigger's test: the rows it covered are tested (and, after a test of every
  // factor, every row's drift starts again).
  void MarkLinearizationTested();
  long updates_since_factorization_ = 0;
  struct Solver;
  // Owns the Solver (backend/src/eif_solver.h) and copies it deeply, so that a copied
  // joiner is every member copied (Clone()).
  class SolverHolder {
   public:
    SolverHolder();
    SolverHolder(const SolverHolder& other);
    SolverHolder& operator=(const SolverHolder&) = delete;
    ~SolverHolder();
    Solver* operator->() const { return solver_.get(); }
    Solver& operator*() const { return *solver_; }

   private:
    std::unique_ptr<Solver> solver_;
  };
  SolverHolder solver_;
  SubmapAssociator associator_;
  // Per landmark, an upper bound on its marginal covariance (NaN: none); see
  // bound_candidate_marginals.
  std::vector<Eigen::Matrix2d> marginal_bound_;
  // Bounds on pairs' Cov(l_a − l_b) for the merge passes, cleared with marginal_bound_
  // and whenever a revision renumbers the landmarks.
  RelativeCovarianceBounds relative_bounds_;
  std::vector<int> last_association_;
  // Per landmark: a join gave it a feature since the last revision pass (or it is new).
  std::vector<char> touched_;
  bool relinearized_since_revision_ = false;
  std::vector<int> rejected_;
  struct Snapshot {  // what a rejected join undoes
    SubmapGraph graph;
    std::vector<int> anchor_offset, landmark_offset;
    std::vector<double> anchor_theta;
    int dim;
    std::vector<Factor> factors;
    Eigen::VectorXd eta;
    SubmapAssociator associator;
    std::vector<Eigen::Matrix2d> marginal_bound;
    JoinerCounters counters;
  };
  // A loop closure waiting for confirmation: the joiner before its map was joined (taken
  // after that map's association, with the counters from before it), the index of its
  // map's factor, the rejected_ entries then, and that map's association.
  // `needed`: distinct old landmarks it did not use that the later maps must pair for it
  // to stand (1 for a closure under a lost anchor, min_loop_pairings for a thin one).
  struct PendingLoopClosure {
    Snapshot before;
    int factor = 0;
    size_t rejected = 0;
    SubmapAssociation association;
    int needed = 1;
    int confirmations = 0;
    bool thin = false;
  };
  std::optional<PendingLoopClosure> pending_loop_;
  // LastAnchor() and LastAnchorCovariance() while a closure waits (`covariance` may be null).
  void AnchorWithoutPendingClosure(Pose2* pose, Eigen::Matrix3d* covariance) const;
  bool suppress_loop_closure_ = false;  // while joining again a map whose closure was undone
  // Set while that map is joined again: its association, reused (the joiner is restored to
  // the state it was found in).
  std::optional<SubmapAssociation> replayed_association_;
  // The decision counters of an association (truncated, thin, ambiguous).
  void CountDecisions(const SubmapAssociation& a);
  // Join() without the confirmation check (validated if validate_joins).
  absl::Status JoinOne(const LocalSubmap& s);
  Snapshot TakeSnapshot() const;
  void Restore(Snapshot snapshot);
  // After a join: confirm the pending loop closure, or undo it once its window is over.
  absl::Status CheckPendingLoopClosure();
  // Undoes the pending loop closure: back to the joiner before its map, and the maps
  // since joined again, that map without its loop pairings.
  absl::Status UndoPendingLoopClosure();
  std::map<std::string, double> times_;
  JoinerCounters counters_;
  double last_t_end_ = -1e300;
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_EIF_JOINER_H_
