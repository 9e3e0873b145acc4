// The calibration's result: the estimates with their standard errors, the sensor's limits
// and its detection probability by range (robot_calibration.h).
#include <Eigen/Cholesky>
#include <algorithm>
#include <boost/math/distributions/beta.hpp>
#include <cmath>
#include <set>

#include "subslam/calibration/internal/calibration_state.h"

namespace subslam::calibration::internal {
namespace {

// √θ with the standard error of a variance component of redundancy r, σ/√(2r) (the
// components' correlation left out).
Estimated Sigma(double theta, double redundancy) {
  if (theta <= 0.0) return {0.0, 0.0};
  const double sigma = std::sqrt(theta);
  return {sigma, redundancy > 0.0 ? sigma / std::sqrt(2.0 * redundancy) : NAN};
}

// EM for the zero-truncated trials (CalibrationState::DetectionCurve), then each bin's 95 %
// interval from the truncated likelihood's observed information.
void TruncatedDetectionProbabilities(const std::vector<std::vector<int>>& trials_of_scan,
                                     std::vector<DetectionBin>* curve) {
  const size_t bins = curve->size();
  std::vector<double> p(bins, 0.0), unrecorded(bins, 0.0);
  for (size_t b = 0; b < bins; ++b) {
    if ((*curve)[b].predicted > 0) p[b] = static_cast<double>((*curve)[b].detected) / (*curve)[b].predicted;
  }
  for (int iteration = 0; iteration < 1000; ++iteration) {
    std::fill(unrecorded.begin(), unrecorded.end(), 0.0);
    for (const std::vector<int>& trials : trials_of_scan) {
      double p0 = 1.0;
      for (int b : trials) p0 *= 1.0 - p[b];
      const double missing = p0 / std::max(1e-12, 1.0 - p0);  // expected unrecorded scans like this one
      for (int b : trials) unrecorded[b] += missing;
    }
    double change = 0.0;
    for (size_t b = 0; b < bins; ++b) {
      const DetectionBin& bin = (*curve)[b];
      if (bin.predicted == 0) continue;
      const double updated = bin.detected / (bin.predicted + unrecorded[b]);
      change = std::max(change, std::abs(updated - p[b]));
      p[b] = updated;
    }
    if (change < 1e-9) break;
  }
  // The observed information of the truncated likelihood, −∂²L/∂p∂pᵀ with
  //   L = Σ_b [k_b log p_b + (n_b − k_b) log(1 − p_b)] − Σ_j log(1 − P₀ⱼ):
  // the plain binomial's diagonal, less each scan's truncation term
  //   w diag(m_b / (1 − p_b)²) − a aᵀ P₀ / (1 − P₀)²,  a_b = m_b / (1 − p_b), w = P₀ / (1 − P₀),
  // m_b the scan's trials in bin b.
  Eigen::MatrixXd information = Eigen::MatrixXd::Zero(bins, bins);
  for (size_t b = 0; b < bins; ++b) {
    const double k = (*curve)[b].detected, n = (*curve)[b].predicted;
    if (n > 0 && p[b] > 0.0 && p[b] < 1.0) information(b, b) = k / (p[b] * p[b]) + (n - k) / ((1 - p[b]) * (1 - p[b]));
  }
  for (const std::vector<int>& trials : trials_of_scan) {
    Eigen::VectorXd m = Eigen::VectorXd::Zero(bins);
    for (int b : trials) m[b] += 1.0;
    double p0 = 1.0;
    for (int b : trials) p0 *= 1.0 - p[b];
    if (p0 >= 1.0 - 1e-12) continue;
    const Eigen::VectorXd one_minus_p = Eigen::VectorXd::Ones(bins) - Eigen::Map<const Eigen::VectorXd>(p.data(), bins);
    const Eigen::VectorXd a = m.cwiseQuotient(one_minus_p);
    information.diagonal() += (p0 / (1 - p0)) * m.cwiseQuotient(one_minus_p.cwiseAbs2());
    information -= (p0 / ((1 - p0) * (1 - p0))) * a * a.transpose();
  }
  // Bins at 0 or 1 (no information in p's interior) keep the plain counts.
  std::vector<int> inner;
  for (size_t b = 0; b < bins; ++b) {
    if ((*curve)[b].predicted > 0 && p[b] > 0.0 && p[b] < 1.0) inner.push_back(static_cast<int>(b));
  }
  Eigen::MatrixXd inner_information(inner.size(), inner.size());
  for (size_t i = 0; i < inner.size(); ++i) {
    for (size_t j = 0; j < inner.size(); ++j) inner_information(i, j) = information(inner[i], inner[j]);
  }
  const Eigen::MatrixXd covariance =
      inner_information.ldlt().solve(Eigen::MatrixXd::Identity(inner.size(), inner.size()));
  std::vector<double> effective_trials(bins, 0.0);
  for (size_t b = 0; b < bins; ++b) effective_trials[b] = (*curve)[b].predicted;
  for (size_t i = 0; i < inner.size(); ++i) {
    const int b = inner[i];
    if (covariance(i, i) > 0.0) effective_trials[b] = p[b] * (1 - p[b]) / covariance(i, i);
  }
  for (size_t b = 0; b < bins; ++b) {
    DetectionBin& bin = (*curve)[b];
    if (bin.predicted == 0) continue;
    bin.expected_unrecorded = unrecorded[b];
    bin.probability = p[b];
    // Jeffreys' interval for the binomial of the same information: n_eff = p(1 − p) / var(p).
    const double n = effective_trials[b], k = p[b] * n;
    const boost::math::beta_distribution<double> jeffreys(k + 0.5, n - k + 0.5);
    bin.lower = k > 0 ? boost::math::quantile(jeffreys, 0.025) : 0.0;
    bin.upper = k < n ? boost::math::quantile(jeffreys, 0.975) : 1.0;
  }
}

}  // namespace

RobotCalibration CalibrationState::Result(int rounds, bool converged, int outliers_left_out) const {
  RobotCalibration r;
  for (int k = 0; k < 4; ++k) r.control_noise[k] = Sigma(theta_[k], redundancy_[k]);
  r.sigma_range_m = Sigma(theta_[kRangeComponent], redundancy_[kRangeComponent]);
  r.sigma_bearing_rad = Sigma(theta_[kBearingComponent], redundancy_[kBearingComponent]);
  r.gap_noise_factor = Sigma(theta_[kGapComponent], redundancy_[kGapComponent]);
  for (const Interval& iv : intervals_) r.gap_intervals += iv.gap ? 1 : 0;
  r.control_scale = Eigen::Vector2d(c_[0], c_[1]);
  r.control_offset = Eigen::Vector2d(dataset_.motion.control_offset[0], c_[2]);
  r.correction_standard_error = correction_covariance_.diagonal().cwiseSqrt();
  r.detections = static_cast<int>(dataset_.NumDetections());
  r.detections_paired = static_cast<int>(pairs_.size());
  r.detections_outliers = outliers_left_out;
  r.redundancy = observations_ - unknowns_;
  r.rounds = rounds;
  r.converged = converged;
  std::set<int> seen;
  r.min_range_m = r.fov_min_rad = INFINITY;
  r.max_range_m = r.fov_max_rad = -INFINITY;
  for (const Pairing& p : pairs_) {
    seen.insert(p.landmark);
    // The limits from where the estimate puts each detected landmark, not from the noisy
    // measurements, whose extremes overshoot the sensor's limits by a few σ.
    const Eigen::Vector3d& x = poses_[pose_of_scan_[p.scan]];
    const Eigen::Vector2d z = sensor_.Observe(Pose2(x[0], x[1], x[2]), landmarks_[p.landmark]);
    r.min_range_m = std::min(r.min_range_m, z[0]);
    r.max_range_m = std::max(r.max_range_m, z[0]);
    r.fov_min_rad = std::min(r.fov_min_rad, z[1]);
    r.fov_max_rad = std::max(r.fov_max_rad, z[1]);
  }
  r.landmarks = static_cast<int>(seen.size());
  for (size_t j = 0; j < dataset_.scans.size(); ++j) {
    const Eigen::Vector3d& x = poses_[pose_of_scan_[j]];
    r.scan_poses.emplace_back(x[0], x[1], WrapAngle(x[2]));
  }
  for (int l : seen) r.landmark_positions.push_back(landmarks_[l]);
  DetectionCurve(seen, &r);
  return r;
}

// At every scan, each estimated landmark predicted inside the limits is one trial, a
// success when one of the scan's detections was paired with it. A data set records a scan
// only when something was detected, so the scans with no landmark detected are missing:
// each recorded scan stands for 1 / (1 − P₀) scans, P₀ = Π (1 − p) over its trials. The
// curve is the maximum-likelihood estimate under that zero truncation, by EM (the expected
// unrecorded scans' trials added to each bin's misses), over the scans with at least one
// landmark detected (the event the truncation conditions on; scans recorded for clutter
// alone carry no information about p).
void CalibrationState::DetectionCurve(const std::set<int>& landmarks, RobotCalibration* r) const {
  if (!(r->max_range_m > r->min_range_m)) return;
  const int bins = static_cast<int>(std::ceil(r->max_range_m / options_.detection_bin_m));
  std::vector<DetectionBin> curve(bins);
  for (int b = 0; b < bins; ++b) {
    curve[b].range_min_m = b * options_.detection_bin_m;
    curve[b].range_max_m = std::min(r->max_range_m, (b + 1) * options_.detection_bin_m);
  }
  std::set<std::pair<int, int>> detected;  // (scan, landmark)
  for (const Pairing& p : pairs_) detected.insert({p.scan, p.landmark});
  std::vector<std::vector<int>> trials_of_scan;  // the bins of each used scan's trials
  for (size_t j = 0; j < dataset_.scans.size(); ++j) {
    const Eigen::Vector3d& x = poses_[pose_of_scan_[j]];
    std::vector<int> trials, hits;
    for (int l : landmarks) {
      const Eigen::Vector2d z = sensor_.Observe(Pose2(x[0], x[1], x[2]), landmarks_[l]);
      if (z[0] < r->min_range_m || z[0] > r->max_range_m || z[1] < r->fov_min_rad || z[1] > r->fov_max_rad) continue;
      trials.push_back(std::min(bins - 1, static_cast<int>(z[0] / options_.detection_bin_m)));
      if (detected.count({static_cast<int>(j), l})) hits.push_back(trials.back());
    }
    if (hits.empty()) continue;
    for (int b : trials) ++curve[b].predicted;
    for (int b : hits) ++curve[b].detected;
    trials_of_scan.push_back(std::move(trials));
  }
  TruncatedDetectionProbabilities(trials_of_scan, &curve);
  for (DetectionBin& bin : curve) {
    if (bin.predicted > 0) r->detection_by_range.push_back(bin);
  }
}

}  // namespace subslam::calibration::internal
