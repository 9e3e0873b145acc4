#include "subslam/calibration/internal/calibration_state.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <utility>

#include "subslam/models/gating.h"

namespace subslam::calibration::internal {

CalibrationState::CalibrationState(const io::Dataset& dataset, const CalibrationOptions& options)
    : dataset_(dataset), options_(options), sensor_(dataset.sensor.range_bearing) {
  io::Dataset recorded = dataset;  // the steps with their controls as recorded
  recorded.motion.control_scale = Eigen::Vector2d::Ones();
  recorded.motion.control_offset = Eigen::Vector2d::Zero();
  model_ = dataset.motion.MakeModel();
  c_ = Eigen::Vector3d(dataset.motion.control_scale[0], dataset.motion.control_scale[1],
                       dataset.motion.control_offset[1]);
  const models::ControlNoise& n = dataset.motion.noise;
  const models::RangeBearingConfig& rb = dataset.sensor.range_bearing;
  theta_ = {n.sigma_u0 * n.sigma_u0,
            n.scale_u0 * n.scale_u0,
            n.sigma_u1 * n.sigma_u1,
            n.scale_u1 * n.scale_u1,
            rb.sigma_range_m * rb.sigma_range_m,
            rb.sigma_bearing_rad * rb.sigma_bearing_rad,
            1.0};
  BuildIntervals(io::BuildSteps(recorded));
}

// The times between consecutive control lines longer than three nominal control periods
// (the median): a gap, over which the steps hold the last control while the robot's own
// changes, so that the odometry there is worse than its noise model says.
std::vector<std::pair<double, double>> CalibrationState::ControlGaps() const {
  const std::vector<io::ControlRecord>& c = dataset_.controls;
  if (c.size() < 3) return {};
  std::vector<double> periods;
  for (size_t k = 1; k < c.size(); ++k) periods.push_back(c[k].t - c[k - 1].t);
  std::nth_element(periods.begin(), periods.begin() + periods.size() / 2, periods.end());
  const double nominal = periods[periods.size() / 2];
  std::vector<std::pair<double, double>> gaps;
  for (size_t k = 1; k < c.size(); ++k) {
    if (c[k].t - c[k - 1].t > 3.0 * nominal) gaps.push_back({c[k - 1].t, c[k].t});
  }
  return gaps;
}

void CalibrationState::BuildIntervals(const std::vector<io::Step>& steps) {
  pose_of_scan_.assign(dataset_.scans.size(), 0);
  const std::vector<std::pair<double, double>> gaps = ControlGaps();
  auto next_gap = gaps.begin();
  std::vector<RecordedStep> pending;
  double span = 0.0;
  for (size_t k = 0; k < steps.size(); ++k) {
    if (k > 0 && steps[k].dt > 0.0) {
      pending.push_back({steps[k].control, steps[k].dt});
      span += steps[k].dt;
    }
    if (steps[k].scan_index < 0) continue;
    if (span > 0.0) {  // a scan at the first step's time shares the initial pose
      const double t_a = steps[k].t - span, t_b = steps[k].t;
      while (next_gap != gaps.end() && next_gap->second <= t_a) ++next_gap;
      const bool gap = next_gap != gaps.end() && next_gap->first < t_b;
      intervals_.push_back({num_poses_ - 1, num_poses_,
                            OdometryInterval(model_.get(), std::move(pending), dataset_.motion.control_offset[0]),
                            gap});
      ++num_poses_;
    }
    pose_of_scan_[steps[k].scan_index] = num_poses_ - 1;
    pending.clear();
    span = 0.0;
  }
}

void CalibrationState::SetPoses(std::vector<Eigen::Vector3d> poses,
                                const std::vector<Eigen::Matrix3d>& scan_covariances) {
  poses_ = std::move(poses);
  pose_covariance_.assign(num_poses_, Eigen::Matrix3d::Zero());
  for (size_t j = 0; j < scan_covariances.size(); ++j) pose_covariance_[pose_of_scan_[j]] = scan_covariances[j];
}

void CalibrationState::SetLandmarks(const std::vector<Eigen::Vector2d>& map,
                                    const std::vector<Eigen::Matrix2d>& covariances) {
  if (options_.known_association) {
    LandmarksFromTruth();
    landmark_covariance_.assign(landmarks_.size(), Eigen::Matrix2d::Zero());
  } else {
    landmarks_ = map;
    landmark_covariance_ = covariances.size() == map.size()
                               ? covariances
                               : std::vector<Eigen::Matrix2d>(map.size(), Eigen::Matrix2d::Zero());
  }
}

// Each true id's landmark at the mean of its detections seen from the start poses.
void CalibrationState::LandmarksFromTruth() {
  std::map<int, std::pair<Eigen::Vector2d, int>> sums;
  for (size_t j = 0; j < dataset_.scans.size(); ++j) {
    const Eigen::Vector3d& x = poses_[pose_of_scan_[j]];
    for (const Detection& d : dataset_.scans[j].detections) {
      if (d.truth_id < 0) continue;
      auto& [sum, count] = sums.try_emplace(d.truth_id, Eigen::Vector2d::Zero(), 0).first->second;
      sum += sensor_.InverseObserve(Pose2(x[0], x[1], x[2]), d.z());
      ++count;
    }
  }
  landmarks_.clear();
  for (const auto& [id, sum_count] : sums) {
    landmark_of_truth_[id] = static_cast<int>(landmarks_.size());
    landmarks_.push_back(sum_count.first / sum_count.second);
  }
}

void CalibrationState::Pair() {
  if (!options_.known_association) return PairByGate();
  pairs_.clear();
  for (size_t j = 0; j < dataset_.scans.size(); ++j) {
    const std::vector<Detection>& detections = dataset_.scans[j].detections;
    for (size_t i = 0; i < detections.size(); ++i) {
      const auto it = landmark_of_truth_.find(detections[i].truth_id);
      if (it == landmark_of_truth_.end() || outliers_.count({static_cast<int>(j), static_cast<int>(i)})) continue;
      pairs_.push_back({static_cast<int>(j), static_cast<int>(i), it->second});
    }
  }
}

// Each scan's detections with the landmarks inside the individual gate, nearest first,
// one to one; the gate's covariance is the sensor's plus the pose's and the landmark's
// marginals (their cross-covariance left out).
void CalibrationState::PairByGate() {
  pairs_.clear();
  const double gate = models::ChiSquareQuantile(options_.gate_probability, 2);
  const Eigen::Matrix2d R = SensorSigma().cwiseAbs2().asDiagonal();
  const double reach = dataset_.sensor.range_bearing.max_range_m + 3.0 * std::sqrt(R(0, 0)) + 1.0;
  for (size_t j = 0; j < dataset_.scans.size(); ++j) {
    const int pose = pose_of_scan_[j];
    const Pose2 x(poses_[pose][0], poses_[pose][1], poses_[pose][2]);
    const std::vector<Detection>& detections = dataset_.scans[j].detections;
    std::vector<std::pair<double, Pairing>> candidates;
    for (size_t l = 0; l < landmarks_.size(); ++l) {
      if ((landmarks_[l] - x.translation()).norm() > reach) continue;
      Matrix23d J_x;
      Eigen::Matrix2d J_l;
      const Eigen::Vector2d h = sensor_.Observe(x, landmarks_[l], &J_x, &J_l);
      const Eigen::Matrix2d S =
          R + J_x * pose_covariance_[pose] * J_x.transpose() + J_l * landmark_covariance_[l] * J_l.transpose();
      const Eigen::Matrix2d S_inv = S.inverse();
      for (size_t i = 0; i < detections.size(); ++i) {
        if (outliers_.count({static_cast<int>(j), static_cast<int>(i)})) continue;
        const Eigen::Vector2d nu = models::RangeBearingModel::Difference(detections[i].z(), h);
        const double d2 = nu.dot(S_inv * nu);
        if (d2 <= gate) candidates.push_back({d2, {static_cast<int>(j), static_cast<int>(i), static_cast<int>(l)}});
      }
    }
    std::sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    std::vector<char> detection_used(detections.size(), 0);
    std::set<int> landmark_used;
    for (const auto& [d2, p] : candidates) {
      if (detection_used[p.detection] || landmark_used.count(p.landmark)) continue;
      detection_used[p.detection] = 1;
      landmark_used.insert(p.landmark);
      pairs_.push_back(p);
    }
  }
}

// Whether paired detection p's normalised squared residual exceeds χ²₂(outlier_probability)
// under the current sensor σ.
bool CalibrationState::IsOutlier(const Pairing& p, double bound) const {
  const Eigen::Vector3d& x = poses_[pose_of_scan_[p.scan]];
  const Eigen::Vector2d h = sensor_.Observe(Pose2(x[0], x[1], x[2]), landmarks_[p.landmark]);
  const Eigen::Vector2d e =
      models::RangeBearingModel::Difference(dataset_.scans[p.scan].detections[p.detection].z(), h);
  return e.cwiseQuotient(SensorSigma()).squaredNorm() > bound;
}

int CalibrationState::DropOutliers() {
  const double bound = models::ChiSquareQuantile(options_.outlier_probability, 2);
  const size_t before = pairs_.size();
  std::erase_if(pairs_, [&](const Pairing& p) {
    if (!IsOutlier(p, bound)) return false;
    outliers_.insert({p.scan, p.detection});
    return true;
  });
  return static_cast<int>(before - pairs_.size());
}

// After the variances moved, each round starts afresh: a detection left out before may
// pass the test under the new σ.
void CalibrationState::FlagOutliers() {
  const double bound = models::ChiSquareQuantile(options_.outlier_probability, 2);
  outliers_.clear();
  for (const Pairing& p : pairs_) {
    if (IsOutlier(p, bound)) outliers_.insert({p.scan, p.detection});
  }
}

Eigen::Vector2d CalibrationState::SensorSigma() const {
  return Eigen::Vector2d(std::sqrt(theta_[kRangeComponent]), std::sqrt(theta_[kBearingComponent]));
}

Eigen::Matrix3d CalibrationState::OdometryCovariance(const std::array<Eigen::Matrix3d, 4>& T, bool gap) const {
  Eigen::Matrix3d sigma = Eigen::Matrix3d::Zero();
  for (int k = 0; k < 4; ++k) sigma += theta_[k] * T[k];
  if (gap) sigma *= theta_[kGapComponent];
  return sigma + 1e-12 * Eigen::Matrix3d::Identity();  // keeps a still interval invertible
}

absl::StatusOr<RobotCalibration> CalibrationState::Run() {
  const std::array<double, kComponents> first = theta_;
  int round = 0;
  bool converged = false;
  int left_out = 0;
  while (round < options_.max_rounds && !converged) {
    ++round;
    Pair();
    left_out = static_cast<int>(outliers_.size());
    if (pairs_.empty()) return absl::FailedPreconditionError("calibration: no detection could be paired");
    absl::StatusOr<RoundSums> sums = SolveRound();
    if (!sums.ok()) return sums.status();
    converged = true;
    for (int k = 0; k < kComponents; ++k) {
      if (first[k] <= 0.0 || !(sums->expected[k] > 0.0)) continue;  // held at zero, or not observed
      const double updated = theta_[k] * sums->weighted[k] / sums->expected[k];
      // Converged: σ moved by less than the tolerance, or by less than a tenth of its own
      // standard error σ / √(2 r_k) (components the data hardly tell apart creep).
      const double sigma = std::sqrt(theta_[k]), step = std::abs(std::sqrt(updated) - sigma);
      const double standard_error = sigma / std::sqrt(2.0 * theta_[k] * sums->expected[k]);
      converged = converged && (step < options_.relative_tolerance * sigma || step < 0.1 * standard_error);
      theta_[k] = updated;
    }
    FlagOutliers();
  }
  return Result(round, converged, left_out);
}

}  // namespace subslam::calibration::internal
