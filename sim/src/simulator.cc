#include "subslam/sim/simulator.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "absl/strings/str_cat.h"

namespace subslam::sim {
namespace {

// The detection probability at range r: α up to full_range, then linearly to zero at
// max_range.
double DetectionProbability(const ScenarioConfig& c, double range) {
  if (range <= c.detection_full_range_m) return c.detection_probability;
  const double span = c.sensor.max_range_m - c.detection_full_range_m;
  return span > 0.0 ? c.detection_probability * std::max(0.0, (c.sensor.max_range_m - range) / span) : 0.0;
}

// An object that drives at constant speed between random points of a region.
struct MovingObject {
  Eigen::Vector2d p;
  Eigen::Vector2d goal;
};

Eigen::Vector2d RandomPoint(const Eigen::AlignedBox2d& region, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> ux(region.min().x(), region.max().x());
  std::uniform_real_distribution<double> uy(region.min().y(), region.max().y());
  const double x = ux(rng);
  return {x, uy(rng)};
}

void Move(MovingObject* o, double step_m, const Eigen::AlignedBox2d& region, std::mt19937_64& rng) {
  const Eigen::Vector2d d = o->goal - o->p;
  if (d.norm() <= step_m) {
    o->p = o->goal;
    o->goal = RandomPoint(region, rng);
  } else {
    o->p += step_m * d.normalized();
  }
}

// The scenario's settings are usable: valid sensor and noise, a control rate, guidance.
absl::Status CheckScenarioConfig(const ScenarioConfig& config) {
  if (absl::Status s = config.sensor.Validate(); !s.ok()) return s;
  if (absl::Status s = config.motion.noise.Validate(); !s.ok()) return s;
  if (!(config.control_rate_hz > 0.0) || config.observation_every < 1) {
    return absl::InvalidArgumentError("control rate must be > 0 and observation_every >= 1");
  }
  if (config.guidance == Guidance::kWaypoints && config.waypoints.empty()) {
    return absl::InvalidArgumentError("waypoint guidance needs waypoints");
  }
  if (config.guidance == Guidance::kReference && !config.reference) {
    return absl::InvalidArgumentError("reference guidance needs a reference function");
  }
  return absl::OkStatus();
}

// The scan at t from pose x: each landmark in range and view detected with the scenario's
// probability, a false alarm per landmark with its probability, the moving objects' markers
// (no true id). The draws come from `rng` through `gauss` and `unit` in a fixed order.
Scan SimulateScan(const ScenarioConfig& config, const models::RangeBearingModel& sensor, const Pose2& x, double t,
                  const std::vector<MovingObject>& objects, std::mt19937_64& rng,
                  std::normal_distribution<double>* gauss, std::uniform_real_distribution<double>* unit) {
  const models::RangeBearingConfig& rb = config.sensor;
  Scan scan;
  scan.t = t;
  for (size_t i = 0; i < config.landmarks.size(); ++i) {
    const io::TruthLandmark& l = config.landmarks[i];
    if ((l.p - x.translation()).squaredNorm() > rb.max_range_m * rb.max_range_m * 1.01) continue;
    const Eigen::Vector2d z = sensor.Observe(x, l.p);
    if (!sensor.IsVisible(z)) continue;
    if ((*unit)(rng) < DetectionProbability(config, z[0])) {
      Detection det;
      det.range_m = std::max(1e-3, z[0] + rb.sigma_range_m * (*gauss)(rng));
      det.bearing_rad = WrapAngle(z[1] + rb.sigma_bearing_rad * (*gauss)(rng));
      det.truth_id = l.id;
      if (config.with_signature) {
        det.signature = config.landmark_signatures[i] + config.signature_sigma * (*gauss)(rng);
      }
      scan.detections.push_back(det);
    }
    if ((*unit)(rng) < config.false_alarm_probability) {
      Detection fa;
      fa.range_m = std::max(1e-3, rb.min_range_m + (rb.max_range_m - rb.min_range_m) * (*unit)(rng));
      fa.bearing_rad = rb.fov_min_rad + (rb.fov_max_rad - rb.fov_min_rad) * (*unit)(rng);
      fa.truth_id = kFalseAlarmId;
      if (config.with_signature) fa.signature = 0.1 + 0.5 * (*unit)(rng);
      scan.detections.push_back(fa);
    }
  }
  for (const MovingObject& o : objects) {  // markers on other robots: seen, with no true id
    const Eigen::Vector2d z = sensor.Observe(x, o.p);
    if (!sensor.IsVisible(z) || !((*unit)(rng) < DetectionProbability(config, z[0]))) continue;
    Detection det;
    det.range_m = std::max(1e-3, z[0] + rb.sigma_range_m * (*gauss)(rng));
    det.bearing_rad = WrapAngle(z[1] + rb.sigma_bearing_rad * (*gauss)(rng));
    det.truth_id = kFalseAlarmId;
    if (config.with_signature) det.signature = 0.1 + 0.5 * (*unit)(rng);
    scan.detections.push_back(det);
  }
  std::shuffle(scan.detections.begin(), scan.detections.end(), rng);
  return scan;
}

}  // namespace

absl::StatusOr<io::Dataset> Simulate(const ScenarioConfig& config, uint64_t seed) {
  if (absl::Status s = CheckScenarioConfig(config); !s.ok()) return s;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);

  io::Dataset d;
  d.name = config.name;
  d.initial_pose = config.initial_pose;
  d.motion = config.motion;
  d.sensor.range_bearing = config.sensor;
  d.sensor.has_truth_id = true;
  d.sensor.has_signature = config.with_signature;
  d.truth_landmarks = config.landmarks;

  const std::unique_ptr<models::MotionModel> model = config.motion.MakeModel();
  const models::RangeBearingModel sensor(config.sensor);
  const double dt = 1.0 / config.control_rate_hz;
  const auto steps = static_cast<int64_t>(std::floor(config.max_duration_s * config.control_rate_hz));
  WaypointFollower follower(config.waypoints, config.follower);

  Pose2 x = config.initial_pose;
  d.truth_poses.push_back({0.0, x});
  std::vector<MovingObject> objects(config.moving_objects);
  for (MovingObject& o : objects) {
    o.p = RandomPoint(config.moving_object_region, rng);
    o.goal = RandomPoint(config.moving_object_region, rng);
  }
  double gap_until = -1.0;  // no control lines before this time [s]
  for (int64_t k = 0; k < steps; ++k) {
    const double t = k * dt;
    Eigen::Vector2d u;
    if (config.guidance == Guidance::kWaypoints) {
      if (follower.Finished()) break;
      u = follower.Control(x, dt);
    } else {
      u = KanayamaControl(x, config.reference(t), config.tracker_gains);
    }
    // The commanded control is what odometry reports; the vehicle actually moves
    // with the commanded control plus noise of covariance M(u_commanded), so the
    // estimator's noise model M(u_reported) is exactly the truth's.
    const Eigen::Matrix2d m = config.motion.noise.Covariance(u);
    // With an odometry scale bias the vehicle moves by scale ⊙ u while u is reported.
    const Eigen::Vector2d actual(config.odometry_scale[0] * u[0] + std::sqrt(m(0, 0)) * gauss(rng),
                                 config.odometry_scale[1] * u[1] + std::sqrt(m(1, 1)) * gauss(rng));
    // A gap starts after a reported control: the next line comes at most
    // max_control_gap_s (plus a step) later.
    if (t >= gap_until) {
      d.controls.push_back({t, u});
      if (config.control_gap_probability > 0.0 && unit(rng) < config.control_gap_probability) {
        gap_until = t + config.max_control_gap_s * (1.0 - unit(rng));  // uniform in (0, max]
      }
    }
    for (MovingObject& o : objects) Move(&o, config.moving_object_speed_mps * dt, config.moving_object_region, rng);
    x = model->Predict(x, actual, dt);
    const double t_next = (k + 1) * dt;
    d.truth_poses.push_back({t_next, x});
    if ((k + 1) % config.observation_every != 0) continue;

    Scan scan = SimulateScan(config, sensor, x, t_next, objects, rng, &gauss, &unit);
    if (!scan.detections.empty()) d.scans.push_back(std::move(scan));
  }
  if (d.controls.empty()) return absl::InvalidArgumentError("simulation produced no steps");
  return d;
}

absl::StatusOr<io::Dataset> SimulateScenario(const std::string& name, const ScenarioOptions& options) {
  absl::StatusOr<ScenarioConfig> config = MakeScenario(name, options);
  if (!config.ok()) return config.status();
  return Simulate(*config, options.seed);
}

}  // namespace subslam::sim
