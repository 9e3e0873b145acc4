// FastSlam: one particle's scan update — association (maximum likelihood or sampled), the
// FastSLAM 2.0 proposal and importance weight, existence, the correspondence votes, and
// the landmark updates that apply the decisions.

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
#include "subslam/frontend/fastslam.h"
#include "subslam/frontend/genealogy.h"
#include "subslam/frontend/internal/worker_pool.h"
#include "subslam/models/gating.h"

namespace subslam::frontend {

void FastSlam::UpdateExistence(LandmarkRecord* record, bool detected) const {
  record->existence = options_.landmarks.UpdatedExistence(record->existence, detected);
  if (options_.landmarks.existence.Confirms(record->existence)) record->confirmed = true;
}

FastSlam::LandmarkGaussian* FastSlam::Mutable(LandmarkRecord* record, Scratch* scratch) {
  if (record->gaussian.use_count() > 1) {
    record->gaussian = std::make_shared<const LandmarkGaussian>(*record->gaussian);
    ++scratch->landmark_copies;
  } else {
    // Sole owner now — possibly because a particle on another thread has just copied the
    // landmark and dropped its reference: the acquire fence orders that thread's reads of
    // the old value (before its release of the count) before our writes.
    std::atomic_thread_fence(std::memory_order_acquire);
  }
  // Sole owner: the object was created non-const, so writing through it is defined.
  return const_cast<LandmarkGaussian*>(record->gaussian.get());
}

FastSlam::PairScore FastSlam::Score(const Prediction& pr, const LandmarkGaussian& landmark, const Eigen::Vector2d& z,
                                    double signature, const Eigen::Vector3d& delta,
                                    const Eigen::Matrix3d& Sigma) const {
  PairScore out;
  out.nu = models::RangeBearingModel::Difference(z, pr.z) - pr.H_pose * delta;
  out.nu[1] = WrapAngle(out.nu[1]);
  out.S = pr.H_pose * Sigma * pr.H_pose.transpose() + pr.Z;
  out.det = out.S(0, 0) * out.S(1, 1) - out.S(0, 1) * out.S(1, 0);
  SUBSLAM_CHECK(out.S(0, 0) > 0.0 && out.det > 0.0) << "predictive covariance not positive definite";
  out.S_inv << out.S(1, 1), -out.S(0, 1), -out.S(1, 0), out.S(0, 0);
  out.S_inv /= out.det;
  out.d2 = out.nu.dot(out.S_inv * out.nu);
  // log N(ν; 0, S) without its −½ log det S, which callers add (or accumulate as a
  // product of determinants, one log per particle and scan).
  out.log_likelihood_but_det =
      -0.5 * out.d2 - std::log(2.0 * std::numbers::pi) + SignatureLogLikelihood(landmark, signature);
  return out;
}

double FastSlam::SignatureLogLikelihood(const LandmarkGaussian& l, double signature) const {
  if (!(options_.sigma_signature > 0) || !std::isfinite(signature) || l.signatures == 0) return 0.0;
  const double var = options_.sigma_signature * options_.sigma_signature * (1.0 + 1.0 / l.signatures);
  const double ds = signature - l.signature_sum / l.signatures;
  return -0.5 * ds * ds / var - 0.5 * std::log(2.0 * std::numbers::pi * var);
}

// One particle's scan update (FastSLAM 2.0), phase by phase: the landmarks in reach and
// their predictions, the pairing of detections with them (by true id, maximum likelihood
// or sampled), the proposal N(x0 ⊕ δ, Σ) updated by each pairing in turn with the
// particle's importance weight, the unexplained detections' weight, and the pose drawn
// from the proposal.
class FastSlam::ScanUpdate {
 public:
  ScanUpdate(const FastSlam& filter, Particle* particle, const std::vector<Eigen::Vector2d>& z,
             const std::vector<double>& signature, int* decisions, Scratch* scratch, std::mt19937_64* rng)
      : f_(filter),
        o_(filter.options_),
        particle_(particle),
        z_(z),
        signature_(signature),
        decisions_(decisions),
        scratch_(scratch),
        rng_(rng),
        predictions_(scratch->predictions),
        R_(filter.sensor_.NoiseCovariance()),
        n_(static_cast<int>(particle->landmarks.size())),
        m_(static_cast<int>(z.size())) {
    x0_ = f_.CurrentPose(*particle_, &Sigma_);
    predictions_.resize(n_);
  }

  // The landmarks in reach — within range and the field of view widened by kFovMarginRad,
  // culled cheaply before the atan2 of a bearing — their predicted range and covariance,
  // and whether each is expected (a miss counts).
  void PredictLandmarksInReach() {
    const double reach = f_.sensor_.config().max_range_m + 10.0;
    const double c_axis = std::cos(x0_.theta + f_.fov_center_), s_axis = std::sin(x0_.theta + f_.fov_center_);
    const models::RangeBearingConfig& rb = f_.sensor_.config();
    for (int i = 0; i < n_; ++i) {
      Prediction& pr = predictions_[i];
      const LandmarkGaussian& l = *particle_->landmarks[i].gaussian;
      pr.used = pr.gated = false;
      const Eigen::Vector2d d = l.mean - x0_.translation();
      const double d2 = d.squaredNorm();
      const double along = c_axis * d.x() + s_axis * d.y(), distance = std::sqrt(d2);
      pr.in_reach = d2 < reach * reach && along >= f_.fov_cos_limit_ * distance;
      if (!pr.in_reach) continue;
      // Expected (for the missed-detection update): well inside range and field of view,
      // tested on the cosine of the bearing off the field of view's centre.
      pr.expected = distance >= rb.min_range_m + o_.landmarks.expect_range_margin_m &&
                    distance <= rb.max_range_m - o_.landmarks.expect_range_margin_m &&
                    along >= f_.fov_cos_expected_ * distance;
      Predict(i);
    }
  }

  // Known association: detection j belongs to the particle's landmark with its true id
  // (predicted even if the particle believes it out of reach), or starts one; a false
  // alarm or a repeated id (truth_ −1, see Update) is ignored.
  void PairByTruthIds() {
    for (int j = 0; j < m_; ++j) {
      decisions_[j] = f_.truth_[j] < 0 ? kIgnore : kNew;
      if (decisions_[j] == kIgnore) continue;
      for (int i = 0; i < n_; ++i) {
        if (particle_->landmarks[i].gaussian->truth_id != f_.truth_[j]) continue;
        decisions_[j] = i;
        if (!predictions_[i].in_reach) {
          predictions_[i].in_reach = true;
          predictions_[i].expected = false;
          Predict(i);
        }
        break;
      }
    }
  }

  // Every (detection, landmark) pair is scored at the prior proposal, where S depends on
  // the landmark only: one 2×2 inverse per landmark, a few flops per pair.
  void PrepareScores() {
    for (int i = 0; i < n_; ++i) {
      Prediction& pr = predictions_[i];
      if (!pr.in_reach) continue;
      pr.S = pr.H_pose * Sigma_ * pr.H_pose.transpose() + pr.Z;
      const double det = pr.S.determinant();
      SUBSLAM_CHECK(det > 0.0) << "predictive covariance not positive definite";
      pr.S_inv = pr.S.inverse();
      pr.log_norm = NAN;  // computed when a pair gates
      pr.det = det;
    }
    scratch_->min_d2.assign(m_, INFINITY);
    scratch_->near_pairs.clear();
    scratch_->pairs.clear();
  }

  // Known association: the given pairings in detection order, each scored at the current
  // proposal.
  void AssociateTruthPairs() {
    for (int j = 0; j < m_; ++j) {
      const int i = decisions_[j];
      if (i < 0) continue;
      PredictBearing(i);
      predictions_[i].gated = true;
      Associate(j, i);
    }
  }

  // The gated pairs, ranked by `association_score`; the pairs within the new-landmark
  // gate (`near_pairs`) for the weight of detections left unexplained.
  void RankGatedPairs() {
    std::vector<double>& min_d2 = scratch_->min_d2;
    for (int j = 0; j < m_; ++j) {
      decisions_[j] = kIgnore;
      for (int i = 0; i < n_; ++i) {
        Prediction& pr = predictions_[i];
        if (!pr.in_reach) continue;
        // νᵀS⁻¹ν ≥ ν_r² / S_rr: most pairs are rejected on range alone.
        const double nu_r = z_[j][0] - pr.z[0];
        if (nu_r * nu_r >= f_.new_landmark_d2_ * pr.S(0, 0)) continue;
        PredictBearing(i);
        const Eigen::Vector2d nu = models::RangeBearingModel::Difference(z_[j], pr.z);
        const double d2 = nu.dot(pr.S_inv * nu);
        min_d2[j] = std::min(min_d2[j], d2);
        if (d2 >= f_.new_landmark_d2_) continue;
        pr.gated = true;
        if (std::isnan(pr.log_norm)) {
          pr.log_norm = -std::log(2.0 * std::numbers::pi) - 0.5 * std::log(pr.det);
        }
        const double ll =
            pr.log_norm - 0.5 * d2 + f_.SignatureLogLikelihood(*particle_->landmarks[i].gaussian, signature_[j]);
        scratch_->near_pairs.push_back({ll, j, i});
        if (d2 >= f_.gate_d2_) continue;
        const double rank = o_.association_score == AssociationScore::kLikelihood ? ll : -d2;
        scratch_->pairs.push_back({rank, j, i});
      }
    }
  }

  // One-to-one greedy assignment, best pair first; the proposal updates in that order,
  // each pair rescored at the current proposal for the weight.
  void AssignGreedily() {
    std::vector<GatedPair>& pairs = scratch_->pairs;
    std::sort(pairs.begin(), pairs.end(), [](const GatedPair& a, const GatedPair& b) {
      return a.rank > b.rank || (a.rank == b.rank && (a.detection < b.detection ||
                                                      (a.detection == b.detection && a.landmark < b.landmark)));
    });
    for (const GatedPair& p : pairs) {
      if (decisions_[p.detection] >= 0 || predictions_[p.landmark].used) continue;
      Associate(p.detection, p.landmark);
    }
  }

  // Data-association sampling, detection by detection: among the still unused gated
  // landmarks and "new", in proportion to their likelihoods at the current proposal.
  void SampleAssociations() {
    std::vector<std::pair<int, double>>& likelihoods = scratch_->likelihoods;
    for (int j = 0; j < m_; ++j) {
      likelihoods.clear();
      double max_ll = f_.log_p0_;
      for (const GatedPair& p : scratch_->pairs) {
        if (p.detection != j || predictions_[p.landmark].used) continue;
        const PairScore score = f_.Score(predictions_[p.landmark], *particle_->landmarks[p.landmark].gaussian, z_[j],
                                         signature_[j], delta_, Sigma_);
        if (score.d2 >= f_.gate_d2_) continue;
        const double ll = score.log_likelihood_but_det - 0.5 * std::log(score.det);
        likelihoods.push_back({p.landmark, ll});
        max_ll = std::max(max_ll, ll);
      }
      if (likelihoods.empty()) continue;
      double total = std::exp(f_.log_p0_ - max_ll);
      for (const auto& [i, ll] : likelihoods) total += std::exp(ll - max_ll);
      double r = std::uniform_real_distribution<double>(0.0, total)(*rng_);
      for (const auto& [i, ll] : likelihoods) {
        r -= std::exp(ll - max_ll);
        if (r < 0) {
          Associate(j, i);
          break;
        }
      }
      if (decisions_[j] < 0) decisions_[j] = kNew;  // sampled "new" although something gated
    }
  }

  // Unexplained detections: a new landmark beyond the new-landmark gate of every
  // landmark, with the density p0; otherwise ignored, with the likelihood of its most
  // likely landmark that no other detection took (at least p0, which is also what a
  // false alarm or a sampled "new" gets).
  void ScoreUnexplained() {
    log_w_ -= 0.5 * std::log(det_product_);
    for (int j = 0; j < m_; ++j) {
      if (decisions_[j] >= 0) continue;
      if (decisions_[j] != kNew && !o_.landmarks.known_association) {
        decisions_[j] = scratch_->min_d2[j] > f_.new_landmark_d2_ ? kNew : kIgnore;
      }
      double log_density = f_.log_p0_;
      if (decisions_[j] == kIgnore && !o_.landmarks.known_association) {
        for (const GatedPair& p : scratch_->near_pairs) {
          if (p.detection == j && !predictions_[p.landmark].used) log_density = std::max(log_density, p.rank);
        }
      }
      log_w_ += log_density;
      if (decisions_[j] == kIgnore) ++scratch_->ignored;
    }
  }

  // The pose drawn from the proposal, the landmarks expected but missed — predicted well
  // inside the field of view (at the prior pose: the sample moves it by centimetres) and
  // not even within the new-landmark gate of any detection — and the weight.
  void SamplePoseAndFinish() {
    Eigen::Vector3d x = x0_.vector() + delta_;
    if (Sigma_.trace() > 0.0) {
      std::normal_distribution<double> normal;
      const Eigen::Vector3d xi(normal(*rng_), normal(*rng_), normal(*rng_));
      const Eigen::LLT<Eigen::Matrix3d> llt(Sigma_);
      if (llt.info() == Eigen::Success) {
        x += llt.matrixL() * xi;
      } else {  // positive semi-definite (e.g. no noise on one axis)
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
        eig.computeDirect(Sigma_);
        x += eig.eigenvectors() * (eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().cwiseProduct(xi));
      }
    }
    for (int i = 0; i < n_; ++i) {
      const Prediction& pr = predictions_[i];
      particle_->landmarks[i].missed = pr.in_reach && !pr.gated && pr.expected;
    }
    const Pose2 previous = particle_->pose;
    SetPose(particle_, Pose2(x[0], x[1], WrapAngle(x[2])));
    if (o_.odometry.enabled()) f_.UpdateCalibration(particle_, previous);
    particle_->log_weight += log_w_;
  }

 private:
  // Landmark i's predicted range, its Jacobians and the predictive covariance without the
  // pose; the bearing (an atan2) waits for PredictBearing, for pairs that pass the range gate.
  void Predict(int i) {
    Prediction& pr = predictions_[i];
    const LandmarkGaussian& l = *particle_->landmarks[i].gaussian;
    Eigen::Matrix2d H_l;
    pr.z[0] = f_.sensor_.ObserveRange(x0_, l.mean, &pr.H_pose, &H_l);
    pr.z[1] = NAN;
    pr.Z = H_l * l.covariance * H_l.transpose() + R_;
  }
  void PredictBearing(int i) {
    Prediction& pr = predictions_[i];
    if (std::isnan(pr.z[1])) pr.z[1] = models::RangeBearingModel::Bearing(x0_, particle_->landmarks[i].gaussian->mean);
  }
  // Pairs detection j with landmark i, scored at the current proposal for the weight, and
  // updates the proposal with it.
  void Associate(int j, int i) {
    Prediction& pr = predictions_[i];
    const PairScore score = f_.Score(pr, *particle_->landmarks[i].gaussian, z_[j], signature_[j], delta_, Sigma_);
    pr.used = true;
    decisions_[j] = i;
    log_w_ += score.log_likelihood_but_det;
    det_product_ *= score.det;
    if (det_product_ < 1e-200 || det_product_ > 1e200) {
      log_w_ -= 0.5 * std::log(det_product_);
      det_product_ = 1.0;
    }
    const Eigen::Matrix<double, 3, 2> K = Sigma_ * pr.H_pose.transpose() * score.S_inv;
    delta_ += K * score.nu;
    Sigma_ -= K * pr.H_pose * Sigma_;
    Sigma_ = 0.5 * (Sigma_ + Sigma_.transpose()).eval();
    ++scratch_->associated;
  }

  const FastSlam& f_;
  const FastSlamOptions& o_;
  Particle* particle_;
  const std::vector<Eigen::Vector2d>& z_;
  const std::vector<double>& signature_;
  int* decisions_;
  Scratch* scratch_;
  std::mt19937_64* rng_;
  std::vector<Prediction>& predictions_;
  const Eigen::Matrix2d R_;
  const int n_, m_;
  Pose2 x0_;
  Eigen::Matrix3d Sigma_;                            // of the proposal
  Eigen::Vector3d delta_ = Eigen::Vector3d::Zero();  // its shift from x0
  double log_w_ = 0.0;
  double det_product_ = 1.0;  // of the associated pairs' S, folded into log_w at the end
};

void FastSlam::UpdateParticle(Particle* particle, const std::vector<Eigen::Vector2d>& z,
                              const std::vector<double>& signature, int* decisions, Scratch* scratch,
                              std::mt19937_64* rng) const {
  ScanUpdate update(*this, particle, z, signature, decisions, scratch, rng);
  update.PredictLandmarksInReach();
  if (options_.landmarks.known_association) update.PairByTruthIds();
  update.PrepareScores();
  if (options_.landmarks.known_association) {
    update.AssociateTruthPairs();
  } else {
    update.RankGatedPairs();
    if (options_.sample_association) {
      update.SampleAssociations();
    } else {
      update.AssignGreedily();
    }
  }
  update.ScoreUnexplained();
  update.SamplePoseAndFinish();
}

void FastSlam::Vote(int m) {
  const int P = num_particles();
  scan_features_.assign(m, -1);
  voted_label_.assign(2 * m, kIgnore);  // [2j]: for modified landmarks, [2j+1]: for created
  scan_disagreement_ = 0.0;
  weights_.resize(P);
  for (int p = 0; p < P; ++p) weights_[p] = std::exp(particles_[p].log_weight);
  for (int j = 0; j < m; ++j) {
    tally_.clear();
    for (int p = 0; p < P; ++p) {
      const int label = decision_label_[p * m + j];
      const double w = weights_[p];
      auto it = std::find_if(tally_.begin(), tally_.end(), [label](const auto& t) { return t.first == label; });
      if (it == tally_.end()) {
        tally_.push_back({label, w});
      } else {
        it->second += w;
      }
    }
    const auto winner = std::max_element(tally_.begin(), tally_.end(), [](const auto& a, const auto& b) {
      return a.second < b.second || (a.second == b.second && a.first > b.first);
    });
    double total = 0.0;
    for (const auto& t : tally_) total += t.second;
    scan_disagreement_ = std::max(scan_disagreement_, 1.0 - winner->second / total);
    int label = winner->first;
    if (label == kNew) {
      label = next_feature_++;
      ++counters_.features;
    }
    if (label >= 0) {
      voted_label_[2 * j] = voted_label_[2 * j + 1] = label;
      scan_features_[j] = label;
      if (options_.landmarks.known_association) feature_truth_[label] = truth_[j];
    } else {
      // Winner "ignore": landmarks that particles created anyway get a fresh minority id.
      const bool created = std::any_of(tally_.begin(), tally_.end(), [](const auto& t) { return t.first == kNew; });
      if (created) {
        voted_label_[2 * j + 1] = next_feature_++;
        ++counters_.features;
      }
    }
  }
}

void FastSlam::ApplyDecisions(Particle* particle, const std::vector<Eigen::Vector2d>& z,
                              const std::vector<double>& signature, const int* decisions, Scratch* scratch) const {
  const Eigen::Matrix2d R = sensor_.NoiseCovariance();
  const Pose2& x = particle->pose;
  const int m = static_cast<int>(z.size());
  const int n_before = static_cast<int>(particle->landmarks.size());
  std::vector<LandmarkRecord>& landmarks = particle->landmarks;
  for (int j = 0; j < m; ++j) {
    const int d = decisions[j];
    if (d >= 0) {
      LandmarkRecord& record = landmarks[d];
      LandmarkGaussian* l = Mutable(&record, scratch);
      // Iterated EKF: relinearise the measurement at the updated landmark mean.
      const Eigen::Vector2d prior_mean = l->mean;
      const Eigen::Matrix2d prior_cov = l->covariance;
      Eigen::Vector2d mean = prior_mean;
      Eigen::Matrix2d H_l, K;
      for (int it = 0; it < options_.landmark_update_iterations; ++it) {
        const Eigen::Vector2d z_hat = sensor_.Observe(x, mean, nullptr, &H_l);
        Eigen::Vector2d nu = models::RangeBearingModel::Difference(z[j], z_hat);
        nu += H_l * (mean - prior_mean);
        nu[1] = WrapAngle(nu[1]);
        const Eigen::Matrix2d S = H_l * prior_cov * H_l.transpose() + R;
        K = prior_cov * H_l.transpose() * S.inverse();
        const Eigen::Vector2d next = prior_mean + K * nu;
        const bool converged = (next - mean).squaredNorm() < 1e-16;
        mean = next;
        if (converged) break;
      }
      l->mean = mean;
      l->covariance = prior_cov - K * H_l * prior_cov;
      l->covariance = 0.5 * (l->covariance + l->covariance.transpose()).eval();
      if (std::isfinite(signature[j])) {
        l->signature_sum += signature[j];
        ++l->signatures;
      }
      UpdateExistence(&record, true);
      if (voted_label_[2 * j] != kIgnore) record.feature = voted_label_[2 * j];
    } else if (d == kNew) {
      auto l = std::make_shared<LandmarkGaussian>();
      if (options_.landmarks.known_association) l->truth_id = truth_[j];
      Eigen::Matrix2d G_z;
      l->mean = sensor_.InverseObserve(x, z[j], nullptr, &G_z);
      l->covariance = G_z * R * G_z.transpose();
      if (std::isfinite(signature[j])) {
        l->signature_sum = signature[j];
        l->signatures = 1;
      }
      LandmarkRecord record;
      record.gaussian = std::move(l);
      record.existence = options_.landmarks.existence.Initial();  // the prior and the creating detection
      record.confirmed = options_.landmarks.existence.Confirms(record.existence);
      record.feature = voted_label_[2 * j + 1];
      landmarks.push_back(std::move(record));
      ++scratch->landmarks_created;
    }
  }
  // Expected but missed (flagged by UpdateParticle): the missed-detection update.
  for (int i = 0; i < n_before; ++i) {
    if (landmarks[i].missed) UpdateExistence(&landmarks[i], false);
  }
  // Known association settles existence too (every landmark has a true id): no cull, so
  // a true landmark keeps its one landmark and common id.
  if (counters_.scans % options_.landmarks.cull_every_scans == 0 && !options_.landmarks.known_association) {
    const auto doomed = [this](const LandmarkRecord& r) {
      return options_.landmarks.existence.Deletes(r.existence, r.confirmed);
    };
    const auto first = std::remove_if(landmarks.begin(), landmarks.end(), doomed);
    scratch->landmarks_culled += landmarks.end() - first;
    landmarks.erase(first, landmarks.end());
  }
}

}  // namespace subslam::frontend
