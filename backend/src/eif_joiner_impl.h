// EifJoiner's implementation (private to the back-end): the state and the steps behind
// the public interface of subslam/backend/eif_joiner.h, whose comments say what each
// public function does. It sequences a join from parts with one job each
// (docs/design/eif.md, "How the EIF joiner is built"):
//   EifEstimate (eif_estimate.h)        the estimate and its rows in the state
//   EifFactor (eif_factor.h)            one local map's factor: linearisation, error, cost
//   EifInformationMatrix (eif_information_matrix.h)  Λ assembled from the factors
//   EifSolver (eif_solver.h)            the factor of Λ; eif_factorization.cc factorises,
//                                       updates and solves, eif_marginals.cc recovers marginals
//   EifLinearizationWatch (eif_linearization_watch.h)  the rows the trigger must test
// and the steps in their files:
//   eif_joiner.cc        joining a local map (association, the factor), the end of the
//                        run, whole-map (tree) joins
//   eif_gauss_newton.cc  relinearisation (the trigger, Gauss-Newton over the submap graph)
//   eif_loop_closure.cc  the loop-closure gate (snapshot, pending closure, undo)
//   eif_revision.cc      revisable association (merge and split passes)
#ifndef SUBSLAM_BACKEND_SRC_EIF_JOINER_IMPL_H_
#define SUBSLAM_BACKEND_SRC_EIF_JOINER_IMPL_H_

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "eif_estimate.h"
#include "eif_factor.h"
#include "eif_information_matrix.h"
#include "eif_linearization_watch.h"
#include "eif_solver.h"
#include "subslam/association/landmark_revision.h"
#include "subslam/association/relative_covariance_bounds.h"
#include "subslam/association/submap_association.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/eif_joiner_options.h"
#include "subslam/core/local_submap.h"
#include "subslam/core/submap_graph.h"

namespace subslam::backend {

class EifJoiner::Impl {
 public:
  Impl(const Pose2& initial_pose, const EifJoinerOptions& options);

  // What EifJoiner's functions of the same names do (eif_joiner.h). Finish() leaves the
  // revision passes until the association settles to EifJoiner; JoinLocalMap and JoinMap
  // leave recording the association's innovation to it (innovation_d2_, innovation_dof_).
  absl::Status JoinLocalMap(const LocalSubmap& submap);
  absl::Status JoinMap(const EifJoiner& right);
  absl::Status Finish();
  absl::Status AdoptEstimate(const SubmapGraph& solved);
  absl::Status ReviseAssociation(bool full);
  absl::Status MergeLandmarks(int keep, int drop);
  absl::Status SplitFeature(int factor, int feature);
  double MaxLinearizationError() const;
  double Cost() const;
  Pose2 LastAnchor() const;
  Eigen::Matrix3d LastAnchorCovariance() const;
  Eigen::MatrixXd JointCovariance(const std::vector<int>& anchors, const std::vector<int>& landmarks) const;
  Eigen::Matrix2d LandmarkCovariance(int j) const { return JointCovariance({}, {j}); }
  std::vector<Eigen::Matrix3d> AnchorCovariances() const;
  std::vector<Eigen::Matrix2d> LandmarkCovariances() const;
  std::vector<association::Matrix5d> AnchorLandmarkCovariances(int anchor, const std::vector<int>& landmarks) const;
  Eigen::Matrix4d LandmarkPairCovariance(int a, int b, std::vector<Eigen::Matrix2d>* own) const;
  std::vector<std::optional<association::Matrix5d>> AnchorLandmarkBounds(int anchor,
                                                                         const std::vector<int>& landmarks) const;
  const Eigen::SparseMatrix<double>& information() const;
  long factor_nonzeros() const;
  FillReducingOrdering factor_ordering() const;

  // The association innovation (d², dof) recorded since EifJoiner last took it.
  double innovation_d2_ = 0.0;
  long innovation_dof_ = 0;

  // Whether some factor's is above chi2 (most factors settled by a bound, without it):
  // every factor after an exact solve, else the factors on the variables the last
  // partial recovery moved.
  bool LinearizationErrorAbove(double chi2);
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
  // Gauss-Newton to convergence (GaussNewton), then the marginal bounds from the new
  // factor for the joins that follow.
  absl::Status Relinearize();
  // Gauss-Newton over every factor from the current estimate, until a step (taken, or
  // predicted with predict_convergence) is below relinearize_tolerance or
  // relinearize_step_chi2, or max_relinearizations; stopped at the best iterate after
  // divergence_rises cost rises in a row.
  absl::Status GaussNewton();
  // With the factors linearised at the estimate x, and the factor (and x) still of the
  // previous linearisation: whether the Gauss-Newton step from x, solved with that factor,
  // is below the stopping thresholds (see predict_convergence).
  bool PredictedStepConverged(const Eigen::VectorXd& x);
  // max over factors of |heading now − heading at the factor's linearisation| of its anchors.
  double MaxHeadingDrift() const;
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
  absl::Status ApplyRevisions(const std::vector<association::FeatureSplit>& splits,
                              const std::vector<association::LandmarkMerge>& merges);
  // For each landmark, the 5 × 5 marginal of [anchor, landmark] where a factor couples
  // the two (read off the sparse inverse on the factor's pattern).
  std::vector<association::Matrix5d> FactorMarginals(int anchor, const std::vector<int>& landmarks) const;
  // Association of `s` (starting at anchor `start`) with the map, timed and counted: a
  // local map, or with `whole_map_groups` a whole map's summary (association::SubmapAssociator::Associate).
  association::SubmapAssociation AssociateAt(const LocalSubmap& s, int start,
                                             const std::vector<std::vector<int>>* whole_map_groups = nullptr);

  EifJoinerOptions options_;
  EifEstimate estimate_;  // the graph, its rows in the state, the continuous headings
  std::vector<EifFactor> factors_;
  // Λ from the factors, assembled when asked for (mutable: a const query may assemble it).
  mutable EifInformationMatrix information_matrix_;
  Eigen::VectorXd eta_;
  // The rows moved since the relinearisation trigger's last test.
  EifLinearizationWatch linearization_watch_;
  // Whether the estimate is Λ⁻¹η exactly (no partial recovery since the last exact solve).
  bool estimate_exact_ = true;
  // Whether the estimate is a converged Gauss-Newton's (set where GaussNewton() stops on
  // its tolerances, cleared by every rebuild of Λ): Finish() then has nothing to iterate.
  bool converged_ = false;
  // Incremental updates since the last full factorisation (the guard's schedule).
  long updates_since_factorization_ = 0;
  // The factor of Λ (eif_solver.h); mutable: a const query keeps the columns it solved.
  mutable EifSolver solver_;
  association::SubmapAssociator associator_;
  // Per landmark, an upper bound on its marginal covariance (NaN: none); see
  // bound_candidate_marginals.
  std::vector<Eigen::Matrix2d> marginal_bound_;
  // Bounds on pairs' Cov(l_a − l_b) for the merge passes, cleared with marginal_bound_
  // and whenever a revision renumbers the landmarks.
  association::RelativeCovarianceBounds relative_bounds_;
  std::vector<int> last_association_;
  // Per landmark: a join gave it a feature since the last revision pass (or it is new).
  std::vector<char> touched_;
  bool relinearized_since_revision_ = false;
  std::vector<int> rejected_;
  struct Snapshot {  // what a rejected join undoes
    EifEstimate estimate;
    std::vector<EifFactor> factors;
    Eigen::VectorXd eta;
    association::SubmapAssociator associator;
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
    association::SubmapAssociation association;
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
  std::optional<association::SubmapAssociation> replayed_association_;
  // The loop-closure gate's decision on a map's association `a` (its pairings in
  // *assoc): the closing map of an undone closure loses its loop pairings; a thin closure
  // is held for confirmation (or, while one is held, adds to its evidence); a closure
  // under a lost anchor is held too. `counters_before`: the counters before `a` was made,
  // which a held closure's snapshot keeps.
  void GateLoopPairings(association::SubmapAssociation a, const JoinerCounters& counters_before,
                        std::vector<int>* assoc);
  // The decision counters of an association (truncated, thin, ambiguous).
  void CountDecisions(const association::SubmapAssociation& a);
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

#endif  // SUBSLAM_BACKEND_SRC_EIF_JOINER_IMPL_H_
