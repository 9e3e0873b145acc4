// FastSLAM 2.0 with unknown data association (known association: a study option, see
// FastSlamOptions::known_association): the Rao-Blackwellised particle filter of
// the local mapper (HybridSLAM §2-3, Montemerlo et al. 2003), usable on its own as the
// single-map FastSLAM 2.0 baseline (`subslam run --frontend fastslam`).
//
// Each particle holds a pose hypothesis and its own map of 2-D Gaussian landmarks.
//  * Between scans a particle's pose is a Gaussian: its pose at the last scan composed
//    with the motion since, r ~ N(r̄, Σ_r), whose linearised process noise accumulates
//    as Σ_r ← F Σ_r Fᵀ + G M Gᵀ, so the pose noise of all the steps since the last scan
//    enters the FastSLAM 2.0 proposal at once. The motion models are SE(2)-equivariant
//    (f(a ∘ r, u) = a ∘ f(r, u); tested for each model), so r̄ and Σ_r are the same for
//    every particle and prediction costs O(1), not O(N).
//  * Scan (per particle): every (detection, landmark) pair whose predicted measurement
//    passes the χ²₂ individual gate is scored by its predictive density
//    N(ν; 0, S), S = H_x Σ H_xᵀ + H_l Σ_l H_lᵀ + R (maximum likelihood; or by
//    Mahalanobis distance, option) and assigned one-to-one, best pair first (or sampled
//    detection by detection: data-association sampling, option). A detection outside the
//    larger new-landmark gate for every landmark starts a new landmark; one between the
//    gates is left unexplained. Each associated detection, in assignment order, updates
//    the proposal (x̄, Σ) by an EKF step with measurement noise H_l Σ_l H_lᵀ + R (the
//    FastSLAM 2.0 proposal); after the scan the pose is sampled from it and Σ reset.
//    The importance weight gains the predictive density of every associated detection
//    and the constant new-landmark density p0 (see FastSlamOptions) for every other.
//    Predicted measurements are computed once per scan and corrected to first order
//    for the proposal's shift, so the inner association loop allocates nothing.
//  * Landmarks are updated by 2-D EKFs (optionally iterated) at the sampled pose; new ones initialised by the
//    inverse sensor model. An optional signature cue (e.g. trunk diameter) multiplies
//    the association likelihood by N(s − s̄; 0, σ_s²(1 + 1/k)) over the k signatures seen.
//  * Existence (existence_model.h, HybridSLAM Eq. 11) per particle and landmark: a
//    detection raises it, a landmark expected inside the field of view but not even gated
//    lowers it; every `cull_every_scans` scans tentative landmarks below the delete
//    threshold are removed, so false alarms do not survive.
//  * Correspondence voting (HybridSLAM §3.1): each detection's decisions (ignore, new,
//    or an existing landmark's common feature id) are tallied with the particles'
//    weights; the winner's common id is written into every landmark the detection
//    modified or created, overwriting earlier ids, so a consensus can be overturned.
//  * Systematic resampling when the effective sample size falls below
//    `resample_ess_ratio` × N, deferred to the next Predict/Update so that estimates
//    taken after a scan (pose(), Map(), a local map closed now) use the weighted
//    particles, not resampled duplicates.
//  * Odometry self-calibration (optional, FastSlamOptions::odometry; odometry_calibration.h):
//    each particle holds a Gaussian N(m_p, P_p) over c = (s0, s1, b). The motion since
//    the last scan is integrated once at ĉ (the particles' weighted mean at that scan),
//    with its Jacobian D = ∂r/∂c, and a particle's prior for the scan is r̂ + D(m_p − ĉ)
//    with covariance Σ_r + D P_p Dᵀ; after the scan its sampled pose updates N(m_p, P_p)
//    by a Kalman step on the motion it implies (c given the particle's path is Gaussian
//    to first order). pose() and pose_covariance() between scans take the motion at ĉ
//    and add the particles' calibration spread through D. The mixture's covariance of c
//    is optimistic: after resampling the particles' paths descend from few ancestors,
//    and each P_p is conditional on its path (docs/limits.md).
//  * Storage: a landmark's Gaussian is shared between particles (std::shared_ptr to
//    const) and copied only when a particle that shares it updates it, so resampling
//    copies pointers, never whole maps. Existence and the common id live in the
//    particle's own small per-landmark record.
//
// Frames: the filter works in one frame, the one of `start` given to the constructor or
// Reset() (the world for the single-map filter, the local map's start frame — identity
// start — for the local mapper). Units: metres, radians, seconds.
// Deterministic for a given seed, whatever the number of threads (FastSlamOptions::
// num_threads). Not thread-safe: one filter per calling thread.
#ifndef SUBSLAM_FRONTEND_FASTSLAM_H_
#define SUBSLAM_FRONTEND_FASTSLAM_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <random>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "subslam/frontend/genealogy.h"
#include "subslam/frontend/landmark_options.h"
#include "subslam/frontend/moment_matching.h"
#include "subslam/frontend/odometry_calibration.h"
#include "subslam/frontend/online_estimator.h"
#include "subslam/models/motion_model.h"
#include "subslam/models/range_bearing_model.h"

namespace subslam::frontend {

class WorkerPool;  // internal/worker_pool.h

// How gated (detection, landmark) pairs are ranked for the one-to-one assignment.
enum class AssociationScore {
  kLikelihood,   // maximum likelihood: N(ν; 0, S), signature cue included
  kMahalanobis,  // nearest neighbour: smallest νᵀS⁻¹ν (as EKF-SLAM's NN)
};

struct FastSlamOptions {
  int num_particles = 100;
  uint64_t seed = 1;
  // Gates, known association (per particle: a detection goes to the particle's landmark
  // of its true id), existence.
  LandmarkOptions landmarks;
  // false: one-to-one greedy assignment of the gated pairs, best `association_score`
  // first; true: data-association sampling — each detection in turn picks one of the
  // unused gated landmarks or "new" at random in proportion to their likelihoods.
  bool sample_association = false;
  AssociationScore association_score = AssociationScore::kLikelihood;
  // p0, the density of a detection explained by a new landmark or by clutter, is the
  // Gaussian density N(·; 0, R) at the new-landmark gate's boundary, R the sensor noise.
  // A detection between the two gates (close to a landmark, but not close enough) is
  // ignored: it updates nothing, and the particle's weight scores it by the likelihood of
  // its most likely landmark that no other detection took (at least p0) — scoring it by
  // p0 alone would down-weight particles whose pose puts a landmark just outside the
  // gate and cut off the tails of the pose posterior (bench/RESULTS.md).
  // Resample when N_eff < resample_ess_ratio · N.
  double resample_ess_ratio = 0.5;
  // Particle depletion, reported only (Counters(): depleted_updates): an update after
  // which N_eff < depletion_ess_ratio · N — a handful of particles carry the weight.
  double depletion_ess_ratio = 0.05;
  // Landmark EKF update iterations (1: plain EKF; more: iterated EKF, relinearising the
  // measurement at the updated mean — better with large bearing noise at long range).
  int landmark_update_iterations = 1;
  // Signature cue: σ of one signature measurement (same units as the signature);
  // 0 disables the cue.
  double sigma_signature = 0.0;
  // Moment matching used by pose(), Map() and the local mapper.
  MomentMatchingOptions moment_matching;
  // Whether pose_covariance() and MomentMatched() (hence Map() and the local maps) scale
  // the particles' spread by (1 + R) / (1 − R), R = SharedAncestry(): after resampling
  // the particles descend from few ancestors whose pose draws they share, so their
  // spread under-states the uncertainty, and their weighted mean carries a Monte Carlo
  // error of its own (MomentMatch; genealogy.h). false: the mixture's own
  // moments (HybridSLAM Eqs. 6-7). The particle filter itself runs the same either way;
  // the local maps differ in their covariance, and so in which features the mapper's
  // max_feature_sigma_ratio rule leaves out.
  bool correct_shared_ancestry = true;
  // Threads for the per-particle part of a scan (association, the proposal, the pose
  // sample, the landmark updates, the copies of resampling), run on oneTBB's shared
  // workers, which sleep when idle. Each pool index keeps a fixed block of particle slots
  // from scan to scan (and the pool offers each index to the thread that ran it before),
  // so that their records tend to stay in one core's cache; an index that finishes its
  // block takes chunks of another's. The results do not depend on it: each particle slot
  // draws from its own random stream, seeded from `seed` and the slot.
  // 0: std::thread::hardware_concurrency().
  int num_threads = 1;
  // The sensor's yaw on the vehicle as an uncertain parameter of each local map: at
  // Reset() every particle draws a yaw ψ ~ N(0, σ²) [rad] and adds it to every bearing it
  // sees (local maps stay independent). A local map identifies ψ only weakly; mostly the
  // spread makes the exported covariance carry a
  // rotation of the map's bearings, so that local maps of an uncalibrated sensor still
  // agree with each other. 0: bearings taken as calibrated. Opt-in: where they are, the
  // spread costs accuracy (docs/limits.md). The counters sensor_yaw_mean and
  // sensor_yaw_spread give the particles' weighted yaw and its spread at each local map's
  // close (Reset() after scans), averaged over the maps closed so far; before the first
  // close, the particles' now (a single-map run).
  double sensor_yaw_sigma = 0.0;
  // The odometry's systematic error learned per particle (see above; off by default).
  OdometryCalibrationOptions odometry;

  absl::Status Validate() const;
};

struct FastSlamCounters {
  long scans = 0;
  long detections = 0;
  long resamples = 0;
  long associated = 0;                // detection-landmark pairings, summed over particles
  long ignored = 0;                   // detections left unexplained (between the gates), summed
  long landmarks_created = 0;         // summed over particles
  long landmarks_culled = 0;          // summed over particles
  long landmark_copies = 0;           // copy-on-write copies (with threads, timing may add a few)
  long features = 0;                  // common feature ids issued
  long scans_with_fewer_threads = 0;  // run below the pool's size (set_thread_limit)
  // Depletion. The smallest N_eff / N after an update; updates below
  // FastSlamOptions::depletion_ess_ratio; entries into lineage collapse (every particle
  // descends from one particle of the run's or the local map's start); scans after which
  // every weight was zero or NaN, so that the weights were reset to uniform (the scan
  // then informs the landmarks but not the choice of particles).
  double min_ess_ratio = 1.0;
  long depleted_updates = 0;
  long lineage_collapses = 0;
  long weight_collapses = 0;
};

class FastSlam final : public OnlineEstimator {
 public:
  FastSlam(std::unique_ptr<models::MotionModel> motion, const models::RangeBearingConfig& sensor, const Pose2& start,
           const FastSlamOptions& options);
  ~FastSlam() override;

  std::string Name() const override { return "fastslam"; }
  void Predict(const Eigen::Vector2d& u, double dt) override;
  absl::Status Update(const Scan& scan) override;
  // Moment-matched pose and covariance (Eqs. 6-7 over the pose block).
  Pose2 pose() const override;
  Eigen::Matrix3d pose_covariance() const override;
  // Moment-matched landmarks with existence ≥ options.moment_matching.min_existence.
  std::vector<LandmarkEstimate> Map() const override;
  StageTimes stage_times() const override { return times_; }
  std::map<std::string, double> Counters() const override;

  // Starts over at `start` with zero uncertainty, no landmarks and equal weights (a new
  // local map). Common feature ids keep increasing across resets.
  void Reset(const Pose2& start);
  // At most this many of its threads for the next scans (0: all), e.g. while another
  // thread of the process needs a core; the results do not change.
  void set_thread_limit(int threads) { thread_limit_ = threads; }
  int threads() const;  // of its pool
  // The particles as Gaussian hypotheses, ready for MomentMatch().
  std::vector<ParticleHypothesis> Hypotheses() const;
  MomentMatchedGaussian MomentMatched() const;

  // N_eff / N of the current weights, in (0, 1].
  double EffectiveSampleSizeRatio() const;
  // The heaviest particle's distinct confirmed features: all of them, and those within
  // the sensor's range of its pose (cheap; used by the submap policy after each scan).
  struct FeatureCounts {
    int total = 0;
    int within_range = 0;
  };
  FeatureCounts ConfirmedFeatureCounts() const;
  // Path diversity: the share of the particles' distinct ancestors at the first scan
  // after the last Reset() (1 until then). Resampling only lowers it; once it is small,
  // the landmarks mapped early rest on a few pose hypotheses and the particle set
  // under-represents the local map's uncertainty.
  double LineageDiversity() const;
  // R = Σ_pq w_p w_q ρ_pq over the current weights, ρ_pq the share of the pose noise
  // sampled since the last Reset() that particles p and q hold in common: the scans
  // before their last common ancestor, over all scans (each scan's pose sample is one
  // independent draw per particle, equal in size — the approximation). Σ_p w_p² when no
  // resampling happened since Reset(); 0 before the first scan, and 0 (no correction:
  // the spread is zero) when every particle is a copy of one (R within 1e-12 of 1).
  // The argument `shared_ancestry` of MomentMatch(). The derivation takes the weights as
  // independent of the particles' deviations, which importance weights are not; when the
  // weights are degenerate (N_eff near 1) the spread carries little information either
  // way and the corrected one can be large (a map whose particles all descend from one
  // late ancestor; its distribution over local maps: docs/design/filters.md).
  double SharedAncestry() const;
  // N_eff / N after the last scan's weight update, before any resampling.
  double last_scan_ess_ratio() const { return last_ess_ratio_; }
  // The common feature id voted for each detection of the last scan, aligned with the
  // scan's detections (−1: out of range or ignored).
  const std::vector<int>& last_scan_features() const { return scan_features_; }
  // The largest share of weight that voted against the winner, over the last scan's
  // detections (0: unanimous).
  double last_scan_disagreement() const { return scan_disagreement_; }
  int num_particles() const { return static_cast<int>(particles_.size()); }
  const FastSlamCounters& counters() const { return counters_; }
  // The odometry calibration now: the moments of the particles' weighted mixture (the
  // prior before the first scan; (1, 1, 0) and zero covariance when off).
  OdometryCalibrationEstimate odometry_calibration() const;

 private:
  struct LandmarkGaussian {
    Eigen::Vector2d mean;
    Eigen::Matrix2d covariance;
    double signature_sum = 0.0;  // over `signatures` detections
    int signatures = 0;
    int truth_id = -1;  // known association only: the true id it was created for
  };
  struct LandmarkRecord {  // per particle
    std::shared_ptr<const LandmarkGaussian> gaussian;
    double existence = 0.5;
    int feature = -1;  // common feature id
    bool confirmed = false;
    bool missed = false;  // scratch: expected in the last scan but not detected
  };
  struct Particle {
    Pose2 pose;                               // at the last scan (or Reset); now: CurrentPose(). Set by SetPose().
    double cos_theta = 1.0, sin_theta = 0.0;  // of pose.theta
    double log_weight = 0.0;                  // normalised: Σ exp(log_weight) = 1 after each scan
    int lineage = -1;                         // index of the ancestor at the first scan after Reset()
    double sensor_yaw = 0.0;                  // the sensor yaw [rad] it assumes (sensor_yaw_sigma), from Reset()
    // Its odometry calibration N(m_p, P_p) (FastSlamOptions::odometry).
    Eigen::Vector3d calibration = Eigen::Vector3d(1.0, 1.0, 0.0);
    Eigen::Matrix3d calibration_covariance = Eigen::Matrix3d::Zero();
    std::vector<LandmarkRecord> landmarks;
  };
  struct PairScore {
    Eigen::Vector2d nu;
    Eigen::Matrix2d S, S_inv;
    double det = 0.0;  // det S
    double d2 = 0.0;
    double log_likelihood_but_det = 0.0;  // log N(ν; 0, S) + ½ log det S (+ signature)
  };
  struct GatedPair {
    double rank;
    int detection;
    int landmark;
  };
  struct Prediction {  // of one landmark of the particle being updated
    Eigen::Vector2d z;
    Matrix23d H_pose;
    Eigen::Matrix2d Z;         // H_l Σ_l H_lᵀ + R
    Eigen::Matrix2d S, S_inv;  // at the prior proposal: H_x Σ H_xᵀ + Z
    double det = 0.0;          // det S
    double log_norm = 0.0;     // −log 2π − ½ log det S (NaN until needed)
    bool in_reach = false;
    bool expected = false;  // well inside range and field of view (missed-detection test)
    bool gated = false;     // some detection within the new-landmark gate
    bool used = false;      // associated in this scan
  };
  // Landmarks further than this outside the field of view are not predicted.
  static constexpr double kFovMarginRad = 0.35;
  static constexpr int kNew = -1;
  static constexpr int kIgnore = -2;

  // The particle's pose now, and its covariance (the motion since the last scan).
  Pose2 CurrentPose(const Particle& p, Eigen::Matrix3d* covariance = nullptr) const;
  // Odometry calibration (fastslam_odometry_calibration.cc): the motion since the scan at
  // ĉ and its Jacobian; a particle's calibration updated by its pose sampled at this scan
  // (it was at `previous`); ĉ and the spread set to the particles' mixture (the prior
  // before any particle), after a scan and, carried into a new local map, at Reset().
  void PredictCalibrated(const Eigen::Vector2d& u, double dt);
  void UpdateCalibration(Particle* p, const Pose2& previous) const;
  void RecentreCalibration();
  static void SetPose(Particle* p, const Pose2& pose);
  // pose() and pose_covariance() after any motion since the last scan, in O(1) from the
  // per-scan particle sums (UpdateMoments).
  void UpdatePoseCache() const;
  void UpdateMoments() const;
  PairScore Score(const Prediction& prediction, const LandmarkGaussian& landmark, const Eigen::Vector2d& z,
                  double signature, const Eigen::Vector3d& delta, const Eigen::Matrix3d& Sigma) const;
  double SignatureLogLikelihood(const LandmarkGaussian& l, double signature) const;
  class ScanUpdate;  // one particle's scan update, phase by phase (fastslam_particle_update.cc)
  // Per-thread scratch of UpdateParticle, reused across scans, and its counts.
  struct alignas(64) Scratch {            // a cache line apart: written by different threads
    std::vector<Prediction> predictions;  // of the particle's landmarks
    std::vector<GatedPair> pairs;
    std::vector<double> min_d2;
    std::vector<GatedPair> near_pairs;  // every pair inside the new-landmark gate, ranked by log-likelihood
    std::vector<std::pair<int, double>> likelihoods;
    std::vector<Eigen::Vector2d> z_seen;  // the scan's detections with the particle's sensor yaw
    long associated = 0, ignored = 0;
    long landmark_copies = 0, landmarks_created = 0, landmarks_culled = 0;
  };
  // The scan's detections as `particle` sees them: z_, or with sensor_yaw_sigma its sensor
  // yaw added to every bearing (in scratch->z_seen).
  const std::vector<Eigen::Vector2d>& DetectionsSeenBy(const Particle& particle, Scratch* scratch) const;
  // Associates the scan for one particle, samples its pose and updates its weight;
  // touches only the particle, its decisions, `scratch` and `rng` (safe to run for
  // different particles in parallel).
  void UpdateParticle(Particle* particle, const std::vector<Eigen::Vector2d>& z, const std::vector<double>& signature,
                      int* decisions, Scratch* scratch, std::mt19937_64* rng) const;
  // The landmark updates, creations, existence updates and culls of one particle's
  // decisions; touches only the particle, landmarks it alone holds (copy-on-write) and
  // `scratch` (safe to run for different particles in parallel).
  void ApplyDecisions(Particle* particle, const std::vector<Eigen::Vector2d>& z, const std::vector<double>& signature,
                      const int* decisions, Scratch* scratch) const;
  void Vote(int m);
  // The scan's detections within the sensor's range into z_, signature_, truth_ (known
  // association: -1 for a false alarm or an id already in the scan) and
  // detection_index_; returns how many.
  int TakeUsableDetections(const Scan& scan);
  // After the weights of a scan: the effective sample size and lineage collapse counters.
  void RecordParticleHealth();
  void Normalize();
  void Resample();
  void UpdateExistence(LandmarkRecord* record, bool detected) const;
  static LandmarkGaussian* Mutable(LandmarkRecord* record, Scratch* scratch);

  std::unique_ptr<models::MotionModel> motion_;
  models::RangeBearingModel sensor_;
  FastSlamOptions options_;
  double gate_d2_ = 0.0, new_landmark_d2_ = 0.0, log_p0_ = 0.0;
  double fov_center_ = 0.0, fov_cos_limit_ = -2.0, fov_cos_expected_ = -2.0;
  std::vector<Particle> particles_, resampled_;
  std::mt19937_64 rng_;                         // resampling
  std::vector<std::mt19937_64> particle_rngs_;  // one stream per particle slot
  std::mt19937_64 yaw_rng_;                     // the particles' sensor yaws (sensor_yaw_sigma)
  std::unique_ptr<WorkerPool> pool_;
  int thread_limit_ = 0;
  // The particles' weighted sensor yaw [rad] and its spread, now and summed over the
  // particle sets Reset() closed (sensor_yaw_sigma; counters sensor_yaw_mean, _spread).
  struct YawMoments {
    double mean = 0.0, spread = 0.0;
  };
  YawMoments SensorYawMoments() const;
  double yaw_mean_sum_ = 0.0, yaw_spread_sum_ = 0.0;
  long yaw_maps_ = 0;
  long scans_at_reset_ = 0;
  std::vector<Scratch> scratch_;      // one per thread
  std::vector<int> owner_;            // the pool index that associated each particle
  struct alignas(64) ParticleBlock {  // a pool index's own particles in Update(); a cache line apart
    std::atomic<int> next{0};         // the first not yet taken
    int end = 0;                      // one past the last
  };
  std::unique_ptr<ParticleBlock[]> blocks_;  // one per pool index
  static constexpr int kChunk = 4;           // particles an index takes from a block at a time
  int next_feature_ = 0;
  // Scratch reused across scans.
  std::vector<int> decisions_;       // particles × detections: landmark index | kNew | kIgnore
  std::vector<int> decision_label_;  // the common id each decision votes for
  std::vector<int> voted_label_;     // per detection: the id written into landmarks
  std::vector<std::pair<int, double>> tally_;
  std::vector<double> weights_;
  std::vector<int> scan_features_;
  std::vector<int> detection_index_;
  double last_ess_ratio_ = 1.0;
  Pose2 motion_since_scan_;  // shared by all particles (see above)
  Eigen::Matrix3d motion_covariance_ = Eigen::Matrix3d::Zero();
  // Odometry calibration: ĉ, D = ∂r/∂c for the motion since the scan, and the particles'
  // weighted Σ_p w_p (P_p + (m_p − ĉ)(m_p − ĉ)ᵀ) at the last scan.
  Eigen::Vector3d calibration_linearized_ = Eigen::Vector3d(1.0, 1.0, 0.0);
  Eigen::Matrix3d motion_calibration_jacobian_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d calibration_spread_ = Eigen::Matrix3d::Zero();
  // pose() / pose_covariance(), computed once per change.
  // Weighted sums over the particles at the last scan, about `origin` (the heaviest):
  // a_p = (x, y, θ) − origin (heading wrapped), c_p, s_p = cos, sin of the heading.
  struct ParticleMoments {
    Pose2 origin;
    double w = 0, c = 0, s = 0, cc = 0, ss = 0, cs = 0;
    Eigen::Vector3d a = Eigen::Vector3d::Zero(), ac = Eigen::Vector3d::Zero(), as = Eigen::Vector3d::Zero();
    Eigen::Matrix3d aa = Eigen::Matrix3d::Zero();
    double spread_scale = 1.0;  // (1 + R) / (1 − R), R = SharedAncestry(), when corrected
  };
  mutable bool moments_valid_ = false;
  mutable ParticleMoments moments_;
  mutable bool pose_cache_valid_ = false;
  mutable Pose2 cached_pose_;
  mutable Eigen::Matrix3d cached_pose_covariance_;
  bool resample_pending_ = false;
  bool lineage_collapsed_ = false;
  std::vector<Eigen::Vector2d> z_;
  std::vector<double> signature_;
  std::vector<int> truth_;                       // known association: the true id of each usable detection
  absl::flat_hash_map<int, int> feature_truth_;  // known association: common id → true id
  mutable std::vector<int> features_scratch_;
  mutable std::vector<char> lineage_seen_;
  Genealogy genealogy_;                           // since Reset()
  std::vector<int> parent_;                       // scratch of Resample
  mutable std::vector<double> ancestry_weights_;  // scratch of SharedAncestry
  double scan_disagreement_ = 0.0;
  FastSlamCounters counters_;
  StageTimes times_;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_FASTSLAM_H_
