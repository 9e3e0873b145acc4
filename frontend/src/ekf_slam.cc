#include "subslam/frontend/ekf_slam.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "absl/strings/str_cat.h"
#include "subslam/core/check.h"
#include "subslam/core/stage_timer.h"
#include "subslam/frontend/internal/single_map_common.h"
#include "subslam/models/gating.h"

namespace subslam::frontend {
absl::Status EkfSlamOptions::Validate() const {
  if (jcbb_max_nodes < 1) return absl::InvalidArgumentError("jcbb_max_nodes must be >= 1");
  if (absl::Status s = innovation_test.Validate(); !s.ok()) return s;
  if (absl::Status s = odometry.Validate(); !s.ok()) return s;
  return landmarks.Validate();
}

EkfSlam::EkfSlam(std::unique_ptr<models::MotionModel> motion, const models::RangeBearingConfig& sensor,
                 const Pose2& initial_pose, const EkfSlamOptions& options,
                 const Eigen::Matrix3d& initial_pose_covariance)
    : motion_(std::move(motion)), sensor_(sensor), options_(options), innovation_monitor_(options.innovation_test) {
  SUBSLAM_CHECK(options_.Validate().ok()) << options_.Validate().message();
  gate_d2_ = models::ChiSquareQuantile(options_.landmarks.gate_probability, 2);
  new_landmark_d2_ = models::ChiSquareQuantile(options_.landmarks.new_landmark_probability, 2);
  vehicle_dim_ = dim_ = options_.odometry.enabled() ? 6 : 3;
  x_.setZero(vehicle_dim_ + 2 * 64);
  P_.setZero(vehicle_dim_ + 2 * 64, vehicle_dim_ + 2 * 64);
  x_.head<3>() = initial_pose.vector();
  P_.topLeftCorner<3, 3>() = 0.5 * (initial_pose_covariance + initial_pose_covariance.transpose());
  if (options_.odometry.enabled()) {
    x_.segment<3>(3) = options_.odometry.PriorMean();
    P_.block<3, 3>(3, 3) = options_.odometry.PriorCovariance();
  }
  for (const char* stage : {"predict", "associate", "update", "map_management"}) times_[stage] = 0;
}

void EkfSlam::Reserve(int dim) {
  const int capacity = static_cast<int>(x_.size());
  if (dim <= capacity) return;
  const int new_capacity = std::max(dim, 2 * capacity);
  Eigen::VectorXd x(new_capacity);
  Eigen::MatrixXd P(new_capacity, new_capacity);
  x.head(dim_) = x_.head(dim_);
  P.topLeftCorner(dim_, dim_) = P_.topLeftCorner(dim_, dim_);
  x_.swap(x);
  P_.swap(P);
}

Pose2 EkfSlam::pose() const { return Pose2::FromVector(x_.head<3>()); }
Eigen::Matrix3d EkfSlam::pose_covariance() const { return P_.topLeftCorner<3, 3>(); }

void EkfSlam::Predict(const Eigen::Vector2d& u, double dt) {
  if (dt <= 0.0) return;
  StageTimer timer(&times_, "predict");
  if (options_.odometry.enabled()) {
    PredictCalibrated(u, dt);
    return;
  }
  Eigen::Matrix3d F;
  Matrix32d G;
  const Pose2 next = motion_->Predict(pose(), u, dt, &F, &G);
  x_.head<3>() = next.vector();
  const int n = dim_ - 3;
  P_.topLeftCorner<3, 3>() =
      F * P_.topLeftCorner<3, 3>() * F.transpose() + G * motion_->noise().Covariance(u) * G.transpose();
  if (n > 0) {
    const Eigen::Matrix<double, 3, Eigen::Dynamic> cross = F * P_.block(0, 3, 3, n);
    P_.block(0, 3, 3, n) = cross;
    P_.block(3, 0, n, 3) = cross.transpose();
  }
}

void EkfSlam::PredictCalibrated(const Eigen::Vector2d& u, double dt) {
  // Vehicle v = [pose, c], c = (s0, s1, b): pose' = f(pose, u'(c)), c' = c, so
  // F_v = [F, G·∂u'/∂c; 0, I] and the control noise enters the pose through G.
  Eigen::Matrix<double, 2, 3> du_dc;
  const Eigen::Vector2d u_calibrated = CalibratedControl(u, x_.segment<3>(3), &du_dc);
  Eigen::Matrix3d F;
  Matrix32d G;
  const Pose2 next = motion_->Predict(pose(), u_calibrated, dt, &F, &G);
  x_.head<3>() = next.vector();
  Eigen::Matrix<double, 6, 6> Fv = Eigen::Matrix<double, 6, 6>::Identity();
  Fv.topLeftCorner<3, 3>() = F;
  Fv.topRightCorner<3, 3>() = G * du_dc;
  Eigen::Matrix<double, 6, 6> Pvv = P_.topLeftCorner<6, 6>().selfadjointView<Eigen::Lower>();
  Pvv = (Fv * Pvv * Fv.transpose()).eval();
  Pvv.topLeftCorner<3, 3>() += G * motion_->noise().Covariance(u_calibrated) * G.transpose();
  P_.topLeftCorner<6, 6>() = 0.5 * (Pvv + Pvv.transpose());
  const int n = dim_ - 6;
  if (n > 0) {
    const Eigen::Matrix<double, 6, Eigen::Dynamic> cross = Fv * P_.block(0, 6, 6, n);
    P_.block(0, 6, 6, n) = cross;
    P_.block(6, 0, n, 6) = cross.transpose();
  }
}

OdometryCalibrationEstimate EkfSlam::odometry_calibration() const {
  OdometryCalibrationEstimate e;
  if (!options_.odometry.enabled()) return e;
  e.value = x_.segment<3>(3);
  e.covariance = P_.block<3, 3>(3, 3).selfadjointView<Eigen::Lower>();
  return e;
}

Eigen::Matrix2d EkfSlam::LandmarkCovarianceBlock(int oa, int ob) const {
  // Only the lower triangle of the landmark-landmark part is kept current.
  if (oa < ob) return P_.block<2, 2>(ob, oa).transpose();
  Eigen::Matrix2d block = P_.block<2, 2>(oa, ob);
  if (oa == ob) block(0, 1) = block(1, 0);
  return block;
}

void EkfSlam::LandmarkColumns(int o, Eigen::Ref<Eigen::MatrixXd> out) const {
  // Rows above the diagonal block come from the lower triangle, transposed.
  out.topRows(o) = P_.block(o, 0, 2, o).transpose();
  out.bottomRows(dim_ - o) = P_.block(o, o, dim_ - o, 2);
  out(o, 1) = P_(o + 1, o);
}

void EkfSlam::SyncPoseRows() {
  // The pose rows are read directly (prediction, cross-covariances, new landmarks),
  // so they are mirrored from the authoritative pose columns.
  auto pose_block = P_.topLeftCorner<3, 3>();
  pose_block.triangularView<Eigen::StrictlyUpper>() = pose_block.transpose();
  P_.block(0, 3, 3, dim_ - 3) = P_.block(3, 0, dim_ - 3, 3).transpose();
  if (vehicle_dim_ == 6) {  // the calibration's rows too
    auto calibration = P_.block<3, 3>(3, 3);
    calibration.triangularView<Eigen::StrictlyUpper>() = calibration.transpose();
    P_.block(3, 6, 3, dim_ - 6) = P_.block(6, 3, dim_ - 6, 3).transpose();
  }
}

Eigen::Matrix2d EkfSlam::CrossCovariance(const Prediction& a, const Prediction& b) const {
  const int oa = Offset(a.landmark), ob = Offset(b.landmark);
  return a.H_pose * P_.topLeftCorner<3, 3>() * b.H_pose.transpose() +
         a.H_pose * P_.block<3, 2>(0, ob) * b.H_landmark.transpose() +
         a.H_landmark * P_.block<2, 3>(oa, 0) * b.H_pose.transpose() +
         a.H_landmark * LandmarkCovarianceBlock(oa, ob) * b.H_landmark.transpose();
}

void EkfSlam::UpdateExistence(LandmarkInfo* info, bool detected) const {
  info->existence = options_.landmarks.UpdatedExistence(info->existence, detected);
  if (options_.landmarks.existence.Confirms(info->existence)) info->confirmed = true;
}

void EkfSlam::GateDetections(const std::vector<Eigen::Vector2d>& z, const std::vector<Prediction>& predictions,
                             association::AssociationProblem* problem, std::vector<double>* min_d2,
                             std::vector<bool>* gated) {
  for (size_t j = 0; j < z.size(); ++j) {
    for (const Prediction& pr : predictions) {
      const Eigen::Vector2d nu = models::RangeBearingModel::Difference(z[j], pr.z);
      const std::optional<double> d2 = models::MahalanobisSquared2(nu, pr.S);
      if (!d2.has_value()) {  // S not positive definite: this pairing is not considered
        ++counters_.numerical_failures;
        continue;
      }
      (*min_d2)[j] = std::min((*min_d2)[j], *d2);
      if (*d2 < new_landmark_d2_) (*gated)[pr.landmark] = true;
      if (*d2 < gate_d2_) problem->candidates[j].push_back({pr.landmark, *d2, nu});
    }
    std::sort(problem->candidates[j].begin(), problem->candidates[j].end(),
              [](const association::AssociationCandidate& a, const association::AssociationCandidate& b) {
                return a.d2 < b.d2;
              });
  }
}

association::AssociationResult EkfSlam::AssociateByTruth(const std::vector<Eigen::Vector2d>& z,
                                                         const std::vector<int>& known_landmark,
                                                         const std::vector<Prediction>& predictions,
                                                         const std::vector<int>& prediction_of_landmark,
                                                         association::AssociationProblem* problem,
                                                         std::vector<bool>* gated) {
  association::AssociationResult association;
  association.landmark_of_detection.assign(z.size(), -1);
  for (size_t j = 0; j < z.size(); ++j) {
    const int i = known_landmark[j];
    if (i == kDropped) ++counters_.known_ignored;
    if (i < 0) continue;
    const Prediction& pr = predictions[prediction_of_landmark[i]];
    const Eigen::Vector2d nu = models::RangeBearingModel::Difference(z[j], pr.z);
    const std::optional<double> d2 = models::MahalanobisSquared2(nu, pr.S);
    if (!d2.has_value()) {  // S not positive definite: this detection is not used
      ++counters_.numerical_failures;
      association.landmark_of_detection[j] = -1;
      (*gated)[i] = true;  // not a new landmark either
      continue;
    }
    problem->candidates[j].push_back({i, *d2, nu});
    association.landmark_of_detection[j] = i;
    (*gated)[i] = true;
  }
  return association;
}

absl::Status EkfSlam::Update(const Scan& scan) {
  if (absl::Status st = CheckScan(scan); !st.ok()) return st;
  ++counters_.scans;
  const Pose2 p = pose();
  const models::RangeBearingConfig& rb = sensor_.config();
  const Eigen::Matrix2d R = sensor_.NoiseCovariance();

  // Detections outside the sensor's valid range are not used.
  const internal::UsableDetections usable = internal::DetectionsInRange(scan, rb);
  const std::vector<Eigen::Vector2d>& z = usable.z;
  const std::vector<int>& detection_index = usable.index;
  scan_features_.assign(scan.detections.size(), -1);
  counters_.detections += static_cast<long>(z.size());
  const int m = static_cast<int>(z.size());

  // Known association: the landmark each detection's true id names (−1: none yet, a new
  // one), or kDropped for a false alarm or an id already detected in this scan.
  std::vector<int> truth_of_detection(m, -1);
  const std::vector<int> known_landmark = options_.landmarks.known_association
                                              ? KnownLandmarks(scan, detection_index, &truth_of_detection)
                                              : std::vector<int>(m, -1);

  // 1. Predicted measurements and individual compatibility.
  std::vector<Prediction> predictions;
  association::AssociationProblem problem;
  problem.candidates.resize(m);
  std::vector<double> min_d2(m, INFINITY);
  std::vector<bool> gated(landmarks_.size(), false);
  std::vector<int> prediction_of_landmark(landmarks_.size(), -1);
  {
    StageTimer timer(&times_, "associate");
    const auto predict = [&](int i) {
      Prediction pr;
      pr.landmark = i;
      pr.z = sensor_.Observe(p, x_.segment<2>(Offset(i)), &pr.H_pose, &pr.H_landmark);
      prediction_of_landmark[i] = static_cast<int>(predictions.size());
      predictions.push_back(pr);
    };
    const double reach = rb.max_range_m + 10.0;
    for (int i = 0; i < num_landmarks(); ++i) {
      if ((x_.segment<2>(Offset(i)) - p.translation()).squaredNorm() <= reach * reach) predict(i);
    }
    // A detected landmark is predicted even if the estimate puts it out of reach.
    for (int i : known_landmark) {
      if (i >= 0 && prediction_of_landmark[i] < 0) predict(i);
    }
    for (Prediction& pr : predictions) pr.S = CrossCovariance(pr, pr) + R;
    if (!options_.landmarks.known_association) GateDetections(z, predictions, &problem, &min_d2, &gated);
  }
  association::AssociationResult association;
  {
    StageTimer timer(&times_, "associate");
    if (options_.landmarks.known_association) {
      association = AssociateByTruth(z, known_landmark, predictions, prediction_of_landmark, &problem, &gated);
    } else if (options_.association == association::AssociationMethod::kJointCompatibility) {
      problem.covariance_block = [&](int, int a, int, int b) -> Eigen::Matrix2d {
        const Prediction& pa = predictions[prediction_of_landmark[a]];
        const Prediction& pb = predictions[prediction_of_landmark[b]];
        return a == b ? pa.S : CrossCovariance(pa, pb);
      };
      association =
          association::JointCompatibility(problem, options_.landmarks.gate_probability, options_.jcbb_max_nodes);
      if (association.truncated) ++counters_.jcbb_truncated;
    } else {
      association = association::NearestNeighbour(problem);
    }
  }

  // 2. Batch EKF update with all pairings.
  std::vector<std::pair<int, const association::AssociationCandidate*>> pairs;  // (detection, candidate)
  for (int j = 0; j < m; ++j) {
    const int l = association.landmark_of_detection[j];
    if (l < 0) continue;
    for (const association::AssociationCandidate& c : problem.candidates[j]) {
      if (c.landmark == l) pairs.push_back({j, &c});
    }
  }
  if (!pairs.empty()) UpdateWithPairings(pairs, predictions, prediction_of_landmark, R);
  // 3. Existence, new landmarks, deletion of false alarms.
  ManageLandmarks(z, detection_index, pairs, predictions, gated, association.landmark_of_detection, known_landmark,
                  truth_of_detection, min_d2);
  return absl::OkStatus();
}

std::vector<int> EkfSlam::KnownLandmarks(const Scan& scan, const std::vector<int>& detection_index,
                                         std::vector<int>* truth_of_detection) const {
  const int m = static_cast<int>(detection_index.size());
  std::vector<int> known_landmark(m, -1);
  for (int j = 0; j < m; ++j) {
    const int truth = scan.detections[detection_index[j]].truth_id;
    const auto earlier = truth_of_detection->begin() + j;
    if (truth < 0 || std::find(truth_of_detection->begin(), earlier, truth) != earlier) {
      known_landmark[j] = kDropped;
      continue;
    }
    (*truth_of_detection)[j] = truth;
    for (int i = 0; i < num_landmarks() && known_landmark[j] < 0; ++i) {
      if (landmarks_[i].truth_id == truth) known_landmark[j] = i;
    }
  }
  return known_landmark;
}

void EkfSlam::UpdateWithPairings(const std::vector<std::pair<int, const association::AssociationCandidate*>>& pairs,
                                 const std::vector<Prediction>& predictions,
                                 const std::vector<int>& prediction_of_landmark, const Eigen::Matrix2d& R) {
  StageTimer timer(&times_, "update");
  const int k = static_cast<int>(pairs.size());
  std::vector<const Prediction*> pred(k);
  for (int a = 0; a < k; ++a) {
    pred[a] = &predictions[prediction_of_landmark[pairs[a].second->landmark]];
  }
  Eigen::MatrixXd PHt(dim_, 2 * k);
  Eigen::MatrixXd landmark_columns(dim_, 2);
  Eigen::VectorXd nu(2 * k);
  for (int a = 0; a < k; ++a) {
    LandmarkColumns(Offset(pred[a]->landmark), landmark_columns);
    PHt.middleCols<2>(2 * a).noalias() = P_.topLeftCorner(dim_, 3) * pred[a]->H_pose.transpose();
    PHt.middleCols<2>(2 * a).noalias() += landmark_columns * pred[a]->H_landmark.transpose();
    nu.segment<2>(2 * a) = pairs[a].second->innovation;
  }
  Eigen::MatrixXd S(2 * k, 2 * k);
  for (int a = 0; a < k; ++a) {
    for (int b = 0; b < k; ++b) {
      S.block<2, 2>(2 * a, 2 * b) = pred[a]->H_pose * PHt.block<3, 2>(0, 2 * b) +
                                    pred[a]->H_landmark * PHt.block<2, 2>(Offset(pred[a]->landmark), 2 * b);
    }
    S.block<2, 2>(2 * a, 2 * a) += R;
  }
  S = 0.5 * (S + S.transpose()).eval();
  Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() != Eigen::Success) {  // the scan's update is skipped
    ++counters_.numerical_failures;
    return;
  }
  // W = PHᵀ L⁻ᵀ, so that K ν = W (L⁻¹ ν) and K S Kᵀ = W Wᵀ.
  Eigen::MatrixXd Wt = PHt.transpose();
  llt.matrixL().solveInPlace(Wt);
  Eigen::VectorXd whitened = nu;
  llt.matrixL().solveInPlace(whitened);
  // −log N(ν; 0, S) = ½ (‖L⁻¹ν‖² + log det S + 2k log 2π), log det S = 2 Σ log L_ii.
  counters_.innovation_neg_log_likelihood += 0.5 * whitened.squaredNorm() +
                                             llt.matrixLLT().diagonal().array().log().sum() +
                                             k * std::log(2.0 * std::numbers::pi);
  counters_.innovation_dof += 2 * k;
  innovation_monitor_.Add(whitened.squaredNorm(), 2 * k);
  x_.head(dim_).noalias() += Wt.transpose() * whitened;
  x_[2] = WrapAngle(x_[2]);
  // Lower triangle only: mirroring the whole matrix would cost as much as the update.
  P_.topLeftCorner(dim_, dim_).selfadjointView<Eigen::Lower>().rankUpdate(Wt.transpose(), -1.0);
  SyncPoseRows();
  counters_.associated += k;
}

void EkfSlam::ManageLandmarks(const std::vector<Eigen::Vector2d>& z, const std::vector<int>& detection_index,
                              const std::vector<std::pair<int, const association::AssociationCandidate*>>& pairs,
                              const std::vector<Prediction>& predictions, const std::vector<bool>& gated,
                              const std::vector<int>& landmark_of_detection, const std::vector<int>& known_landmark,
                              const std::vector<int>& truth_of_detection, const std::vector<double>& min_d2) {
  const int m = static_cast<int>(z.size());
  StageTimer timer(&times_, "map_management");
  for (const auto& [j, c] : pairs) {
    UpdateExistence(&landmarks_[c->landmark], true);
    scan_features_[detection_index[j]] = landmarks_[c->landmark].id;
  }
  for (const Prediction& pr : predictions) {
    if (gated[pr.landmark]) continue;
    if (sensor_.IsVisible(pr.z, options_.landmarks.expect_range_margin_m,
                          options_.landmarks.expect_bearing_margin_rad)) {
      UpdateExistence(&landmarks_[pr.landmark], false);
    }
  }
  for (int j = 0; j < m; ++j) {
    // Known association: a detection of a known landmark never starts another (its pairing
    // may have been skipped as a numerical failure).
    if (landmark_of_detection[j] >= 0 || known_landmark[j] == kDropped || known_landmark[j] >= 0) continue;
    if (min_d2[j] > new_landmark_d2_) {
      AddLandmark(z[j], truth_of_detection[j]);
      scan_features_[detection_index[j]] = landmarks_.back().id;
    } else if (!options_.landmarks.known_association) {
      ++counters_.ambiguous;
    }
  }
  // Known association settles existence too (every landmark has a true id): no cull.
  if (counters_.scans % options_.landmarks.cull_every_scans != 0 || options_.landmarks.known_association) return;
  std::vector<int> doomed;
  for (int i = 0; i < num_landmarks(); ++i) {
    if (options_.landmarks.existence.Deletes(landmarks_[i].existence, landmarks_[i].confirmed)) {
      doomed.push_back(i);
    }
  }
  if (!doomed.empty()) RemoveLandmarks(doomed);
}

void EkfSlam::AddLandmark(const Eigen::Vector2d& z, int truth_id) {
  const Pose2 p = pose();
  Matrix23d G_pose;
  Eigen::Matrix2d G_z;
  const Eigen::Vector2d l = sensor_.InverseObserve(p, z, &G_pose, &G_z);
  Reserve(dim_ + 2);
  const int o = dim_;
  x_.segment<2>(o) = l;
  const Eigen::MatrixXd cross = G_pose * P_.topLeftCorner(3, dim_);  // 2 × dim
  P_.block(o, 0, 2, dim_) = cross;
  P_.block(0, o, dim_, 2) = cross.transpose();
  P_.block<2, 2>(o, o) =
      G_pose * P_.topLeftCorner<3, 3>() * G_pose.transpose() + G_z * sensor_.NoiseCovariance() * G_z.transpose();
  dim_ += 2;
  LandmarkInfo info;
  info.id = next_id_++;
  info.truth_id = truth_id;
  info.existence = options_.landmarks.existence.Initial();  // the prior and the creating detection
  info.confirmed = options_.landmarks.existence.Confirms(info.existence);
  landmarks_.push_back(info);
  ++counters_.new_landmarks;
}

void EkfSlam::RemoveLandmarks(const std::vector<int>& sorted_indices) {
  std::vector<int> keep;
  for (int i = 0; i < vehicle_dim_; ++i) keep.push_back(i);
  std::vector<LandmarkInfo> kept;
  size_t d = 0;
  for (int i = 0; i < num_landmarks(); ++i) {
    if (d < sorted_indices.size() && sorted_indices[d] == i) {
      ++d;
      continue;
    }
    keep.push_back(Offset(i));
    keep.push_back(Offset(i) + 1);
    kept.push_back(landmarks_[i]);
  }
  const int new_dim = static_cast<int>(keep.size());
  const Eigen::MatrixXd P = P_(keep, keep);
  const Eigen::VectorXd x = x_(keep);
  P_.topLeftCorner(new_dim, new_dim) = P;
  x_.head(new_dim) = x;
  dim_ = new_dim;
  counters_.deleted_landmarks += static_cast<long>(sorted_indices.size());
  landmarks_ = std::move(kept);
}

void EkfSlam::Reset(const Pose2& start) {
  dim_ = vehicle_dim_;
  x_.head<3>() = start.vector();
  P_.topLeftCorner<3, 3>().setZero();
  if (vehicle_dim_ == 6) {  // the calibration stays, uncorrelated with the new pose
    P_.block<3, 3>(3, 0).setZero();
    P_.block<3, 3>(0, 3).setZero();
  }
  landmarks_.clear();
  scan_features_.clear();
}

MomentMatchedGaussian EkfSlam::Export(double min_existence) const {
  MomentMatchedGaussian g;
  std::vector<int> index = {0, 1, 2};
  for (int i = 0; i < num_landmarks(); ++i) {
    if (landmarks_[i].existence < min_existence) continue;
    index.push_back(Offset(i));
    index.push_back(Offset(i) + 1);
    g.features.push_back(landmarks_[i].id);
    g.existence.push_back(landmarks_[i].existence);
    g.signature.push_back(std::numeric_limits<double>::quiet_NaN());
    if (options_.landmarks.known_association) g.truth_id.push_back(landmarks_[i].truth_id);
  }
  g.mean = x_(index);
  g.covariance = covariance()(index, index);
  g.particles_used = 1;
  if (RepairCovariance(&g.covariance, 1e-9)) ++g.covariance_repairs;
  return g;
}

int EkfSlam::NumConfirmed() const {
  int n = 0;
  for (const LandmarkInfo& l : landmarks_) n += l.confirmed ? 1 : 0;
  return n;
}

int EkfSlam::NumConfirmedWithinRange() const {
  const double r2 = sensor_.config().max_range_m * sensor_.config().max_range_m;
  int n = 0;
  for (int i = 0; i < num_landmarks(); ++i) {
    if (landmarks_[i].confirmed && (x_.segment<2>(Offset(i)) - x_.head<2>()).squaredNorm() <= r2) ++n;
  }
  return n;
}

std::vector<LandmarkEstimate> EkfSlam::Map() const {
  std::vector<LandmarkEstimate> out;
  for (int i = 0; i < num_landmarks(); ++i) {
    if (!landmarks_[i].confirmed) continue;
    out.push_back({landmarks_[i].id, x_.segment<2>(Offset(i)), LandmarkCovarianceBlock(Offset(i), Offset(i))});
  }
  return out;
}

std::map<std::string, double> EkfSlam::Counters() const {
  int confirmed = 0;
  for (const LandmarkInfo& l : landmarks_) confirmed += l.confirmed ? 1 : 0;
  std::map<std::string, double> out = {{"scans", counters_.scans},
                                       {"detections", counters_.detections},
                                       {"associated", counters_.associated},
                                       {"new_landmarks", counters_.new_landmarks},
                                       {"ambiguous_detections", counters_.ambiguous},
                                       {"known_association_ignored", counters_.known_ignored},
                                       {"deleted_landmarks", counters_.deleted_landmarks},
                                       {"jcbb_truncated_scans", counters_.jcbb_truncated},
                                       {"innovation_neg_log_likelihood", counters_.innovation_neg_log_likelihood},
                                       {"innovation_dof", counters_.innovation_dof},
                                       {"numerical_failures", counters_.numerical_failures},
                                       {"landmarks_in_state", num_landmarks()},
                                       {"confirmed_landmarks", confirmed}};
  innovation_monitor_.AddCounters(&out);
  if (options_.odometry.enabled()) odometry_calibration().AddCounters(&out);
  return out;
}

}  // namespace subslam::frontend
