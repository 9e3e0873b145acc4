#include "subslam/pipeline/calibrate_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "report_json.h"
#include "subslam/eval/trajectory_errors.h"
#include "subslam/io/output_directory.h"

namespace subslam::pipeline {

CalibrateOptions::CalibrateOptions() {
  start.frontend = Frontend::kRbpf;
  start.backend.kind = Backend::kEif;
}

absl::Status CalibrateOptions::Validate() const {
  if (absl::Status s = calibration.Validate(); !s.ok()) return s;
  return start.Validate();
}

namespace {

// The start run's pose at each scan time (its final trajectory, one entry per step).
absl::Status StartPoses(const io::Dataset& d, const Trajectory& trajectory, calibration::CalibrationStart* start) {
  for (const Scan& scan : d.scans) {
    const auto it = std::lower_bound(trajectory.begin(), trajectory.end(), scan.t,
                                     [](const PoseEstimate& p, double t) { return p.t < t; });
    if (it == trajectory.end() || it->t != scan.t) {
      return absl::InternalError(absl::StrCat("calibrate: the start run has no pose at the scan at t = ", scan.t));
    }
    start->scan_poses.push_back(it->pose);
    start->scan_covariances.push_back(it->covariance);
  }
  return absl::OkStatus();
}

double RmsPosition(const io::Dataset& d, const std::vector<Pose2>& poses) {
  Trajectory t;
  for (size_t j = 0; j < poses.size(); ++j) t.push_back({d.scans[j].t, poses[j], Eigen::Matrix3d::Zero()});
  return eval::ComputeTrajectoryErrors(t, d.truth_poses).rms_position_m;
}

void SetKnownAssociation(bool known, RunOptions* o) {
  o->ekf.landmarks.known_association = known;
  o->fastslam.landmarks.known_association = known;
  o->seif.landmarks.known_association = known;
  o->backend.eif.association.known_association = known;
  o->backend.ekf.association.known_association = known;
}

}  // namespace

absl::StatusOr<CalibrateResult> RunCalibration(io::Dataset dataset, const CalibrateOptions& options) {
  if (absl::Status s = options.Validate(); !s.ok()) return s;
  const auto t0 = std::chrono::steady_clock::now();
  CalibrateResult result;
  result.source = options.source;
  result.motion_before = dataset.motion;
  result.sensor_before = dataset.sensor.range_bearing;
  RunOptions start_options = options.start;
  start_options.out_dir.clear();
  start_options.progress = false;
  SetKnownAssociation(options.calibration.known_association, &start_options);
  absl::StatusOr<RunResult> run = RunPipeline(dataset, start_options);
  if (!run.ok()) return run.status();
  if (run->stop)
    return absl::FailedPreconditionError(absl::StrCat("calibrate: the start run stopped: ", run->stop->reason));
  calibration::CalibrationStart start;
  if (absl::Status s = StartPoses(dataset, run->final_trajectory, &start); !s.ok()) return s;
  for (const LandmarkEstimate& l : run->landmarks) {
    start.landmarks.push_back(l.position);
    start.landmark_covariances.push_back(l.covariance);
  }
  result.start_landmarks = static_cast<int>(run->landmarks.size());
  if (run->errors) result.start_rms_position_m = run->errors->rms_position_m;
  absl::StatusOr<calibration::RobotCalibration> c = calibration::CalibrateRobot(dataset, start, options.calibration);
  if (!c.ok()) return c.status();
  result.calibration = *std::move(c);
  if (!dataset.truth_poses.empty()) result.rms_position_m = RmsPosition(dataset, result.calibration.scan_poses);
  result.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!options.out_dir.empty()) {
    absl::StatusOr<std::filesystem::path> dir = io::PrepareOutputDirectory(options.out_dir, "calibrate");
    if (!dir.ok()) return dir.status();
    std::ofstream out(*dir / "calibration.json");
    out << CalibrationJson(result, options.invocation).dump(2) << "\n";
    if (!out) return absl::InternalError(absl::StrCat("cannot write ", (*dir / "calibration.json").string()));
  }
  return result;
}

namespace {

nlohmann::json MotionJson(const io::MotionConfig& m, const std::array<double, 4>& noise, bool with_correction) {
  const std::string ch1 = m.model == io::MotionModelType::kUnicycle ? "sigma_omega" : "sigma_steer";
  nlohmann::json j = {{"sigma_v", noise[0]}, {"sigma_v_scale", noise[1]}, {ch1, noise[2]}, {ch1 + "_scale", noise[3]}};
  if (with_correction) {
    j["control_scale"] = {m.control_scale[0], m.control_scale[1]};
    j["control_offset"] = {m.control_offset[0], m.control_offset[1]};
  }
  return j;
}

nlohmann::json SensorJson(const models::RangeBearingConfig& rb) {
  return {{"sigma_range", rb.sigma_range_m},
          {"sigma_bearing", rb.sigma_bearing_rad},
          {"min_range", rb.min_range_m},
          {"max_range", rb.max_range_m},
          {"fov", {rb.fov_min_rad, rb.fov_max_rad}}};
}

}  // namespace

nlohmann::json CalibrationJson(const CalibrateResult& r, const nlohmann::json& invocation) {
  const calibration::RobotCalibration& c = r.calibration;
  io::MotionConfig motion = r.motion_before;
  motion.control_scale = c.control_scale;
  motion.control_offset = c.control_offset;
  models::RangeBearingConfig sensor = r.sensor_before;
  sensor.sigma_range_m = c.sigma_range_m.value;
  sensor.sigma_bearing_rad = c.sigma_bearing_rad.value;
  sensor.min_range_m = c.min_range_m;
  sensor.max_range_m = c.max_range_m;
  sensor.fov_min_rad = c.fov_min_rad;
  sensor.fov_max_rad = c.fov_max_rad;
  const std::array<double, 4> noise = {c.control_noise[0].value, c.control_noise[1].value, c.control_noise[2].value,
                                       c.control_noise[3].value};
  const std::array<double, 4> noise_se = {c.control_noise[0].standard_error, c.control_noise[1].standard_error,
                                          c.control_noise[2].standard_error, c.control_noise[3].standard_error};
  const models::ControlNoise& n0 = r.motion_before.noise;
  nlohmann::json standard_errors = {
      {"motion", MotionJson(motion, noise_se, false)},
      {"sensor",
       {{"sigma_range", c.sigma_range_m.standard_error}, {"sigma_bearing", c.sigma_bearing_rad.standard_error}}}};
  standard_errors["motion"]["control_scale"] = {c.correction_standard_error[0], c.correction_standard_error[1]};
  standard_errors["motion"]["control_offset"] = {0.0, c.correction_standard_error[2]};
  nlohmann::json curve = nlohmann::json::array();
  for (const calibration::DetectionBin& b : c.detection_by_range) {
    curve.push_back({{"range_min", b.range_min_m},
                     {"range_max", b.range_max_m},
                     {"predicted", b.predicted},
                     {"detected", b.detected},
                     {"probability", b.probability},
                     {"lower", b.lower},
                     {"upper", b.upper}});
  }
  nlohmann::json fit = {
      {"detections", c.detections}, {"paired", c.detections_paired},        {"outliers", c.detections_outliers},
      {"landmarks", c.landmarks},   {"redundancy", c.redundancy},           {"rounds", c.rounds},
      {"converged", c.converged},   {"start_landmarks", r.start_landmarks}, {"seconds", r.wall_seconds}};
  if (r.start_rms_position_m) fit["start_rms_position_m"] = *r.start_rms_position_m;
  if (r.rms_position_m) fit["rms_position_m"] = *r.rms_position_m;
  return {{"source", r.source},
          {"manifest_fragment", {{"motion", MotionJson(motion, noise, true)}, {"sensor", SensorJson(sensor)}}},
          {"standard_errors", standard_errors},
          {"before",
           {{"motion", MotionJson(r.motion_before, {n0.sigma_u0, n0.scale_u0, n0.sigma_u1, n0.scale_u1}, true)},
            {"sensor", SensorJson(r.sensor_before)}}},
          {"detection_probability_by_range", curve},
          {"fit", fit},
          {"build", BuildJson()},
          {"invocation", invocation}};
}

std::string CalibrationTable(const CalibrateResult& r) {
  const calibration::RobotCalibration& c = r.calibration;
  const models::ControlNoise& n = r.motion_before.noise;
  std::string t;
  const auto row = [&t](const std::string& name, double before, const calibration::Estimated& e) {
    absl::StrAppendFormat(&t, "  %-34s %10.5g -> %10.5g  (se %.2g)\n", name, before, e.value, e.standard_error);
  };
  row("sigma_v [m/s]", n.sigma_u0, c.control_noise[0]);
  row("sigma_v_scale", n.scale_u0, c.control_noise[1]);
  row("sigma_u1 [rad/s or rad]", n.sigma_u1, c.control_noise[2]);
  row("sigma_u1_scale", n.scale_u1, c.control_noise[3]);
  row("sigma_range [m]", r.sensor_before.sigma_range_m, c.sigma_range_m);
  row("sigma_bearing [rad]", r.sensor_before.sigma_bearing_rad, c.sigma_bearing_rad);
  row("control_scale[0]", r.motion_before.control_scale[0], {c.control_scale[0], c.correction_standard_error[0]});
  row("control_scale[1]", r.motion_before.control_scale[1], {c.control_scale[1], c.correction_standard_error[1]});
  row("control_offset[1]", r.motion_before.control_offset[1], {c.control_offset[1], c.correction_standard_error[2]});
  absl::StrAppendFormat(&t, "  %-34s %.3f .. %.3f m, bearing %.3f .. %.3f rad\n", "range, field of view (detections)",
                        c.min_range_m, c.max_range_m, c.fov_min_rad, c.fov_max_rad);
  std::string curve;
  for (const calibration::DetectionBin& b : c.detection_by_range) {
    absl::StrAppendFormat(&curve, " %.1f-%.1f m: %.2f [%.2f, %.2f] of %d;", b.range_min_m, b.range_max_m, b.probability,
                          b.lower, b.upper, b.predicted);
  }
  absl::StrAppendFormat(&t, "  %-34s%s\n", "detection probability by range", curve);
  absl::StrAppendFormat(&t, "  %-34s %d of %d paired (%d outliers left out), %d landmarks, redundancy %.0f\n", "fit",
                        c.detections_paired, c.detections, c.detections_outliers, c.landmarks, c.redundancy);
  absl::StrAppendFormat(&t, "  %-34s %d%s, %.1f s\n", "rounds", c.rounds,
                        c.converged ? " (converged)" : " (NOT CONVERGED)", r.wall_seconds);
  if (r.rms_position_m) {
    absl::StrAppendFormat(&t, "  %-34s %.3f m (start run %.3f m, %d landmarks)\n", "scan poses vs truth, RMS",
                          *r.rms_position_m, r.start_rms_position_m.value_or(NAN), r.start_landmarks);
  }
  return t;
}

}  // namespace subslam::pipeline
