// SeifSlam: the measurement update of one scan — the gated candidates with their local
// covariances, association (NN or JCBB, or by the true ids), new landmarks, existence, and
// ISEIF's iterated relinearisation with its adaptive stop.

#include <Eigen/Cholesky>
#include <Eigen/CholmodSupport>
#include <Eigen/LU>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "absl/strings/str_cat.h"
#include "subslam/core/check.h"
#include "subslam/core/stage_timer.h"
#include "subslam/frontend/internal/single_map_common.h"
#include "subslam/frontend/seif_slam.h"
#include "subslam/models/gating.h"

namespace subslam::frontend {

void SeifSlam::UpdateExistence(LandmarkInfo* info, bool detected) const {
  info->existence = options_.landmarks.UpdatedExistence(info->existence, detected);
  if (options_.landmarks.existence.Confirms(info->existence)) info->confirmed = true;
}

std::vector<int> SeifSlam::LandmarksInReach(const Pose2& p) const {
  std::vector<int> in_reach;
  const double reach = cell_size_m_;
  const int64_t cx = CellCoordinate(p.x), cy = CellCoordinate(p.y);
  for (int64_t dx = -1; dx <= 1; ++dx) {
    for (int64_t dy = -1; dy <= 1; ++dy) {
      auto it = grid_.find(CellKey(cx + dx, cy + dy));
      if (it == grid_.end()) continue;
      for (int l : it->second) {
        if ((mu_.segment<2>(Offset(l)) - p.translation()).squaredNorm() <= reach * reach) in_reach.push_back(l);
      }
    }
  }
  std::sort(in_reach.begin(), in_reach.end());
  return in_reach;
}

void SeifSlam::AssociateByTruth(const Scan& scan, const std::vector<int>& detection_index,
                                std::vector<int>* landmark_of_detection, std::vector<bool>* creates,
                                absl::flat_hash_map<int, bool>* gated) const {
  const int m = static_cast<int>(detection_index.size());
  for (int j = 0; j < m; ++j) {
    const int truth = scan.detections[detection_index[j]].truth_id;
    if (truth < 0) continue;  // a false alarm: no true landmark to associate with
    if (auto it = landmark_of_truth_.find(truth); it != landmark_of_truth_.end()) {
      (*landmark_of_detection)[j] = it->second;
      if (auto g = gated->find(it->second); g != gated->end()) g->second = true;
    } else {
      (*creates)[j] = true;
    }
  }
}

void SeifSlam::AssociateByGates(const Pose2& p, const std::vector<Eigen::Vector2d>& z, const std::vector<int>& in_reach,
                                const Eigen::Matrix2d& R, std::vector<int>* landmark_of_detection,
                                std::vector<bool>* creates, absl::flat_hash_map<int, bool>* gated) {
  const int m = static_cast<int>(z.size());
  std::vector<Eigen::Vector2d> points(m);
  for (int j = 0; j < m; ++j) points[j] = sensor_.InverseObserve(p, z[j]);
  const double r2 = options_.candidate_radius_m * options_.candidate_radius_m;
  std::vector<int> candidates;
  for (int l : in_reach) {
    for (int j = 0; j < m; ++j) {
      if ((mu_.segment<2>(Offset(l)) - points[j]).squaredNorm() <= r2) {
        candidates.push_back(l);
        break;
      }
    }
  }
  const LocalCovariance cov = Covariance(candidates, options_.covariance == CovarianceRecovery::kExact);
  struct Prediction {
    Eigen::Vector2d z;
    Eigen::Matrix<double, 2, 5> H;
    Eigen::Matrix2d S;
  };
  absl::flat_hash_map<int, Prediction> prediction;
  auto joint = [&cov](int a, int b) -> Eigen::Matrix<double, 5, 5> {
    // Σ over [x, l_a] × [x, l_b].
    const int oa = cov.offset.at(a), ob = cov.offset.at(b);
    Eigen::Matrix<double, 5, 5> s;
    s.topLeftCorner<3, 3>() = cov.sigma.topLeftCorner<3, 3>();
    s.topRightCorner<3, 2>() = cov.sigma.block<3, 2>(0, ob);
    s.bottomLeftCorner<2, 3>() = cov.sigma.block<2, 3>(oa, 0);
    s.bottomRightCorner<2, 2>() = cov.sigma.block<2, 2>(oa, ob);
    return s;
  };
  for (int l : candidates) {
    Prediction pr;
    Matrix23d H_pose;
    Eigen::Matrix2d H_landmark;
    pr.z = sensor_.Observe(p, mu_.segment<2>(Offset(l)), &H_pose, &H_landmark);
    pr.H << H_pose, H_landmark;
    pr.S = pr.H * joint(l, l) * pr.H.transpose() + R;
    pr.S = 0.5 * (pr.S + pr.S.transpose()).eval();
    prediction[l] = pr;
  }
  association::AssociationProblem problem;
  problem.candidates.resize(m);
  std::vector<double> min_d2(m, INFINITY);
  for (int j = 0; j < m; ++j) {
    for (int l : candidates) {
      const Prediction& pr = prediction[l];
      const Eigen::Vector2d nu = models::RangeBearingModel::Difference(z[j], pr.z);
      const std::optional<double> d2 = models::MahalanobisSquared2(nu, pr.S);
      if (!d2.has_value()) {  // S not positive definite: this pairing is not considered
        ++numerical_failures_;
        continue;
      }
      min_d2[j] = std::min(min_d2[j], *d2);
      if (*d2 < new_landmark_d2_) (*gated)[l] = true;
      if (*d2 < gate_d2_) problem.candidates[j].push_back({l, *d2, nu});
    }
    std::sort(problem.candidates[j].begin(), problem.candidates[j].end(),
              [](const association::AssociationCandidate& a, const association::AssociationCandidate& b) {
                return a.d2 < b.d2;
              });
  }
  association::AssociationResult association;
  if (options_.association == association::AssociationMethod::kJointCompatibility) {
    problem.covariance_block = [&](int, int a, int, int b) -> Eigen::Matrix2d {
      if (a == b) return prediction[a].S;
      return prediction[a].H * joint(a, b) * prediction[b].H.transpose();
    };
    association =
        association::JointCompatibility(problem, options_.landmarks.gate_probability, options_.jcbb_max_nodes);
    if (association.truncated) ++counters_.jcbb_truncated;
  } else {
    association = association::NearestNeighbour(problem);
  }
  for (int j = 0; j < m; ++j) {
    (*landmark_of_detection)[j] = association.landmark_of_detection[j];
    if ((*landmark_of_detection)[j] < 0) {
      if (min_d2[j] > new_landmark_d2_) {
        (*creates)[j] = true;
      } else {
        ++counters_.ambiguous;
      }
    }
  }
}

void SeifSlam::MeasurementUpdate(const std::vector<std::pair<int, Eigen::Vector2d>>& pairs,
                                 const std::vector<int>& touched) {
  const bool iterate = options_.iterated.enabled && options_.iterated.max_iterations > 1 &&
                       counters_.scans % options_.iterated.period_scans == 0;
  // μ⁰, the prediction, over the pose and the observed landmarks (Eq. 28's g).
  Eigen::VectorXd previous = GatherMean(touched);
  Linearization lin;
  for (int i = 1;; ++i) {
    // Eqs. 14-19: linearise at the latest estimate μⁱ⁻¹, starting from the prediction;
    // the first pass is the SEIF update.
    {
      StageTimer timer(&times_, i == 1 ? "measurement" : "iteration");
      if (i > 1) Retract(lin);
      lin = ApplyMeasurements(pairs);
    }
    if (!iterate) {
      RecoverLocally();  // the pose the new landmarks are initialised from
      break;
    }
    StageTimer timer(&times_, "iteration");
    ++counters_.iterations;
    if (i <= options_.iterated.exact_recoveries) {
      RecoverMeanExactly();
    } else {
      Relax(ActiveLandmarks(), options_.relaxation_sweeps);
    }
    const Eigen::VectorXd current = GatherMean(touched);
    Eigen::VectorXd change = current - previous;
    change[2] = WrapAngle(change[2]);
    previous = current;
    if (change.cwiseAbs().maxCoeff() < options_.iterated.stop_change || i == options_.iterated.max_iterations) {
      ++counters_.iterated_updates;
      break;
    }
  }
  counters_.associated += static_cast<long>(pairs.size());
}

std::vector<int> SeifSlam::ManageLandmarks(const Scan& scan, const std::vector<int>& detection_index,
                                           const std::vector<Eigen::Vector2d>& z, const Pose2& p,
                                           const std::vector<int>& landmark_of_detection,
                                           const std::vector<bool>& creates, const std::vector<int>& in_reach,
                                           const absl::flat_hash_map<int, bool>& gated) {
  const int m = static_cast<int>(z.size());
  std::vector<int> created;
  StageTimer timer(&times_, "map_management");
  for (int j = 0; j < m; ++j) {
    const int l = landmark_of_detection[j];
    if (l < 0) continue;
    UpdateExistence(&landmarks_[l], true);
    landmarks_[l].last_seen_scan = counters_.scans;
    scan_features_[detection_index[j]] = l;
  }
  for (int l : in_reach) {
    if (gated.at(l)) continue;
    const Eigen::Vector2d z_hat = sensor_.Observe(p, mu_.segment<2>(Offset(l)));
    if (sensor_.IsVisible(z_hat, options_.landmarks.expect_range_margin_m,
                          options_.landmarks.expect_bearing_margin_rad)) {
      UpdateExistence(&landmarks_[l], false);
    }
  }
  std::vector<std::pair<int, Eigen::Vector2d>> new_pairs;
  const Pose2 updated = pose();
  for (int j = 0; j < m; ++j) {
    if (!creates[j]) continue;
    const int l = AddLandmarkSlot(sensor_.InverseObserve(updated, z[j]));
    LandmarkInfo& info = landmarks_[l];
    info.existence = options_.landmarks.existence.Initial();
    info.confirmed = options_.landmarks.existence.Confirms(info.existence);
    info.last_seen_scan = counters_.scans;
    if (options_.landmarks.known_association) {
      info.truth_id = scan.detections[detection_index[j]].truth_id;
      landmark_of_truth_[info.truth_id] = l;
    }
    scan_features_[detection_index[j]] = l;
    new_pairs.push_back({l, z[j]});
    created.push_back(l);
    ++counters_.new_landmarks;
  }
  // The first detection's information: ν = 0 at μ_l = g(μ_x, z), so the mean holds.
  if (!new_pairs.empty()) ApplyMeasurements(new_pairs);
  if (counters_.scans % options_.landmarks.cull_every_scans == 0) {
    for (size_t i = 0; i < landmarks_.size(); ++i) {
      LandmarkInfo& info = landmarks_[i];
      if (info.alive && options_.landmarks.existence.Deletes(info.existence, info.confirmed)) {
        Marginalize(static_cast<int>(i));
        ++counters_.deleted_landmarks;
      }
    }
  }
  return created;
}

absl::Status SeifSlam::Update(const Scan& scan) {
  if (absl::Status st = CheckScan(scan); !st.ok()) return st;
  FlushMotion();
  ++counters_.scans;
  Invalidate();
  const Pose2 p = pose();
  const models::RangeBearingConfig& rb = sensor_.config();
  const Eigen::Matrix2d R = sensor_.NoiseCovariance();

  const internal::UsableDetections usable = internal::DetectionsInRange(scan, rb);
  const std::vector<Eigen::Vector2d>& z = usable.z;
  const std::vector<int>& detection_index = usable.index;
  scan_features_.assign(scan.detections.size(), -1);
  counters_.detections += static_cast<long>(z.size());
  const int m = static_cast<int>(z.size());

  // 1. Association.
  std::vector<int> landmark_of_detection(m, -1);
  std::vector<bool> creates(m, false);
  absl::flat_hash_map<int, bool> gated;  // landmarks within reach → gated with a detection
  std::vector<int> in_reach;
  {
    StageTimer timer(&times_, "associate");
    in_reach = LandmarksInReach(p);
    for (int l : in_reach) gated[l] = false;
    if (options_.landmarks.known_association) {
      AssociateByTruth(scan, detection_index, &landmark_of_detection, &creates, &gated);
    } else {
      AssociateByGates(p, z, in_reach, R, &landmark_of_detection, &creates, &gated);
    }
  }

  // 2. Measurement update of the associations; ISEIF relinearises it to convergence.
  std::vector<std::pair<int, Eigen::Vector2d>> pairs;
  std::vector<int> touched;
  for (int j = 0; j < m; ++j) {
    if (landmark_of_detection[j] < 0) continue;
    pairs.push_back({landmark_of_detection[j], z[j]});
    touched.push_back(landmark_of_detection[j]);
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  if (!pairs.empty()) MeasurementUpdate(pairs, touched);

  // 3. Existence, new landmarks, deletion of false alarms.
  const std::vector<int> created =
      ManageLandmarks(scan, detection_index, z, p, landmark_of_detection, creates, in_reach, gated);
  counters_.max_active = std::max<long>(counters_.max_active, num_active_landmarks());

  // 4. Sparsification, then the amortised recovery (exact recovery needs none: the
  // new landmarks, the marginalisation and sparsification all keep Ω μ = ξ).
  Sparsify();
  if (options_.recovery == MeanRecovery::kRelaxation) {
    touched.insert(touched.end(), created.begin(), created.end());
    RecoverAmortised(touched);
  }
  // Only here and after the motion update: an iterated update must not see its
  // coordinates shift between applying a linearisation and taking it back.
  WrapHeading();
  if (options_.pose_covariance == CovarianceRecovery::kExact) {
    StageTimer timer(&times_, "pose_covariance");
    const Eigen::Matrix3d sigma = Covariance({}, true).sigma;
    exact_pose_cov_ = 0.5 * (sigma + sigma.transpose());
  }
  return absl::OkStatus();
}

}  // namespace subslam::frontend
