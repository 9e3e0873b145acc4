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
//  1. data association (association/submap_association.h), with the marginal covariances it
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
#include "subslam/association/submap_association.h"
#include "subslam/backend/eif_joiner_options.h"
#include "subslam/backend/map_joiner.h"
#include "subslam/core/local_submap.h"
#include "subslam/core/submap_graph.h"

namespace subslam::backend {

class EifJoiner final : public MapJoiner {
 public:
  EifJoiner(const Pose2& initial_pose, const EifJoinerOptions& options);
  ~EifJoiner() override;

  // Relinearises to convergence if relinearize_at_end, then revises the association
  // until a pass changes nothing.
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
  // The nonlinear least-squares cost Σ_f r_fᵀ Q_f⁻¹ r_f of every local map's factor at
  // the current estimate (whitened, dimensionless).
  double Cost() const;

  const SubmapGraph& graph() const override;
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
  std::vector<association::Matrix5d> AnchorLandmarkCovariances(int anchor, const std::vector<int>& landmarks) const;
  // The joint marginal of landmarks a and b (a's rows first), entry by entry as
  // JointCovariance({}, {a, b}) gives it, each landmark's own block taken from `own` (NaN:
  // recovered now and kept there), so that a merge pass pays each pair's cross terms only.
  Eigen::Matrix4d LandmarkPairCovariance(int a, int b, std::vector<Eigen::Matrix2d>* own) const;
  // For each landmark, an upper bound on that 5 × 5 marginal: the exact anchor block and
  // cross-covariance (one solve for the anchor's columns) with the landmark's block
  // replaced by its marginal bound (see bound_candidate_marginals); nullopt for a
  // landmark without one.
  std::vector<std::optional<association::Matrix5d>> AnchorLandmarkBounds(int anchor,
                                                                         const std::vector<int>& landmarks) const;

  const std::vector<int>& last_association() const override;
  // Ids of the local maps whose association failed validation.
  const std::vector<int>& rejected() const;
  // The information matrix (both triangles), assembled on demand from the factors (a join
  // updates only the factor of Λ and η); for tests and tools.
  const Eigen::SparseMatrix<double>& information() const;
  int state_dimension() const;
  // Entries of the sparse LDLᵀ factor of Λ (its fill; 0 before the first join).
  long factor_nonzeros() const;
  // The ordering of that factor's last full factorisation (kAmd or kNestedDissection).
  FillReducingOrdering factor_ordering() const;
  // Where a variable sits in Λ and η (−1 for the fixed P0).
  int anchor_offset(int k) const;
  int landmark_offset(int j) const;
  std::map<std::string, double> stage_times() const override;
  const JoinerCounters& counters() const override;
  const association::SubmapAssociator& associator() const override;

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
  // The joiner's parts and state (backend/src/eif_joiner_impl.h), held by a pointer that
  // copies what it points to: a copy of the joiner is a copy of every part (Clone()).
  class Impl;
  class ImplHolder {
   public:
    explicit ImplHolder(std::unique_ptr<Impl> impl);
    ImplHolder(const ImplHolder& other);
    ImplHolder& operator=(const ImplHolder&) = delete;
    ~ImplHolder();
    Impl* operator->() const { return impl_.get(); }
    Impl& operator*() const { return *impl_; }

   private:
    std::unique_ptr<Impl> impl_;
  };

  EifJoiner(const EifJoiner& other);  // every part copied, for Clone()
  friend class CeresJoiner;           // whose copies copy their EIF
  // Hands the association innovation recorded since the last call to MapJoiner (after
  // every call that may associate: a join, a whole-map join, Finish()).
  void RecordInnovation();

  ImplHolder impl_;
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_EIF_JOINER_H_
