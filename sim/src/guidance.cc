#include "subslam/sim/guidance.h"

#include <algorithm>
#include <cmath>

namespace subslam::sim {

WaypointFollower::WaypointFollower(std::vector<Eigen::Vector2d> waypoints, const WaypointFollowerOptions& options)
    : waypoints_(std::move(waypoints)), options_(options) {}

Eigen::Vector2d WaypointFollower::Control(const Pose2& pose, double dt) {
  while (next_ < waypoints_.size() && (waypoints_[next_] - pose.translation()).norm() < options_.reach_m) {
    ++next_;
  }
  if (Finished()) return {0.0, options_.car_like ? u1_ : 0.0};
  const Eigen::Vector2d d = waypoints_[next_] - pose.translation();
  const double error = WrapAngle(std::atan2(d.y(), d.x()) - pose.theta);
  if (options_.car_like) {
    const double max_change = options_.max_u1_rate * dt;
    const double wanted = std::clamp(error, -options_.max_u1, options_.max_u1);
    u1_ += std::clamp(wanted - u1_, -max_change, max_change);
  } else {
    u1_ = std::clamp(options_.heading_gain * error, -options_.max_u1, options_.max_u1);
  }
  return {options_.speed_mps, u1_};
}

Eigen::Vector2d KanayamaControl(const Pose2& pose, const ReferenceState& reference,
                                const ReferenceTrackerGains& gains) {
  const Pose2 e = Between(pose, reference.pose);  // reference in the vehicle frame
  const double v = reference.v * std::cos(e.theta) + gains.k_x * e.x;
  const double omega = reference.omega + reference.v * (gains.k_y * e.y + gains.k_theta * std::sin(e.theta));
  return {v, omega};
}

}  // namespace subslam::sim
