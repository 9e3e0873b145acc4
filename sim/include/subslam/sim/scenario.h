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
//
// A scenario is fully determined by (name, options): the world (landmarks, waypoint
// jitter) is drawn from `world_seed` and the noise from `seed`.
#ifndef SUBSLAM_SIM_SCENARIO_H_
#define SUBSLAM_SIM_SCENARIO_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "subslam/io/dataset.h"
#include "subslam/sim/guidance.h"

namespace subslam::sim {

// User-facing knobs; every field has a documented default.
struct ScenarioOptions {
  uint64_t seed = 1;                       // noise, detections, clutter
  std::optional<uint64_t> world_seed;      // landmarks and path jitter; default: seed
  std::optional<double> detection_probability;    // α; default: the scenario's (1.0)
  std::optional<double> false_alarm_probability;  // β per visible feature; default 0.0
  std::optional<double> duration_s;        // truncate the run (default: whole path)
  int fmj_case = 1;                        // fmj-ellipse: 1 or 2
  // random scenario knobs.
  double random_world_size_m = 200.0;      // square world side
  int random_landmarks = 300;              // uniformly placed landmarks
  // > 0: the landmarks on a square lattice of this spacing [m] over the whole world
  // instead (random_landmarks ignored): a world where a loop closure shifted by one
  // lattice cell fits almost as well as the right one.
  double random_lattice_spacing_m = 0.0;
  double random_path_length_m = 1000.0;    // distance driven
  double random_noise_scale = 1.0;         // multiplies every σ
  bool with_signature = false;             // detections carry a noisy landmark signature

  absl::Status Validate() const;
};

enum class Guidance { kWaypoints, kReference };

// Everything the simulator needs; produced by MakeScenario, editable by callers.
struct ScenarioConfig {
  std::string name;
  io::MotionConfig motion;             // the model and the control noise
  models::RangeBearingConfig sensor;   // the sensor and its noise
  double control_rate_hz = 40.0;
  int observation_every = 8;           // one scan every N control steps
  double max_duration_s = 1000.0;      // hard stop
  Pose2 initial_pose;
  Guidance guidance = Guidance::kWaypoints;
  std::vector<Eigen::Vector2d> waypoints;
  WaypointFollowerOptions follower;
  ReferenceFunction reference;         // kReference only
  ReferenceTrackerGains tracker_gains;
  std::vector<io::TruthLandmark> landmarks;
  double detection_probability = 1.0;  // α
  double false_alarm_probability = 0.0;  // β: per visible feature and scan
  bool with_signature = false;
  double signature_sigma = 0.02;       // σ of the signature cue (e.g. trunk diameter [m])
  std::vector<double> landmark_signatures;  // true signature per landmark, when used
};

// Names accepted by MakeScenario.
std::vector<std::string> ScenarioNames();

absl::StatusOr<ScenarioConfig> MakeScenario(const std::string& name,
                                            const ScenarioOptions& options);

}  // namespace subslam::sim

#endif  // SUBSLAM_SIM_SCENARIO_H_
