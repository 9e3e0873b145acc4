// The sparse extended information filter (SEIF; Thrun et al., IJRR 2004, and
// Probabilistic Robotics ch. 12) and its iterated variant ISEIF (*Iterative Sparse
// Extended Information Filter*, §2.3), as whole single-map SLAM filters: the fourth
// system of the papers cited in docs/scenarios.md, and a baseline.
//
// State y = [pose (3), landmark 1 (2), …] in the world frame (conventions.h), kept in
// information form: Ω = Σ⁻¹ and ξ = Ω μ, block-sparse, plus a running estimate μ of
// the mean. A landmark is *active* while Ω links it with the pose.
//
//  * Motion: x' = f(x, u) linearised at μ_x, x' ≈ A x + c + w,
//    w ~ N(0, Q). With Φ = T⁻ᵀ Ω T⁻¹ (T = diag(A, I)) and M = Q (I + Φ_xx Q)⁻¹,
//        Ω' = Φ − Φ_{:,x} M Φ_{x,:},    ξ' = ξ_Φ − Φ_{:,x} M ξ_Φ,x,   ξ_Φ = T⁻ᵀ ξ + Φ_{:,x} c.
//    This is Thrun's Table 12.2 written without Q⁻¹ (Q = G M(u) Gᵀ has rank 2 for
//    two-channel controls). Φ_{:,x} is non-zero on the pose and the active landmarks
//    only, so the cost is O(a²) for a active landmarks, whatever the map size. The
//    control steps between two scans are composed into one such step (a chain of
//    pose-only linear-Gaussian maps is one; same linearisation points), applied to Ω
//    when the next scan arrives: O(1) per control step.
//  * Measurement (per scan): Ω += Hᵀ R⁻¹ H, ξ += Hᵀ R⁻¹ (ν + H μ), linearised at μ;
//    touches the pose and the observed landmarks, which become active. A new landmark
//    gets μ_l = g(μ_x, z) and the information of its first detection only, which equals
//    the EKF's augmentation by the inverse sensor model.
//  * Sparsification (Thrun Table 12.7): when more than max_active_landmarks are
//    active, those seen longest ago (ties: lower ids first) are made
//    passive by the approximation
//    p(x | m⁺, m⁰, m⁻) ≈ p(x | m⁺, m⁻ = μ⁻); only the pose/active block changes.
//    This is the approximation that makes SEIF over-confident (ISEIF §2.2).
//  * Mean recovery: exact (sparse Cholesky of Ω with CHOLMOD; O(n) and more per scan),
//    or amortised block Gauss-Seidel relaxation (Thrun §12.6) over the pose, the active
//    and the observed landmarks, and a round-robin slice of the rest.
//  * Marginal covariances (for gating, and the reported pose covariance): exact, or
//    Thrun's Markov-blanket approximation — the inverse of Ω restricted to the pose,
//    the active landmarks, the candidates and their neighbours, i.e. conditioned on all
//    other landmarks at their means (over-confident; documented, not hidden).
//  * Association: nearest neighbour or JCBB with χ² gating on the recovered mean and
//    the (approximate) covariance, as EkfSlam; or, as an explicit study option only,
//    the detections' true ids. Existence (HybridSLAM Eq. 11) and the cull of tentative
//    landmarks are EkfSlam's; a culled landmark is marginalised out of Ω (exact).
//  * ISEIF (ISEIF §2.3, Eqs. 14-19): on every `period_scans`-th scan the measurement
//    update is relinearised at the latest estimate — Gauss-Newton on the step's MAP
//    problem (Eq. 9) — until the largest change of the pose or an observed landmark
//    falls below stop_change, or max_iterations. The first iteration is the SEIF update.
//    The first linearisation is followed by an exact recovery of the whole mean (this
//    carries the correction over the map), later ones by local relaxation; association
//    is decided once, before iterating.
//  * Time per stage: motion, associate (covariance recovery included), measurement,
//    iteration, sparsification, recovery, map_management (existence, new landmarks,
//    culls) and pose_covariance (exact pose covariance only).
//
// Cost per scan with the defaults: O(a³ + k³) for a active landmarks and a Markov
// blanket of k landmarks (both capped), plus the relaxation's fixed slice, whatever
// the map size; landmarks within reach come from a uniform grid over the means. Exact
// recovery and exact covariances cost a sparse factorisation of Ω each.
//
// Without sparsification and with exact recovery and covariances, SeifSlam equals
// EkfSlam started with the same prior (tests/frontend/seif_slam_test.cc).
// Not thread-safe.
#ifndef SUBSLAM_FRONTEND_SEIF_SLAM_H_
#define SUBSLAM_FRONTEND_SEIF_SLAM_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "absl/container/btree_map.h"
#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/association/data_association.h"
#include "subslam/frontend/landmark_options.h"
#include "subslam/frontend/online_estimator.h"
#include "subslam/models/motion_model.h"
#include "subslam/models/range_bearing_model.h"

namespace subslam::frontend {

enum class MeanRecovery { kExact, kRelaxation };
enum class CovarianceRecovery { kExact, kMarkovBlanket };
const char* ToString(MeanRecovery recovery);
const char* ToString(CovarianceRecovery recovery);
absl::StatusOr<MeanRecovery> MeanRecoveryFromString(const std::string& name);
absl::StatusOr<CovarianceRecovery> CovarianceRecoveryFromString(const std::string& name);

// ISEIF's iterated measurement update (ISEIF §2.3).
struct IteratedUpdateOptions {
  bool enabled = false;       // false: SEIF
  int period_scans = 100;     // iterate on every this-many-th scan (the paper: 100 or 500 steps)
  int max_iterations = 10;    // linearisations per iterated update (1 = the SEIF update)
  double stop_change = 1e-3;  // adaptive stop: max |Δμ| over the pose and observed landmarks [m, rad]
  // The first this-many linearisations are followed by an exact recovery of the whole
  // mean (CHOLMOD); later ones by relaxation of the pose and the active landmarks. The
  // first carries the correction to the whole map; the later ones are local.
  int exact_recoveries = 1;
};

struct SeifOptions {
  association::AssociationMethod association = association::AssociationMethod::kNearestNeighbour;
  long jcbb_max_nodes = 20000;
  LandmarkOptions landmarks;  // gates, known association, existence
  // A landmark whose mean lies farther than this from a detection's point (the
  // detection projected from the pose mean) is not gated with it: a cheap pre-filter
  // that bounds the covariance recovery to the neighbourhood of the detections.
  double candidate_radius_m = 10.0;
  // Sparsification bound on the active landmarks (Thrun's experiments use a few to a
  // few tens); 0 never sparsifies (the exact EIF, whose motion update is then O(n²)).
  int max_active_landmarks = 20;
  MeanRecovery recovery = MeanRecovery::kRelaxation;
  int relaxation_sweeps = 2;            // Gauss-Seidel sweeps per scan over the local set
  int relaxation_extra_landmarks = 20;  // round-robin landmarks added to each scan's sweeps
  // Covariances for gating.
  CovarianceRecovery covariance = CovarianceRecovery::kMarkovBlanket;
  int blanket_max_landmarks = 40;  // cap on the Markov-blanket landmarks per scan
  // The reported pose covariance. The Markov blanket conditions the pose on every
  // passive landmark and is far over-confident even without sparsification; kExact is
  // the marginal of the filter's own Ω, factorised once per scan and propagated
  // exactly (A Σ Aᵀ + Q) between scans — use it to judge the filter's consistency.
  CovarianceRecovery pose_covariance = CovarianceRecovery::kMarkovBlanket;
  // SEIF needs a positive-definite prior on the start pose (the information of a
  // perfectly known pose is infinite): σ of x, y [m] and heading [rad].
  Eigen::Vector3d initial_pose_sigma{0.01, 0.01, 0.001};
  IteratedUpdateOptions iterated;

  absl::Status Validate() const;
};

struct SeifCounters {
  long scans = 0;
  long detections = 0;
  long associated = 0;
  long new_landmarks = 0;
  long ambiguous = 0;
  long deleted_landmarks = 0;
  long jcbb_truncated = 0;
  long sparsifications = 0;  // scans on which landmarks were made passive
  long deactivated_landmarks = 0;
  long iterated_updates = 0;  // ISEIF: updates that iterated
  long iterations = 0;        // ISEIF: linearisations over those updates
  long exact_recoveries = 0;
  long max_active = 0;  // largest active set seen after an update
};

class SeifSlam final : public OnlineEstimator {
 public:
  SeifSlam(std::unique_ptr<models::MotionModel> motion, const models::RangeBearingConfig& sensor,
           const Pose2& initial_pose, const SeifOptions& options);
  ~SeifSlam() override;

  std::string Name() const override { return options_.iterated.enabled ? "iseif" : "seif"; }
  void Predict(const Eigen::Vector2d& u, double dt) override;
  // Known association reads detections' truth_id; without it truth ids are never read.
  absl::Status Update(const Scan& scan) override;
  Pose2 pose() const override;
  // Exact or Markov-blanket marginal (options.pose_covariance).
  Eigen::Matrix3d pose_covariance() const override;
  // Confirmed landmarks, with exact marginal covariances (one factorisation).
  std::vector<LandmarkEstimate> Map() const override;
  StageTimes stage_times() const override { return times_; }
  std::map<std::string, double> Counters() const override;

  // Recovers the whole mean exactly (Ω μ = ξ) now, whatever options.recovery says.
  void RecoverMeanExactly();
  const SeifCounters& counters() const { return counters_; }
  int num_landmarks() const;  // live landmarks (tentative included)
  int num_active_landmarks() const { return static_cast<int>(pose_links_.size()); }
  // Landmark-landmark links (off-diagonal 2×2 blocks, each counted once).
  long num_landmark_links() const;
  // The dense information matrix, vector and mean over [pose, live landmarks in id
  // order], and those ids (for tests and small problems). The first two apply the
  // pending motion to Ω first.
  Eigen::MatrixXd DenseInformation();
  Eigen::VectorXd DenseInformationVector();
  Eigen::VectorXd DenseMean() const;
  std::vector<int> LiveLandmarkIds() const;
  // The landmark id each detection of the last scan was associated with or created
  // (−1: out of range, ambiguous, or a false alarm under known association).
  const std::vector<int>& last_scan_features() const { return scan_features_; }

 private:
  class ExactSolver;
  // Factorisations or innovation covariances that were not positive definite (Counters():
  // numerical_failures); a failed recovery leaves NaN, so the run stops there.
  mutable long numerical_failures_ = 0;
  // One linearised measurement update: what it adds to Ω and ξ.
  struct Linearization {
    std::vector<int> landmarks;  // distinct, in the order of D's blocks
    Eigen::MatrixXd D;           // added to Ω over [pose, landmarks]
    Eigen::VectorXd dxi;         // added to ξ
  };
  struct LandmarkInfo {
    bool alive = true;
    double existence = 0.5;
    bool confirmed = false;
    long last_seen_scan = 0;
    int truth_id = -1;  // known association only
  };
  // Covariance over a few variables: pose (if asked) and landmarks, as one dense matrix.
  struct LocalCovariance {
    Eigen::MatrixXd sigma;                 // over [pose, landmarks in `index` order]
    absl::flat_hash_map<int, int> offset;  // landmark → row offset in sigma
  };

  int Offset(int landmark) const { return 3 + 2 * landmark; }
  void Reserve(int landmarks);
  int AddLandmarkSlot(const Eigen::Vector2d& mean);
  std::vector<int> ActiveLandmarks() const;  // sorted ids
  // Ω over [pose, landmarks] (dense, 3 + 2k), and ScatterAdd of a dense increment over
  // the same variables (exactly zero blocks create no link).
  Eigen::MatrixXd Gather(const std::vector<int>& landmarks) const;
  Eigen::VectorXd GatherXi(const std::vector<int>& landmarks) const;
  Eigen::VectorXd GatherMean(const std::vector<int>& landmarks) const;
  void ScatterAdd(const std::vector<int>& landmarks, const Eigen::MatrixXd& D);
  void AddXi(const std::vector<int>& landmarks, const Eigen::VectorXd& d);
  // Shifts μ_θ into (−π, π] and ξ with it (the same Gaussian in shifted coordinates).
  void WrapHeading();
  // Applies the motion composed since the last flush to Ω and ξ (Thrun Table 12.2).
  void FlushMotion();
  // Linearises the pairings at μ, adds Hᵀ R⁻¹ H and Hᵀ R⁻¹ (ν + Hμ); returns what it
  // added so that an iterated update can take it back.
  Linearization ApplyMeasurements(const std::vector<std::pair<int, Eigen::Vector2d>>& pairs);
  // The scan update's steps (seif_measurement_update.cc): the landmarks within reach of
  // the pose (a 3 × 3 block of grid cells); association by true id or by the gates (NN or
  // JCBB on the candidates' local covariances), marking the landmarks a detection gated
  // and the detections that start a landmark; the measurement update, relinearised to
  // convergence on ISEIF's period; existence, new landmarks and culls (returns the new ones).
  std::vector<int> LandmarksInReach(const Pose2& p) const;
  void AssociateByTruth(const Scan& scan, const std::vector<int>& detection_index,
                        std::vector<int>* landmark_of_detection, std::vector<bool>* creates,
                        absl::flat_hash_map<int, bool>* gated) const;
  void AssociateByGates(const Pose2& p, const std::vector<Eigen::Vector2d>& z, const std::vector<int>& in_reach,
                        const Eigen::Matrix2d& R, std::vector<int>* landmark_of_detection, std::vector<bool>* creates,
                        absl::flat_hash_map<int, bool>* gated);
  void MeasurementUpdate(const std::vector<std::pair<int, Eigen::Vector2d>>& pairs, const std::vector<int>& touched);
  std::vector<int> ManageLandmarks(const Scan& scan, const std::vector<int>& detection_index,
                                   const std::vector<Eigen::Vector2d>& z, const Pose2& p,
                                   const std::vector<int>& landmark_of_detection, const std::vector<bool>& creates,
                                   const std::vector<int>& in_reach, const absl::flat_hash_map<int, bool>& gated);
  void Retract(const Linearization& lin);
  void Sparsify();
  void Marginalize(int landmark);
  void Relax(const std::vector<int>& landmarks, int sweeps);
  void RelaxPose();
  void RelaxLandmark(int landmark);
  // After the measurement update: exact, or relaxation of the pose and the active
  // landmarks (options.recovery).
  void RecoverLocally();
  // End of a scan (relaxation only): the pose, the active and the touched landmarks and
  // a round-robin slice of relaxation_extra_landmarks others.
  void RecoverAmortised(const std::vector<int>& touched);
  LocalCovariance Covariance(const std::vector<int>& landmarks, bool exact) const;
  void UpdateExistence(LandmarkInfo* info, bool detected) const;
  void Invalidate() { ++version_; }
  // A uniform grid over landmark means (cell = the scan's reach), kept current on every
  // write of a landmark mean, so a scan finds the landmarks within reach in O(1).
  static constexpr uint64_t kNoCell = ~0ULL;
  int64_t CellCoordinate(double v) const;
  static uint64_t CellKey(int64_t cx, int64_t cy);
  void UpdateCell(int landmark);
  void RemoveFromCell(int landmark);

  std::unique_ptr<models::MotionModel> motion_;
  models::RangeBearingModel sensor_;
  SeifOptions options_;
  double gate_d2_ = 0.0, new_landmark_d2_ = 0.0;
  // Block-sparse Ω: pose block, pose-landmark links (the active set), landmark
  // diagonal blocks and landmark-landmark links (stored in both directions; the block
  // at links_[i][j] is Ω_{l_i, l_j}). The links are ordered maps: sums over them
  // (e.g. the relaxation's Ω·μ) then run in landmark order, so a run is reproducible to
  // the bit (a hash map's order changes from process to process).
  Eigen::Matrix3d omega_xx_;
  absl::btree_map<int, Matrix32d> pose_links_;
  std::vector<Eigen::Matrix2d> omega_ll_;
  std::vector<absl::btree_map<int, Eigen::Matrix2d>> links_;
  Eigen::VectorXd xi_, mu_;  // capacity-doubling; 3 + 2 × (landmark slots) live
  std::vector<LandmarkInfo> landmarks_;
  absl::flat_hash_map<int, int> landmark_of_truth_;  // known association only
  double cell_size_m_ = 1.0;
  absl::flat_hash_map<uint64_t, std::vector<int>> grid_;
  std::vector<uint64_t> cell_of_;  // per landmark slot; kNoCell when dead
  int live_landmarks_ = 0;
  size_t round_robin_ = 0;
  SeifCounters counters_;
  StageTimes times_;
  std::vector<int> scan_features_;
  long version_ = 0;
  mutable long pose_cov_version_ = -1;
  mutable Eigen::Matrix3d pose_cov_;
  Eigen::Matrix3d exact_pose_cov_;  // options.pose_covariance == kExact, at the last flush
  // Motion since the last flush, composed: x_now ≈ A (x_flushed − flushed_pose_) + μ_x + w,
  // w ~ N(0, Q); applied to Ω before anything reads it.
  bool motion_pending_ = false;
  Eigen::Matrix3d pending_A_ = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d pending_Q_ = Eigen::Matrix3d::Zero();
  Eigen::Vector3d flushed_pose_ = Eigen::Vector3d::Zero();
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_SEIF_SLAM_H_
