#include "subslam/frontend/fastslam.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>
#include <thread>

#include "absl/strings/str_cat.h"
#include "subslam/core/check.h"
#include "subslam/core/stage_timer.h"
#include "subslam/frontend/genealogy.h"
#include "subslam/frontend/internal/worker_pool.h"
#include "subslam/models/gating.h"

namespace subslam::frontend {

namespace {

// log N(ν; 0, S) for 2-D ν given S⁻¹ν·ν = d2.
double LogGaussian2(double d2, const Eigen::Matrix2d& S) {
  return -0.5 * d2 - std::log(2.0 * std::numbers::pi) - 0.5 * std::log(S.determinant());
}

}  // namespace

absl::Status FastSlamOptions::Validate() const {
  if (num_particles < 1) return absl::InvalidArgumentError("num_particles must be >= 1");
  if (absl::Status s = landmarks.Validate(); !s.ok()) return s;
  if (!(resample_ess_ratio >= 0.0 && resample_ess_ratio <= 1.0)) {
    return absl::InvalidArgumentError("resample_ess_ratio must be in [0, 1]");
  }
  if (!(depletion_ess_ratio >= 0.0 && depletion_ess_ratio <= 1.0)) {
    return absl::InvalidArgumentError("depletion_ess_ratio must be in [0, 1]");
  }
  if (landmark_update_iterations < 1) {
    return absl::InvalidArgumentError("landmark_update_iterations must be >= 1");
  }
  if (!(sigma_signature >= 0.0 && std::isfinite(sigma_signature))) {
    return absl::InvalidArgumentError("sigma_signature must be finite and >= 0");
  }
  if (!(moment_matching.min_existence >= 0.0 && moment_matching.min_existence <= 1.0)) {
    return absl::InvalidArgumentError("moment_matching.min_existence must be in [0, 1]");
  }
  // Exported maps must pass LocalSubmap::Validate's conditioning test (1e-13).
  if (!(moment_matching.repair_relative_floor >= 1e-12 && moment_matching.repair_relative_floor < 1.0)) {
    return absl::InvalidArgumentError(absl::StrCat("moment_matching.repair_relative_floor must be in [1e-12, 1), got ",
                                                   moment_matching.repair_relative_floor));
  }
  if (num_threads < 0) return absl::InvalidArgumentError("num_threads must be >= 0 (0: every core)");
  if (!(sensor_yaw_sigma >= 0.0 && std::isfinite(sensor_yaw_sigma))) {
    return absl::InvalidArgumentError("sensor_yaw_sigma must be finite and >= 0");
  }
  if (absl::Status s = odometry.Validate(); !s.ok()) return s;
  if (landmarks.known_association && sample_association) {
    return absl::InvalidArgumentError("known_association and sample_association exclude each other");
  }
  return absl::OkStatus();
}

FastSlam::FastSlam(std::unique_ptr<models::MotionModel> motion, const models::RangeBearingConfig& sensor,
                   const Pose2& start, const FastSlamOptions& options)
    : motion_(std::move(motion)), sensor_(sensor), options_(options), rng_(options.seed) {
  SUBSLAM_CHECK(options_.Validate().ok()) << options_.Validate().message();
  gate_d2_ = models::ChiSquareQuantile(options_.landmarks.gate_probability, 2);
  new_landmark_d2_ = models::ChiSquareQuantile(options_.landmarks.new_landmark_probability, 2);
  log_p0_ = LogGaussian2(new_landmark_d2_, sensor_.NoiseCovariance());
  const models::RangeBearingConfig& rb = sensor_.config();
  fov_center_ = 0.5 * (rb.fov_min_rad + rb.fov_max_rad);
  const double half = 0.5 * (rb.fov_max_rad - rb.fov_min_rad) + kFovMarginRad;
  fov_cos_limit_ = half >= kPi ? -2.0 : std::cos(half);  // −2: no bearing limit
  const double half_expected = 0.5 * (rb.fov_max_rad - rb.fov_min_rad) - options_.landmarks.expect_bearing_margin_rad;
  fov_cos_expected_ = half_expected >= kPi ? -2.0 : std::cos(std::max(0.0, half_expected));
  for (const char* stage : {"predict", "associate", "update", "resample"}) times_[stage] = 0;
  const int threads = options_.num_threads > 0 ? options_.num_threads
                                               : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  pool_ = std::make_unique<WorkerPool>(std::min(threads, options_.num_particles));
  scratch_.resize(pool_->threads());
  blocks_ = std::make_unique<ParticleBlock[]>(pool_->threads());
  particle_rngs_.reserve(options_.num_particles);
  for (int p = 0; p < options_.num_particles; ++p) {
    std::seed_seq seq{options_.seed, static_cast<uint64_t>(p)};
    particle_rngs_.emplace_back(seq);
  }
  std::seed_seq yaw_seq{options_.seed, static_cast<uint64_t>(options_.num_particles)};  // a stream of its own
  yaw_rng_.seed(yaw_seq);
  Reset(start);
}

FastSlam::~FastSlam() = default;

void FastSlam::Reset(const Pose2& start) {
  // The outgoing particles' yaws, if they have seen a scan: a local map's (sensor_yaw_sigma).
  if (options_.sensor_yaw_sigma > 0.0 && counters_.scans > scans_at_reset_) {
    const YawMoments m = SensorYawMoments();
    yaw_mean_sum_ += m.mean;
    yaw_spread_sum_ += m.spread;
    ++yaw_maps_;
  }
  if (options_.odometry.enabled()) RecentreCalibration();  // before the particles go
  scans_at_reset_ = counters_.scans;
  Particle fresh;
  fresh.calibration = calibration_linearized_;  // the carried calibration (ResetCalibration)
  fresh.calibration_covariance = calibration_spread_;
  particles_.assign(options_.num_particles, fresh);
  const double log_w = -std::log(static_cast<double>(options_.num_particles));
  for (Particle& p : particles_) {
    SetPose(&p, start);
    p.log_weight = log_w;
  }
  if (options_.sensor_yaw_sigma > 0.0) {
    std::normal_distribution<double> normal(0.0, options_.sensor_yaw_sigma);
    for (Particle& p : particles_) p.sensor_yaw = normal(yaw_rng_);
  }
  pose_cache_valid_ = moments_valid_ = false;
  scan_features_.clear();
  feature_truth_.clear();
  scan_disagreement_ = 0.0;
  resample_pending_ = false;
  lineage_collapsed_ = false;
  motion_since_scan_ = Pose2();
  motion_covariance_.setZero();
  genealogy_.Reset();
}

const std::vector<Eigen::Vector2d>& FastSlam::DetectionsSeenBy(const Particle& particle, Scratch* scratch) const {
  if (options_.sensor_yaw_sigma == 0.0) return z_;
  scratch->z_seen = z_;
  for (Eigen::Vector2d& z : scratch->z_seen) z[1] = WrapAngle(z[1] + particle.sensor_yaw);
  return scratch->z_seen;
}

void FastSlam::Predict(const Eigen::Vector2d& u, double dt) {
  if (dt <= 0.0) return;
  if (resample_pending_) {
    StageTimer timer(&times_, "resample");
    Resample();
  }
  StageTimer timer(&times_, "predict");
  pose_cache_valid_ = false;
  if (options_.odometry.enabled()) {
    PredictCalibrated(u, dt);
    return;
  }
  // The motion since the last scan, shared by every particle (the models are
  // SE(2)-equivariant: f(a ∘ r, u) = a ∘ f(r, u)), so prediction is O(1), not O(N).
  Eigen::Matrix3d F;
  Matrix32d G;
  motion_since_scan_ = motion_->Predict(motion_since_scan_, u, dt, &F, &G);
  motion_covariance_ = F * motion_covariance_ * F.transpose() + G * motion_->noise().Covariance(u) * G.transpose();
}

Pose2 FastSlam::CurrentPose(const Particle& p, Eigen::Matrix3d* covariance) const {
  // p.pose ∘ r with the particle's cached cos / sin; ∂/∂r = diag(R(θ_p), 1).
  Pose2 r = motion_since_scan_;
  Eigen::Matrix3d Q = motion_covariance_;
  if (options_.odometry.enabled()) {  // r̂ + D(m_p − ĉ), Σ_r + D P_p Dᵀ
    const Eigen::Matrix3d& D = motion_calibration_jacobian_;
    const Eigen::Vector3d shift = D * (p.calibration - calibration_linearized_);
    r = Pose2(r.x + shift.x(), r.y + shift.y(), WrapAngle(r.theta + shift.z()));
    Q += D * p.calibration_covariance * D.transpose();
  }
  const double c = p.cos_theta, s = p.sin_theta;
  if (covariance != nullptr) {
    Eigen::Matrix3d J;
    J << c, -s, 0, s, c, 0, 0, 0, 1;
    *covariance = J * Q * J.transpose();
  }
  return Pose2(p.pose.x + c * r.x - s * r.y, p.pose.y + s * r.x + c * r.y, WrapAngle(p.pose.theta + r.theta));
}

void FastSlam::SetPose(Particle* p, const Pose2& pose) {
  p->pose = pose;
  p->cos_theta = std::cos(pose.theta);
  p->sin_theta = std::sin(pose.theta);
}

int FastSlam::TakeUsableDetections(const Scan& scan) {
  const models::RangeBearingConfig& rb = sensor_.config();
  z_.clear();
  signature_.clear();
  truth_.clear();
  detection_index_.clear();
  for (size_t k = 0; k < scan.detections.size(); ++k) {
    const Detection& d = scan.detections[k];
    if (d.range_m < rb.min_range_m || d.range_m > rb.max_range_m) continue;
    z_.push_back(d.z());
    signature_.push_back(d.signature);
    if (options_.landmarks.known_association) {
      // A false alarm, or an id already detected in this scan: no true landmark to pair.
      const bool repeated = d.truth_id >= 0 && std::find(truth_.begin(), truth_.end(), d.truth_id) != truth_.end();
      truth_.push_back(repeated ? kFalseAlarmId : d.truth_id);
    }
    detection_index_.push_back(static_cast<int>(k));
  }
  return static_cast<int>(z_.size());
}

void FastSlam::RecordParticleHealth() {
  last_ess_ratio_ = EffectiveSampleSizeRatio();
  counters_.min_ess_ratio = std::min(counters_.min_ess_ratio, last_ess_ratio_);
  if (last_ess_ratio_ < options_.depletion_ess_ratio) ++counters_.depleted_updates;
  const bool collapsed = num_particles() > 1 && LineageDiversity() * num_particles() < 1.5;
  if (collapsed && !lineage_collapsed_) ++counters_.lineage_collapses;
  lineage_collapsed_ = collapsed;
}

absl::Status FastSlam::Update(const Scan& scan) {
  if (absl::Status st = CheckScan(scan); !st.ok()) return st;
  if (resample_pending_) {
    StageTimer timer(&times_, "resample");
    Resample();
  }
  ++counters_.scans;
  genealogy_.AddScan();
  const int m = TakeUsableDetections(scan);
  const int P = num_particles();
  counters_.detections += m;
  if (particles_[0].lineage < 0) {
    for (int p = 0; p < P; ++p) particles_[p].lineage = p;
  }
  decisions_.assign(static_cast<size_t>(P) * m, kIgnore);
  decision_label_.assign(static_cast<size_t>(P) * m, kIgnore);
  // Both runs below use the same threads: the second updates the particles each thread
  // associated in the first.
  const int threads = thread_limit_;
  if (threads > 0 && threads < pool_->threads()) ++counters_.scans_with_fewer_threads;
  {
    StageTimer timer(&times_, "associate");
    // Each pool index takes its own contiguous block of particles first, the same block
    // every scan; as the pool offers each index to the thread that ran it before
    // (WorkerPool), a particle's records tend to stay in one core's cache (particles
    // handed out in small chunks to whichever thread is free move between cores from scan
    // to scan, which costs more than a second thread gains on machines whose cores pass
    // cache lines slowly). An index that finishes its block takes small chunks from the
    // others' (the threads do not always run at the same speed: another process may hold
    // a core). Which thread takes a particle changes nothing in the result: each slot
    // draws from its own stream.
    const int T = pool_->Active(threads);
    for (int b = 0; b < T; ++b) {
      blocks_[b].next.store(b * P / T, std::memory_order_relaxed);
      blocks_[b].end = (b + 1) * P / T;
    }
    owner_.resize(P);
    pool_->Run(
        [&](int t) {
          Scratch& scratch = scratch_[t];
          for (int k = 0; k < T; ++k) {
            ParticleBlock& block = blocks_[(t + k) % T];
            for (int begin = block.next.fetch_add(kChunk, std::memory_order_relaxed); begin < block.end;
                 begin = block.next.fetch_add(kChunk, std::memory_order_relaxed)) {
              for (int p = begin; p < std::min(block.end, begin + kChunk); ++p) {
                owner_[p] = t;
                Particle& particle = particles_[p];
                int* decisions = decisions_.data() + static_cast<size_t>(p) * m;
                UpdateParticle(&particle, DetectionsSeenBy(particle, &scratch), signature_, decisions, &scratch,
                               &particle_rngs_[p]);
                for (int j = 0; j < m; ++j) {
                  decision_label_[p * m + j] =
                      decisions[j] >= 0 ? particle.landmarks[decisions[j]].feature : decisions[j];
                }
              }
            }
          }
        },
        threads);
    for (Scratch& scratch : scratch_) {
      counters_.associated += scratch.associated;
      counters_.ignored += scratch.ignored;
      scratch.associated = scratch.ignored = 0;
    }
    pose_cache_valid_ = moments_valid_ = false;
    motion_since_scan_ = Pose2();  // every particle now holds its sampled pose
    motion_covariance_.setZero();
    Normalize();
    if (options_.odometry.enabled()) RecentreCalibration();
    RecordParticleHealth();
    Vote(m);
    std::vector<int> per_detection(scan.detections.size(), -1);
    for (int j = 0; j < m; ++j) per_detection[detection_index_[j]] = scan_features_[j];
    scan_features_.swap(per_detection);
  }
  {
    StageTimer timer(&times_, "update");
    // Each index updates the particles it has just associated (likely in its cache).
    pool_->Run(
        [&](int t) {
          for (int p = 0; p < P; ++p) {
            if (owner_[p] != t) continue;
            ApplyDecisions(&particles_[p], DetectionsSeenBy(particles_[p], &scratch_[t]), signature_,
                           decisions_.data() + static_cast<size_t>(p) * m, &scratch_[t]);
          }
        },
        threads);
    for (Scratch& scratch : scratch_) {
      counters_.landmark_copies += scratch.landmark_copies;
      counters_.landmarks_created += scratch.landmarks_created;
      counters_.landmarks_culled += scratch.landmarks_culled;
      scratch.landmark_copies = scratch.landmarks_created = scratch.landmarks_culled = 0;
    }
  }
  // Resampling is deferred to the next Predict or Update, so that pose(), Map() and a
  // local map closed now see the weighted particles rather than resampled duplicates.
  resample_pending_ = last_ess_ratio_ < options_.resample_ess_ratio;
  return absl::OkStatus();
}

int FastSlam::threads() const { return pool_->threads(); }

void FastSlam::Normalize() {
  double max_log = -INFINITY;
  for (Particle& p : particles_) {
    if (std::isnan(p.log_weight)) p.log_weight = -INFINITY;  // no weight
    max_log = std::max(max_log, p.log_weight);
  }
  if (!std::isfinite(max_log)) {  // every weight zero or NaN: uniform
    ++counters_.weight_collapses;
    const double log_w = -std::log(static_cast<double>(particles_.size()));
    for (Particle& p : particles_) p.log_weight = log_w;
    return;
  }
  double total = 0.0;
  for (const Particle& p : particles_) total += std::exp(p.log_weight - max_log);
  const double log_total = max_log + std::log(total);
  for (Particle& p : particles_) p.log_weight -= log_total;
}

double FastSlam::LineageDiversity() const {
  if (particles_[0].lineage < 0) return 1.0;
  lineage_seen_.assign(particles_.size(), 0);
  int distinct = 0;
  for (const Particle& p : particles_) {
    if (!lineage_seen_[p.lineage]) {
      lineage_seen_[p.lineage] = 1;
      ++distinct;
    }
  }
  return static_cast<double>(distinct) / num_particles();
}

double FastSlam::SharedAncestry() const {
  ancestry_weights_.resize(particles_.size());
  for (size_t p = 0; p < particles_.size(); ++p) ancestry_weights_[p] = std::exp(particles_[p].log_weight);
  const double R = genealogy_.SharedAncestry(ancestry_weights_);
  // R = 1: every particle is a copy of one, so the spread is zero and needs no scaling.
  return R < 1.0 - 1e-12 ? R : 0.0;
}

double FastSlam::EffectiveSampleSizeRatio() const {
  double sum_sq = 0.0;
  for (const Particle& p : particles_) sum_sq += std::exp(2.0 * p.log_weight);
  return 1.0 / (sum_sq * num_particles());
}

FastSlam::YawMoments FastSlam::SensorYawMoments() const {
  YawMoments m;
  double second = 0.0;
  for (const Particle& p : particles_) m.mean += std::exp(p.log_weight) * p.sensor_yaw;
  for (const Particle& p : particles_)
    second += std::exp(p.log_weight) * (p.sensor_yaw - m.mean) * (p.sensor_yaw - m.mean);
  m.spread = std::sqrt(second);
  return m;
}

void FastSlam::Resample() {
  const int P = num_particles();
  std::uniform_real_distribution<double> uniform(0.0, 1.0 / P);
  const double u0 = uniform(rng_);
  resampled_.resize(P);
  parent_.resize(P);
  double cumulative = std::exp(particles_[0].log_weight);
  int source = 0;
  for (int i = 0; i < P; ++i) {
    const double u = u0 + static_cast<double>(i) / P;
    while (u > cumulative && source + 1 < P) cumulative += std::exp(particles_[++source].log_weight);
    parent_[i] = source;
  }
  // Copied (landmark pointers, not landmarks) by the pool index whose block of particles
  // each copy falls in (Update()), so that a particle's records are written where they
  // will be updated.
  const int threads = pool_->Active(thread_limit_);
  pool_->Run(
      [&](int t) {
        for (int i = t * P / threads; i < (t + 1) * P / threads; ++i) resampled_[i] = particles_[parent_[i]];
      },
      threads);
  particles_.swap(resampled_);
  genealogy_.AddResampling(parent_);
  resample_pending_ = false;
  pose_cache_valid_ = moments_valid_ = false;
  const double log_w = -std::log(static_cast<double>(P));
  for (Particle& p : particles_) p.log_weight = log_w;
  ++counters_.resamples;
}

void FastSlam::UpdateMoments() const {
  if (moments_valid_) return;
  // The particles at the last scan, about the heaviest one (for precision), as the sums
  // UpdatePoseCache() needs for any motion r since the scan.
  size_t heaviest = 0;
  for (size_t p = 1; p < particles_.size(); ++p) {
    if (particles_[p].log_weight > particles_[heaviest].log_weight) heaviest = p;
  }
  ParticleMoments& m = moments_;
  m = ParticleMoments{};
  m.origin = particles_[heaviest].pose;
  for (const Particle& p : particles_) {
    const double w = std::exp(p.log_weight);
    const Eigen::Vector3d a(p.pose.x - m.origin.x, p.pose.y - m.origin.y, WrapAngle(p.pose.theta - m.origin.theta));
    const double c = p.cos_theta, s = p.sin_theta;
    m.w += w;
    m.a += w * a;
    m.aa += w * a * a.transpose();
    m.c += w * c;
    m.s += w * s;
    m.cc += w * c * c;
    m.ss += w * s * s;
    m.cs += w * c * s;
    m.ac += w * c * a;
    m.as += w * s * a;
  }
  if (options_.correct_shared_ancestry) m.spread_scale = SharedAncestrySpreadScale(SharedAncestry());
  moments_valid_ = true;
}

void FastSlam::UpdatePoseCache() const {
  if (pose_cache_valid_) return;
  UpdateMoments();
  const ParticleMoments& m = moments_;
  // Particle p is now at its scan pose ∘ r (r, Σ_r shared): relative to the origin,
  // v_p = a_p + c_p e1 + s_p e2 with e1 = (r_x, r_y, 0), e2 = (−r_y, r_x, 0) (headings about
  // the origin's do not change with r), and its covariance is J_p Σ_r J_pᵀ with
  // J_p = c_p K1 + s_p K2 + K3. The weighted first and second moments are therefore
  // fixed combinations of the per-scan sums: O(1) per step instead of O(N).
  const Pose2& r = motion_since_scan_;
  const Eigen::Vector3d e1(r.x, r.y, 0.0), e2(-r.y, r.x, 0.0);
  const Eigen::Vector3d mean = (m.a + m.c * e1 + m.s * e2) / m.w;
  Eigen::Matrix3d second = m.aa + m.ac * e1.transpose() + e1 * m.ac.transpose() + m.as * e2.transpose() +
                           e2 * m.as.transpose() + m.cc * e1 * e1.transpose() + m.ss * e2 * e2.transpose() +
                           m.cs * (e1 * e2.transpose() + e2 * e1.transpose());
  Eigen::Matrix3d K1 = Eigen::Matrix3d::Zero(), K2 = Eigen::Matrix3d::Zero(), K3 = Eigen::Matrix3d::Zero();
  K1(0, 0) = K1(1, 1) = 1.0;
  K2(0, 1) = -1.0;
  K2(1, 0) = 1.0;
  K3(2, 2) = 1.0;
  Eigen::Matrix3d Q = motion_covariance_;
  if (options_.odometry.enabled()) {
    Q += motion_calibration_jacobian_ * calibration_spread_ * motion_calibration_jacobian_.transpose();
  }
  // The particles' spread (corrected for their shared ancestry), then their own
  // covariances J_p Σ_r J_pᵀ.
  cached_pose_covariance_ = m.spread_scale * (second / m.w - mean * mean.transpose());
  second.setZero();
  second += m.cc * K1 * Q * K1.transpose() + m.ss * K2 * Q * K2.transpose() +
            m.cs * (K1 * Q * K2.transpose() + K2 * Q * K1.transpose()) +
            m.c * (K1 * Q * K3.transpose() + K3 * Q * K1.transpose()) +
            m.s * (K2 * Q * K3.transpose() + K3 * Q * K2.transpose()) + m.w * K3 * Q * K3.transpose();
  cached_pose_covariance_ += second / m.w;
  // Back to the world: the origin's position, and its heading moved by r_θ.
  cached_pose_ = Pose2(m.origin.x + mean.x(), m.origin.y + mean.y(), WrapAngle(m.origin.theta + r.theta + mean.z()));
  cached_pose_covariance_ = 0.5 * (cached_pose_covariance_ + cached_pose_covariance_.transpose()).eval();
  pose_cache_valid_ = true;
}

Pose2 FastSlam::pose() const {
  UpdatePoseCache();
  return cached_pose_;
}

Eigen::Matrix3d FastSlam::pose_covariance() const {
  UpdatePoseCache();
  return cached_pose_covariance_;
}

std::vector<ParticleHypothesis> FastSlam::Hypotheses() const {
  std::vector<ParticleHypothesis> out(particles_.size());
  for (size_t p = 0; p < particles_.size(); ++p) {
    const Particle& particle = particles_[p];
    out[p].weight = std::exp(particle.log_weight);
    out[p].pose = CurrentPose(particle, &out[p].pose_covariance);
    out[p].features.reserve(particle.landmarks.size());
    for (const LandmarkRecord& r : particle.landmarks) {
      const LandmarkGaussian& l = *r.gaussian;
      out[p].features.push_back(
          {r.feature, l.mean, l.covariance, r.existence,
           l.signatures > 0 ? l.signature_sum / l.signatures : std::numeric_limits<double>::quiet_NaN()});
    }
  }
  return out;
}

MomentMatchedGaussian FastSlam::MomentMatched() const {
  const std::vector<ParticleHypothesis> h = Hypotheses();
  MomentMatchedGaussian g =
      MomentMatch(h, options_.moment_matching, options_.correct_shared_ancestry ? SharedAncestry() : 0.0);
  if (options_.landmarks.known_association) {
    g.truth_id.reserve(g.features.size());
    for (int f : g.features) {
      const auto it = feature_truth_.find(f);
      g.truth_id.push_back(it == feature_truth_.end() ? -1 : it->second);
    }
  }
  return g;
}

std::vector<LandmarkEstimate> FastSlam::Map() const {
  const MomentMatchedGaussian g = MomentMatched();
  std::vector<LandmarkEstimate> out;
  for (size_t k = 0; k < g.features.size(); ++k) {
    const int o = 3 + 2 * static_cast<int>(k);
    out.push_back({g.features[k], g.mean.segment<2>(o), g.covariance.block<2, 2>(o, o)});
  }
  return out;
}

FastSlam::FeatureCounts FastSlam::ConfirmedFeatureCounts() const {
  size_t heaviest = 0;
  for (size_t p = 1; p < particles_.size(); ++p) {
    if (particles_[p].log_weight > particles_[heaviest].log_weight) heaviest = p;
  }
  const Particle& particle = particles_[heaviest];
  const double range = sensor_.config().max_range_m;
  const Eigen::Vector2d position = CurrentPose(particle).translation();
  FeatureCounts counts;
  features_scratch_.clear();
  for (const LandmarkRecord& r : particle.landmarks) {
    if (!r.confirmed) continue;
    features_scratch_.push_back(r.feature);
    if ((r.gaussian->mean - position).squaredNorm() <= range * range) {
      ++counts.within_range;
    }
  }
  std::sort(features_scratch_.begin(), features_scratch_.end());
  counts.total =
      static_cast<int>(std::unique(features_scratch_.begin(), features_scratch_.end()) - features_scratch_.begin());
  return counts;
}

std::map<std::string, double> FastSlam::Counters() const {
  double landmarks = 0;
  for (const Particle& p : particles_) landmarks += static_cast<double>(p.landmarks.size());
  std::map<std::string, double> out = {{"scans", counters_.scans},
                                       {"detections", counters_.detections},
                                       {"particles", num_particles()},
                                       {"resamples", counters_.resamples},
                                       {"associated_all_particles", counters_.associated},
                                       {"ignored_all_particles", counters_.ignored},
                                       {"landmarks_created_all_particles", counters_.landmarks_created},
                                       {"landmarks_culled_all_particles", counters_.landmarks_culled},
                                       {"landmark_copies", counters_.landmark_copies},
                                       {"common_features_issued", counters_.features},
                                       {"scans_with_fewer_threads", counters_.scans_with_fewer_threads},
                                       {"min_ess_ratio", counters_.min_ess_ratio},
                                       {"depleted_updates", counters_.depleted_updates},
                                       {"lineage_collapses", counters_.lineage_collapses},
                                       {"weight_collapses", counters_.weight_collapses},
                                       {"mean_landmarks_per_particle", landmarks / num_particles()}};
  if (options_.odometry.enabled()) odometry_calibration().AddCounters(&out);
  if (options_.sensor_yaw_sigma > 0.0) {
    // Averaged over the particle sets closed by Reset() (local maps); without any, the
    // current particles (a single-map run).
    const YawMoments now = SensorYawMoments();
    out["sensor_yaw_mean"] = yaw_maps_ > 0 ? yaw_mean_sum_ / yaw_maps_ : now.mean;
    out["sensor_yaw_spread"] = yaw_maps_ > 0 ? yaw_spread_sum_ / yaw_maps_ : now.spread;
  }
  return out;
}

}  // namespace subslam::frontend
