#include "subslam/sim/scenario.h"

#include <cmath>
#include <random>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace subslam::sim {
namespace {

using Eigen::Vector2d;

// Point and unit tangent at arc length s along a polyline (s clamped to its length).
std::pair<Vector2d, Vector2d> PointAtArcLength(const std::vector<Vector2d>& path, double s) {
  for (size_t i = 0; i + 1 < path.size(); ++i) {
    const Vector2d seg = path[i + 1] - path[i];
    const double len = seg.norm();
    if (s <= len || i + 2 == path.size()) {
      const Vector2d dir = seg / len;
      return {path[i] + std::min(s, len) * dir, dir};
    }
    s -= len;
  }
  return {path.front(), Vector2d::UnitX()};
}

double PolylineLength(const std::vector<Vector2d>& path) {
  double l = 0.0;
  for (size_t i = 0; i + 1 < path.size(); ++i) l += (path[i + 1] - path[i]).norm();
  return l;
}

Pose2 StartPose(const std::vector<Vector2d>& waypoints) {
  const Vector2d d = waypoints[1] - waypoints[0];
  return Pose2(waypoints[0].x(), waypoints[0].y(), std::atan2(d.y(), d.x()));
}

// Landmarks scattered along a path: arc length uniform, lateral offset uniform in
// ±half_width (never closer than min_offset to the path centre line).
std::vector<io::TruthLandmark> CorridorLandmarks(const std::vector<Vector2d>& path, int count, double half_width,
                                                 double min_offset, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> along(0.0, PolylineLength(path));
  std::uniform_real_distribution<double> across(min_offset, half_width);
  std::bernoulli_distribution side(0.5);
  std::vector<io::TruthLandmark> out;
  for (int id = 0; id < count; ++id) {
    const auto [p, dir] = PointAtArcLength(path, along(rng));
    const Vector2d normal(-dir.y(), dir.x());
    out.push_back({id, p + (side(rng) ? 1.0 : -1.0) * across(rng) * normal});
  }
  return out;
}

ScenarioConfig Combined2km(std::mt19937_64& world) {
  ScenarioConfig c;
  c.name = "combined-2km";
  c.motion.model = io::MotionModelType::kAckermann;
  c.motion.geometry = {4.0, 0.0, 0.0, 0.0};  // wheelbase 4 m (ours), plain bicycle
  c.motion.noise = {0.3, DegToRad(3.0), 0.0, 0.0};
  c.sensor = {0.5, DegToRad(5.0), 0.0, 30.0, -kPi / 2, kPi / 2};
  c.control_rate_hz = 40.0;
  c.observation_every = 8;  // 5 Hz
  c.max_duration_s = 2000.0;
  // A loop around a 900 m square centred in the 2 km world (ours), 4 waypoints a side
  // jittered by ±60 m, then on past the start to close the loop.
  std::uniform_real_distribution<double> jitter(-60.0, 60.0);
  const double h = 450.0;
  const Vector2d corners[4] = {{-h, -h}, {h, -h}, {h, h}, {-h, h}};
  std::vector<Vector2d> loop;
  for (int side = 0; side < 4; ++side) {
    for (int k = 0; k < 4; ++k) {
      const Vector2d p = corners[side] + (corners[(side + 1) % 4] - corners[side]) * (k / 4.0);
      loop.push_back(p + Vector2d(jitter(world), jitter(world)));
    }
  }
  c.waypoints = loop;
  c.waypoints.push_back(loop[0]);
  c.waypoints.push_back(loop[1]);
  c.waypoints.push_back(loop[2]);
  c.initial_pose = StartPose(c.waypoints);
  c.follower = {3.0, 3.0, true, DegToRad(30.0), DegToRad(20.0), 0.0};
  std::vector<Vector2d> closed = loop;
  closed.push_back(loop[0]);
  c.landmarks = CorridorLandmarks(closed, 554, 35.0, 2.0, world);
  return c;
}

ScenarioConfig Hybrid120m(std::mt19937_64& world) {
  ScenarioConfig c;
  c.name = "hybrid-120m";
  c.motion.model = io::MotionModelType::kUnicycle;
  // σ = 0.25·v and 0.35·ω (HybridSLAM §5) plus small floors (ours) so that a
  // straight run (ω = 0) keeps a non-zero process noise.
  c.motion.noise = {0.01, DegToRad(0.5), 0.25, 0.35};
  c.sensor = {0.05, DegToRad(1.0), 0.0, 25.0, -kPi, kPi};
  c.control_rate_hz = 10.0;
  c.observation_every = 1;
  c.max_duration_s = 700.0;
  std::uniform_real_distribution<double> jitter(-5.0, 5.0);
  const Vector2d corners[4] = {{15, 15}, {105, 15}, {105, 105}, {15, 105}};
  std::vector<Vector2d> loop;
  for (const Vector2d& corner : corners) loop.push_back(corner + Vector2d(jitter(world), jitter(world)));
  c.waypoints = loop;
  c.waypoints.push_back(loop[0]);
  c.waypoints.push_back(loop[1]);  // one significant loop closure, then on
  c.initial_pose = StartPose(c.waypoints);
  c.follower = {1.0, 2.0, false, DegToRad(100.0), 0.0, 1.5};
  std::uniform_real_distribution<double> uniform(0.0, 120.0);
  for (int id = 0; id < 35; ++id) c.landmarks.push_back({id, {uniform(world), uniform(world)}});
  return c;
}

ScenarioConfig FmjEllipse(int fmj_case, std::mt19937_64& world) {
  ScenarioConfig c;
  c.name = "fmj-ellipse";
  c.motion.model = io::MotionModelType::kUnicycle;
  c.motion.noise = {0.1, DegToRad(2.0), 0.0, 0.0};        // ours: FMJ gives no values
  c.sensor = {0.1, DegToRad(1.0), 0.0, 12.0, -kPi, kPi};  // ours
  c.control_rate_hz = 40.0;
  c.observation_every = 4;                // 10 Hz (ours)
  const double period = 2.0 * kPi / 0.1;  // one lap of FMJ Eq. 11
  c.max_duration_s = 1.5 * period;
  c.guidance = Guidance::kReference;
  c.reference = [](double t) {
    // FMJ Eq. 11: x = 30 sin(0.1 t), y = 20 cos(0.1 t) − 20.
    const double s = std::sin(0.1 * t), co = std::cos(0.1 * t);
    const double dx = 3.0 * co, dy = -2.0 * s;     // first derivatives
    const double ddx = -0.3 * s, ddy = -0.2 * co;  // second derivatives
    ReferenceState r;
    r.pose = Pose2(30.0 * s, 20.0 * co - 20.0, std::atan2(dy, dx));
    r.v = std::hypot(dx, dy);
    r.omega = (dx * ddy - dy * ddx) / (dx * dx + dy * dy);
    return r;
  };
  c.initial_pose = c.reference(0.0).pose;
  // Landmarks beside the path at 2–6 m either side (ours), by arc length: case 1
  // evenly (49 a side), case 2 with 60 of 100 in the first quarter of the lap.
  std::vector<Vector2d> lap;
  for (int k = 0; k <= 400; ++k) lap.push_back(c.reference(period * k / 400.0).pose.translation());
  const double length = PolylineLength(lap);
  std::uniform_real_distribution<double> offset(2.0, 6.0), unit(0.0, 1.0);
  const int count = fmj_case == 1 ? 98 : 100;
  for (int id = 0; id < count; ++id) {
    double fraction;
    if (fmj_case == 1) {
      fraction = (id / 2 + 0.5 * unit(world)) / (count / 2);
    } else {
      fraction = id < 60 ? 0.25 * unit(world) : 0.25 + 0.75 * unit(world);
    }
    const auto [p, dir] = PointAtArcLength(lap, fraction * length);
    const Vector2d normal(-dir.y(), dir.x());
    c.landmarks.push_back({id, p + (id % 2 == 0 ? 1.0 : -1.0) * offset(world) * normal});
  }
  return c;
}

ScenarioConfig IseifCircle() {
  ScenarioConfig c;
  c.name = "iseif-circle";
  c.motion.model = io::MotionModelType::kAckermann;
  c.motion.geometry = {4.0, 0.0, 0.0, 0.0};
  c.motion.noise = {0.3, DegToRad(2.0), 0.0, 0.0};
  c.sensor = {0.2, DegToRad(2.0), 0.0, 30.0, -kPi / 2, kPi / 2};  // 180° FOV (ours)
  c.control_rate_hz = 40.0;
  c.observation_every = 8;
  c.max_duration_s = 1000.0;
  // Circle of radius 100 m (ours) through the start (0, 0), centre (0, 100).
  const double radius = 100.0;
  const Vector2d centre(0.0, radius);
  auto on_circle = [&](double r, double angle) {
    return Vector2d(centre.x() + r * std::sin(angle), centre.y() - r * std::cos(angle));
  };
  for (int i = 1; i <= 20; ++i) c.waypoints.push_back(on_circle(radius, kTwoPi * i / 20));
  for (int i = 1; i <= 2; ++i) c.waypoints.push_back(on_circle(radius, kTwoPi * i / 20));
  c.initial_pose = Pose2(0.0, 0.0, 0.0);
  c.follower = {3.0, 2.0, true, DegToRad(30.0), DegToRad(20.0), 0.0};
  // 200 landmarks on two circles astride the path (ours: radii 100 ∓ 8 m).
  for (int i = 0; i < 100; ++i) {
    const double a = kTwoPi * (i + 0.25) / 100;
    c.landmarks.push_back({2 * i, on_circle(radius - 8.0, a)});
    c.landmarks.push_back({2 * i + 1, on_circle(radius + 8.0, a + kPi / 100)});
  }
  return c;
}

ScenarioConfig Random(const ScenarioOptions& o, std::mt19937_64& world) {
  ScenarioConfig c;
  c.name = "random";
  const double k = o.random_noise_scale, size = o.random_world_size_m;
  c.motion.model = io::MotionModelType::kUnicycle;
  c.motion.noise = {0.1 * k, DegToRad(2.0) * k, 0.05 * k, 0.05 * k};
  c.sensor = {0.1 * k, DegToRad(1.0) * k, 0.0, 20.0, -kPi, kPi};
  c.control_rate_hz = 20.0;
  c.observation_every = 4;
  const double speed = 2.0;
  c.max_duration_s = o.random_path_length_m / speed * 1.2;
  // A jittered polygon around the centre, repeated until the path length is covered.
  std::uniform_real_distribution<double> jitter(-0.08 * size, 0.08 * size);
  std::vector<Vector2d> loop;
  for (int i = 0; i < 8; ++i) {
    const double a = kTwoPi * i / 8;
    loop.push_back(Vector2d(size / 2, size / 2) + 0.35 * size * Vector2d(std::cos(a), std::sin(a)) +
                   Vector2d(jitter(world), jitter(world)));
  }
  double length = 0.0;
  c.waypoints.push_back(loop[0]);
  for (size_t i = 1; length < o.random_path_length_m; ++i) {
    const Vector2d& p = loop[i % loop.size()];
    length += (p - c.waypoints.back()).norm();
    c.waypoints.push_back(p);
  }
  c.initial_pose = StartPose(c.waypoints);
  c.follower = {speed, 2.0, false, DegToRad(60.0), 0.0, 1.5};
  const double spacing = o.random_lattice_spacing_m;
  if (spacing > 0.0) {
    int id = 0;
    for (double x = 0.5 * spacing; x < size; x += spacing) {
      for (double y = 0.5 * spacing; y < size; y += spacing) c.landmarks.push_back({id++, {x, y}});
    }
    return c;
  }
  std::uniform_real_distribution<double> uniform(0.0, size);
  for (int id = 0; id < o.random_landmarks; ++id) {
    c.landmarks.push_back({id, {uniform(world), uniform(world)}});
  }
  return c;
}

// A small indoor robot with a camera, of the MRCLAM kind (its data set's description):
// what a user's first estimates do not describe — the detection probability falling with
// range, commanded odometry with a scale bias, moving objects with landmark markers and
// odometry gaps — so that tests cover it without real data.
ScenarioConfig CameraRobot(std::mt19937_64& world) {
  ScenarioConfig c;
  c.name = "camera-robot";
  c.motion.model = io::MotionModelType::kUnicycle;
  c.motion.noise = {0.02, DegToRad(3.0), 0.1, 0.1};
  c.sensor = {0.1, DegToRad(1.0), 1.0, 8.7, -0.595, 0.498};
  c.control_rate_hz = 50.0;
  c.observation_every = 12;  // about 4 Hz
  c.max_duration_s = 740.0;
  c.detection_probability = 0.56;
  c.detection_full_range_m = 2.0;
  c.odometry_scale = Vector2d(0.93, 0.95);
  const Eigen::AlignedBox2d room(Vector2d(0.0, 0.0), Vector2d(15.0, 8.0));
  c.moving_objects = 4;
  c.moving_object_speed_mps = 0.2;
  c.moving_object_region = room;
  c.control_gap_probability = 150.0 / (740.0 * 50.0);  // about 150 gaps in the run
  c.max_control_gap_s = 1.0;
  // Landmarks at least 1.5 m apart, 0.5 m inside the walls.
  std::uniform_real_distribution<double> x(0.5, 14.5), y(0.5, 7.5);
  while (c.landmarks.size() < 15) {
    const Vector2d p(x(world), y(world));
    bool apart = true;
    for (const io::TruthLandmark& l : c.landmarks) apart = apart && (l.p - p).norm() >= 1.5;
    if (apart) c.landmarks.push_back({static_cast<int>(c.landmarks.size()), p});
  }
  // Random waypoints 1 m inside the walls, at least 3 m apart, for the whole run.
  std::uniform_real_distribution<double> wx(1.0, 14.0), wy(1.0, 7.0);
  const double speed = 0.2;
  c.waypoints.push_back(Vector2d(wx(world), wy(world)));
  for (double length = 0.0; length < speed * c.max_duration_s * 1.2;) {
    const Vector2d p(wx(world), wy(world));
    if ((p - c.waypoints.back()).norm() < 3.0) continue;
    length += (p - c.waypoints.back()).norm();
    c.waypoints.push_back(p);
  }
  c.initial_pose = StartPose(c.waypoints);
  c.follower = {speed, 0.5, false, 1.0, 0.0, 1.0};
  return c;
}

}  // namespace

absl::Status ScenarioOptions::Validate() const {
  auto probability = [](const std::optional<double>& p) {
    return !p.has_value() || (std::isfinite(*p) && *p >= 0.0 && *p <= 1.0);
  };
  if (!probability(detection_probability) || !probability(false_alarm_probability)) {
    return absl::InvalidArgumentError("detection and false-alarm probabilities must be in [0, 1]");
  }
  if (moving_objects.has_value() && *moving_objects < 0) {
    return absl::InvalidArgumentError(absl::StrCat("moving objects must be >= 0, got ", *moving_objects));
  }
  if (duration_s.has_value() && !(std::isfinite(*duration_s) && *duration_s > 0.0)) {
    return absl::InvalidArgumentError("duration must be > 0");
  }
  if (fmj_case != 1 && fmj_case != 2) {
    return absl::InvalidArgumentError(absl::StrCat("fmj_case must be 1 or 2, got ", fmj_case));
  }
  if (!(random_lattice_spacing_m >= 0.0 && std::isfinite(random_lattice_spacing_m) &&
        (random_lattice_spacing_m == 0.0 || random_lattice_spacing_m >= 0.5))) {
    return absl::InvalidArgumentError("random scenario: lattice spacing must be 0 (off) or >= 0.5 m");
  }
  if (!(random_world_size_m > 10.0 && random_landmarks >= 0 && random_path_length_m > 0.0 &&
        random_noise_scale > 0.0)) {
    return absl::InvalidArgumentError(
        "random scenario: need world size > 10 m, landmarks >= 0, path length > 0, noise scale > 0");
  }
  return absl::OkStatus();
}

std::vector<std::string> ScenarioNames() {
  return {"combined-2km", "hybrid-120m", "fmj-ellipse", "iseif-circle", "random", "camera-robot"};
}

absl::StatusOr<ScenarioConfig> MakeScenario(const std::string& name, const ScenarioOptions& options) {
  if (absl::Status s = options.Validate(); !s.ok()) return s;
  std::mt19937_64 world(options.world_seed.value_or(options.seed) * 0x9E3779B97F4A7C15ULL + 17);
  ScenarioConfig c;
  if (name == "combined-2km") {
    c = Combined2km(world);
  } else if (name == "hybrid-120m") {
    c = Hybrid120m(world);
  } else if (name == "fmj-ellipse") {
    c = FmjEllipse(options.fmj_case, world);
  } else if (name == "iseif-circle") {
    c = IseifCircle();
  } else if (name == "random") {
    c = Random(options, world);
  } else if (name == "camera-robot") {
    c = CameraRobot(world);
  } else {
    return absl::InvalidArgumentError(
        absl::StrCat("unknown scenario \"", name, "\" (known: ", absl::StrJoin(ScenarioNames(), ", "), ")"));
  }
  c.detection_probability = options.detection_probability.value_or(c.detection_probability);
  c.false_alarm_probability = options.false_alarm_probability.value_or(c.false_alarm_probability);
  if (options.duration_s.has_value()) c.max_duration_s = std::min(c.max_duration_s, *options.duration_s);
  if (options.moving_objects.has_value()) {
    if (*options.moving_objects > 0 && c.moving_object_region.isEmpty()) {
      return absl::InvalidArgumentError(absl::StrCat("moving objects must be 0 in scenario \"", name,
                                                     "\" (only camera-robot has a region for them)"));
    }
    c.moving_objects = *options.moving_objects;
  }
  c.with_signature = options.with_signature;
  if (c.with_signature) {
    std::uniform_real_distribution<double> diameter(0.1, 0.6);
    for (size_t i = 0; i < c.landmarks.size(); ++i) c.landmark_signatures.push_back(diameter(world));
  }
  return c;
}

}  // namespace subslam::sim
