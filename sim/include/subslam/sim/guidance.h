// Guidance laws that drive the simulated vehicle along its ground-truth path. They act
// on the TRUE pose (the simulator knows it) and output the true control; the simulator
// then corrupts the control with noise for the estimator.
//
// WaypointFollower — steer towards the current waypoint, switch to the next within
// `reach_m`. For a car (Ackermann) the output steering angle is the heading error,
// rate-limited and clamped (the classic SLAM-simulator guidance of Bailey's toolbox,
// used by the Combined SLAM and ISEIF experiments); for a unicycle the turn rate is
// `heading_gain` × heading error, clamped.
//
// ReferenceTracker — Kanayama's tracking law on a time-parametrised reference
// (FMJ §IV, Eq. 12):  v = v_r cos θ_e + K_x x_e,  ω = ω_r + v_r (K_y y_e + K_θ sin θ_e),
// with (x_e, y_e, θ_e) the reference pose in the vehicle frame.
#ifndef SUBSLAM_SIM_GUIDANCE_H_
#define SUBSLAM_SIM_GUIDANCE_H_

#include <Eigen/Core>
#include <functional>
#include <vector>

#include "subslam/core/pose2.h"

namespace subslam::sim {

struct WaypointFollowerOptions {
  double speed_mps = 3.0;               // commanded speed
  double reach_m = 2.0;                 // switch to the next waypoint within this distance
  bool car_like = true;                 // true: u1 = steering angle; false: u1 = turn rate
  double max_u1 = DegToRad(30.0);       // max |steer| [rad] or |ω| [rad/s]
  double max_u1_rate = DegToRad(20.0);  // max |d steer / dt| [rad/s] (car only)
  double heading_gain = 1.5;            // ω per rad of heading error [1/s] (unicycle only)
};

class WaypointFollower {
 public:
  WaypointFollower(std::vector<Eigen::Vector2d> waypoints, const WaypointFollowerOptions& options);

  // The true control (v, u1) for the next dt seconds, given the true pose.
  Eigen::Vector2d Control(const Pose2& pose, double dt);
  bool Finished() const { return next_ >= waypoints_.size(); }
  size_t next_waypoint() const { return next_; }

 private:
  std::vector<Eigen::Vector2d> waypoints_;
  WaypointFollowerOptions options_;
  size_t next_ = 0;
  double u1_ = 0.0;
};

// A reference trajectory: pose, speed v_r and turn rate ω_r at time t.
struct ReferenceState {
  Pose2 pose;
  double v = 0.0;
  double omega = 0.0;
};
using ReferenceFunction = std::function<ReferenceState(double t)>;

struct ReferenceTrackerGains {
  double k_x = 32.0;  // FMJ Eq. 12 as printed
  double k_y = 20.0;
  double k_theta = 0.01;
};

// Kanayama tracking control (unicycle output (v, ω)).
Eigen::Vector2d KanayamaControl(const Pose2& pose, const ReferenceState& reference, const ReferenceTrackerGains& gains);

}  // namespace subslam::sim

#endif  // SUBSLAM_SIM_GUIDANCE_H_
