// Named, seeded simulation scenarios reproducing the papers' set-ups (the papers cited
// in docs/scenarios.md). Where a paper leaves a parameter out, the value chosen here is
// marked "ours" in docs/scenarios.md, which lists every scenario's parameters.
//
//   combined-2km  Combined SLAM §7: 2 km × 2 km, 554 features, 3 m/s, 40 Hz / 5 Hz,
//                 180° FOV, 30 m, σ_v 0.3 m/s, σ_steer 3°, σ_r 0.5 m, σ_b 5°, one loop.
//   hybrid-120m   HybridSLAM §5: 120 m × 120 m, 35 features, 1 m/s, 360°, 25 m, 10 Hz,
//                 σ = 0.25·v and 0.35·ω, σ_r 0.05 m, σ_b 1°, α / β clutter options.
//   fmj-ellipse   FMJ §IV: the ellipse reference (30 m × 20 m semi-axes) tracked by
//                 Kanayama's law; case 1 (98 landmarks even along the path) or case 2
//                 (100 landmarks of uneven density).
//   iseif-circle  ISEIF §4.1: 20 waypoints on a circle, 200 landmarks on two circles
//                 astride it, wheelbase 4 m, 3 m/s, max steer 30°, σ (0.3 m/s, 2°),
//                 σ (0.2 m, 2°), 40 Hz / 5 Hz, 30 m.
//   random        knobs for scaling studies (world size, landmarks, path length, noise).
//   camera-robot  a small indoor robot of the MRCLAM kind (ours, from that data set's
//                 description): a 15 m × 8 m room, 15 landmarks, 0.2 m/s at random, a
//                 camera with a 62° field of view, 1–8.7 m, σ_r 0.1 m, σ_b 1°, detecting
//                 a landmark with probability 0.56 up to 2 m and less beyond; odometry
//                 reported as commanded while the robot drives at 0.93× and turns at
//                 0.95×; four other robots moving with the same markers; odometry gaps
//                 of up to 1 s.
//
// A scenario is fully determined by (name, options): the world (landmarks, waypoint
// jitter) is drawn from `world_seed` and the noise from `seed`.
#ifndef SUBSLAM_SIM_SCENARIO_H_
#define SUBSLAM_SIM_SCENARIO_H_

#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "subslam/io/dataset.h"
#include "subslam/sim/guidance.h"

namespace subslam::sim {

// User-facing knobs; every field has a documented default.
struct ScenarioOptions {
  uint64_t seed = 1;                              // noise, detections, clutter
  std::optional<uint64_t> world_seed;             // landmarks and path jitter; default: seed
  std::optional<double> detection_probability;    // α; default: the scenario's (1.0)
  std::optional<double> false_alarm_probability;  // β per visible feature; default 0.0
  std::optional<double> duration_s;               // truncate the run (default: whole path)
  // Objects moving with landmark markers (default: the scenario's; camera-robot 4); more
  // than none only where the scenario has a region for them (camera-robot).
  std::optional<int> moving_objects;
  int fmj_case = 1;  // fmj-ellipse: 1 or 2
  // random scenario knobs.
  double random_world_size_m = 200.0;  // square world side
  int random_landmarks = 300;          // uniformly placed landmarks
  // > 0: the landmarks on a square lattice of this spacing [m] over the whole world
  // instead (random_landmarks ignored): a world where a loop closure shifted by one
  // lattice cell fits almost as well as the right one.
  double random_lattice_spacing_m = 0.0;
  double random_path_length_m = 1000.0;  // distance driven
  double random_noise_scale = 1.0;       // multiplies every σ
  bool with_signature = false;           // detections carry a noisy landmark signature

  absl::Status Validate() const;
};

enum class Guidance { kWaypoints, kReference };

// Everything the simulator needs; produced by MakeScenario, editable by callers.
struct ScenarioConfig {
  std::string name;
  io::MotionConfig motion;            // the model and the control noise
  models::RangeBearingConfig sensor;  // the sensor and its noise
  double control_rate_hz = 40.0;
  int observation_every = 8;       // one scan every N control steps
  double max_duration_s = 1000.0;  // hard stop
  Pose2 initial_pose;
  Guidance guidance = Guidance::kWaypoints;
  std::vector<Eigen::Vector2d> waypoints;
  WaypointFollowerOptions follower;
  ReferenceFunction reference;  // kReference only
  ReferenceTrackerGains tracker_gains;
  std::vector<io::TruthLandmark> landmarks;
  double detection_probability = 1.0;    // α (ScenarioOptions overrides it)
  double false_alarm_probability = 0.0;  // β: per visible feature and scan
  // The detection probability falls with range: α up to detection_full_range_m, then
  // linearly to zero at the sensor's max_range_m (infinity: α at every range).
  double detection_full_range_m = std::numeric_limits<double>::infinity();
  // The vehicle moves by these factors of the commanded speed and turn rate, which the
  // data set reports as its odometry: a systematic error that the white noise of
  // `motion.noise` does not describe ({1, 1}: none).
  Eigen::Vector2d odometry_scale = Eigen::Vector2d::Ones();
  // Objects that move (other robots) and carry the landmarks' markers: each is detected as
  // a landmark would be and reported without a true id (a false alarm that persists and
  // moves). They drive at moving_object_speed_mps between random points of the region.
  int moving_objects = 0;
  double moving_object_speed_mps = 0.2;
  Eigen::AlignedBox2d moving_object_region;
  // Gaps in the odometry: at each control step a gap starts with this probability and
  // lasts uniform in (0, max_control_gap_s]; the vehicle moves on, and the data set holds
  // no control line inside the gap (the last one is held, as a reader of real logs does).
  double control_gap_probability = 0.0;
  double max_control_gap_s = 1.0;
  bool with_signature = false;
  double signature_sigma = 0.02;            // σ of the signature cue (e.g. trunk diameter [m])
  std::vector<double> landmark_signatures;  // true signature per landmark, when used
};

// Names accepted by MakeScenario.
std::vector<std::string> ScenarioNames();

absl::StatusOr<ScenarioConfig> MakeScenario(const std::string& name, const ScenarioOptions& options);

}  // namespace subslam::sim

#endif  // SUBSLAM_SIM_SCENARIO_H_
