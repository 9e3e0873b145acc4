#include "subslam/eval/trajectory_errors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_set>

#include "landmark_matching.h"
#include "subslam/eval/nees.h"
#include "subslam/models/gating.h"

namespace subslam::eval {

Pose2 InterpolatePose(const std::vector<io::TimedPose>& truth, double t) {
  if (truth.empty()) return Pose2();
  if (t <= truth.front().t) return truth.front().pose;
  if (t >= truth.back().t) return truth.back().pose;
  const auto it =
      std::lower_bound(truth.begin(), truth.end(), t, [](const io::TimedPose& p, double time) { return p.t < time; });
  const io::TimedPose& b = *it;
  if (b.t == t) return b.pose;
  const io::TimedPose& a = *(it - 1);
  const double w = (t - a.t) / (b.t - a.t);
  return Pose2(a.pose.x + w * (b.pose.x - a.pose.x), a.pose.y + w * (b.pose.y - a.pose.y),
               WrapAngle(a.pose.theta + w * WrapAngle(b.pose.theta - a.pose.theta)));
}

TrajectoryErrors ComputeTrajectoryErrors(const Trajectory& estimate, const std::vector<io::TimedPose>& truth,
                                         const TrajectoryErrorOptions& options) {
  TrajectoryErrors r;
  if (estimate.empty() || truth.empty()) return r;
  const double lo = models::ChiSquareQuantile(0.025, 3), hi = models::ChiSquareQuantile(0.975, 3);
  const double chi95 = models::ChiSquareQuantile(0.95, 3);
  const double fail_d2 = options.failure_sigma * options.failure_sigma;
  double sx = 0, sy = 0, sh = 0, nees_sum = 0;
  int nees_count = 0, in_bounds = 0, run = 0;
  for (const PoseEstimate& e : estimate) {
    const Pose2 t = InterpolatePose(truth, e.t);
    const Eigen::Vector3d d = PoseDifference(t, e.pose);
    sx += d.x() * d.x();
    sy += d.y() * d.y();
    sh += d.z() * d.z();
    const double pos = std::hypot(d.x(), d.y());
    r.max_position_error_m = std::max(r.max_position_error_m, pos);
    r.final_position_error_m = pos;
    const std::optional<double> nees = PoseNees(t, e.pose, e.covariance);
    const double value = nees.value_or(std::numeric_limits<double>::quiet_NaN());
    r.nees.push_back(value);
    if (nees.has_value()) {
      nees_sum += value;
      ++nees_count;
      if (value >= lo && value <= hi) ++in_bounds;
    }
    // A singular covariance (not evaluable) neither starts nor breaks an excursion.
    if (nees.has_value()) run = value > fail_d2 ? run + 1 : 0;
    r.longest_excursion_steps = std::max(r.longest_excursion_steps, run);
  }
  const double n = static_cast<double>(estimate.size());
  r.steps = static_cast<int>(estimate.size());
  r.rms_x_m = std::sqrt(sx / n);
  r.rms_y_m = std::sqrt(sy / n);
  r.rms_position_m = std::sqrt((sx + sy) / n);
  r.rms_heading_rad = std::sqrt(sh / n);
  r.mean_nees = nees_count > 0 ? nees_sum / nees_count : std::numeric_limits<double>::quiet_NaN();
  r.nees_steps = nees_count;
  r.fraction_nees_in_bounds = nees_count > 0 ? static_cast<double>(in_bounds) / nees_count : 0.0;
  r.mean_consistency_index = r.mean_nees / chi95;
  r.failed = r.longest_excursion_steps > options.failure_steps;
  return r;
}

MapErrors ComputeMapErrors(const std::vector<LandmarkEstimate>& estimate, const std::vector<io::TruthLandmark>& truth,
                           double match_radius_m) {
  MapErrors m;
  m.estimated = static_cast<int>(estimate.size());
  std::vector<Eigen::Vector2d> estimated(estimate.size()), true_positions(truth.size());
  for (size_t i = 0; i < estimate.size(); ++i) estimated[i] = estimate[i].position;
  for (size_t j = 0; j < truth.size(); ++j) true_positions[j] = truth[j].p;
  double sq = 0, sq_x = 0, sq_y = 0, nees = 0;
  int nees_count = 0;
  const LandmarkMatching matching = MatchWithinRadius(estimated, true_positions, match_radius_m);
  for (const auto& [e, t] : matching.pairs) {
    ++m.matched;
    const Eigen::Vector2d error = estimate[e].position - truth[t].p;
    sq += error.squaredNorm();
    sq_x += error.x() * error.x();
    sq_y += error.y() * error.y();
    if (auto v = PointNees(truth[t].p, estimate[e].position, estimate[e].covariance)) {
      nees += *v;
      ++nees_count;
    }
  }
  for (char near : matching.near_truth) m.spurious += near ? 0 : 1;
  m.duplicates = m.estimated - m.matched - m.spurious;
  m.rms_m = m.matched > 0 ? std::sqrt(sq / m.matched) : 0.0;
  m.rms_x_m = m.matched > 0 ? std::sqrt(sq_x / m.matched) : 0.0;
  m.rms_y_m = m.matched > 0 ? std::sqrt(sq_y / m.matched) : 0.0;
  m.mean_nees = nees_count > 0 ? nees / nees_count : 0.0;
  return m;
}

std::vector<io::TruthLandmark> ObservedTruthLandmarks(const io::Dataset& dataset) {
  if (!dataset.sensor.has_truth_id) return dataset.truth_landmarks;
  std::unordered_set<int> seen;
  for (const Scan& scan : dataset.scans) {
    for (const Detection& d : scan.detections) {
      if (d.truth_id >= 0) seen.insert(d.truth_id);
    }
  }
  std::vector<io::TruthLandmark> observed;
  for (const io::TruthLandmark& l : dataset.truth_landmarks) {
    if (seen.contains(l.id)) observed.push_back(l);
  }
  return observed;
}

}  // namespace subslam::eval
