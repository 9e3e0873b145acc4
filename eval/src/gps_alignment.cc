#include "subslam/eval/gps_alignment.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"

namespace subslam::eval {

absl::StatusOr<Pose2> RigidAlignment2D(const std::vector<Eigen::Vector2d>& source,
                                       const std::vector<Eigen::Vector2d>& target) {
  if (source.size() != target.size() || source.size() < 2) {
    return absl::InvalidArgumentError(
        absl::StrCat("rigid alignment needs >= 2 point pairs, got ", source.size(), " and ", target.size()));
  }
  Eigen::Vector2d ms = Eigen::Vector2d::Zero(), mt = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < source.size(); ++i) {
    ms += source[i];
    mt += target[i];
  }
  ms /= source.size();
  mt /= target.size();
  // Closed-form 2-D rotation: θ = atan2(Σ s × t, Σ s · t) on centred points.
  double dot = 0.0, cross = 0.0;
  for (size_t i = 0; i < source.size(); ++i) {
    const Eigen::Vector2d s = source[i] - ms, t = target[i] - mt;
    dot += s.dot(t);
    cross += s.x() * t.y() - s.y() * t.x();
  }
  if (std::abs(dot) + std::abs(cross) < 1e-12) {
    return absl::InvalidArgumentError("rigid alignment: points are degenerate");
  }
  const double theta = std::atan2(cross, dot);
  const Pose2 rotation_only(0.0, 0.0, theta);
  const Eigen::Vector2d t = mt - rotation_only.rotation() * ms;
  return Pose2(t.x(), t.y(), theta);
}

std::vector<int> GrossGpsFaults(const std::vector<io::TimedPoint>& gps, const GpsFaultRule& rule) {
  std::vector<int> faults;
  const int n = static_cast<int>(gps.size());
  for (int i = 0; i < n; ++i) {
    std::vector<double> xs, ys;
    double dt = 0.0;
    for (int k = std::max(0, i - rule.neighbours); k <= std::min(n - 1, i + rule.neighbours); ++k) {
      if (k == i) continue;
      xs.push_back(gps[k].p.x());
      ys.push_back(gps[k].p.y());
      dt = std::max(dt, std::abs(gps[k].t - gps[i].t));
    }
    if (xs.empty()) continue;
    const auto median = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      const size_t m = v.size() / 2;
      return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
    };
    const Eigen::Vector2d centre(median(xs), median(ys));
    if ((gps[i].p - centre).norm() > rule.base_m + rule.speed_mps * dt) faults.push_back(i);
  }
  return faults;
}

absl::StatusOr<GpsComparison> CompareWithGps(const Trajectory& trajectory, const std::vector<io::TimedPoint>& gps,
                                             const GpsFaultRule& rule) {
  if (trajectory.size() < 2) return absl::InvalidArgumentError("trajectory too short");
  std::vector<char> fault(gps.size(), 0);
  for (int i : GrossGpsFaults(gps, rule)) fault[i] = 1;
  std::vector<Eigen::Vector2d> est, fix;
  size_t j = 0;
  int rejected = 0;
  for (size_t i = 0; i < gps.size(); ++i) {
    const io::TimedPoint& g = gps[i];
    if (g.t < trajectory.front().t || g.t > trajectory.back().t) continue;
    if (fault[i]) {
      ++rejected;
      continue;
    }
    while (j + 1 < trajectory.size() && trajectory[j + 1].t < g.t) ++j;
    const PoseEstimate& a = trajectory[j];
    const PoseEstimate& b = trajectory[std::min(j + 1, trajectory.size() - 1)];
    const double w = b.t > a.t ? std::clamp((g.t - a.t) / (b.t - a.t), 0.0, 1.0) : 0.0;
    est.push_back(a.pose.translation() + w * (b.pose.translation() - a.pose.translation()));
    fix.push_back(g.p);
  }
  absl::StatusOr<Pose2> transform = RigidAlignment2D(est, fix);
  if (!transform.ok()) return transform.status();
  GpsComparison c;
  c.matched_fixes = static_cast<int>(est.size());
  c.rejected_fixes = rejected;
  c.gps_T_estimate = *transform;
  double sx = 0, sy = 0;
  for (size_t i = 0; i < est.size(); ++i) {
    const Eigen::Vector2d r = TransformFrom(*transform, est[i]) - fix[i];
    sx += r.x() * r.x();
    sy += r.y() * r.y();
    c.max_m = std::max(c.max_m, r.norm());
  }
  const double n = static_cast<double>(est.size());
  c.rms_x_m = std::sqrt(sx / n);
  c.rms_y_m = std::sqrt(sy / n);
  c.rms_m = std::sqrt((sx + sy) / n);
  return c;
}

}  // namespace subslam::eval
