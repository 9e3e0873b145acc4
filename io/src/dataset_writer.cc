#include "subslam/io/dataset_writer.h"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "subslam/io/run_output_writer.h"

namespace subslam::io {
namespace {

std::string G(double v) { return absl::StrFormat("%.17g", v); }

}  // namespace

absl::Status WriteDataset(const Dataset& d, const std::string& directory, const SimulationInfo* simulation) {
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec) return absl::InternalError(absl::StrCat(directory, ": cannot create: ", ec.message()));
  const std::filesystem::path dir(directory);
  const bool unicycle = d.motion.model == MotionModelType::kUnicycle;

  std::string controls = unicycle ? "# t v omega\n" : "# t v steer\n";
  for (const ControlRecord& c : d.controls) {
    absl::StrAppend(&controls, G(c.t), " ", G(c.u[0]), " ", G(c.u[1]), "\n");
  }
  if (auto s = WriteTextFile((dir / "controls.dat").string(), controls); !s.ok()) return s;

  const bool has_sig = d.sensor.has_signature, has_id = d.sensor.has_truth_id;
  std::string obs = absl::StrCat("# t range bearing", has_sig ? " signature" : "", has_id ? " truth_id" : "", "\n");
  for (const Scan& scan : d.scans) {
    for (const Detection& det : scan.detections) {
      absl::StrAppend(&obs, G(scan.t), " ", G(det.range_m), " ", G(det.bearing_rad));
      if (has_sig) absl::StrAppend(&obs, " ", G(det.signature));
      if (has_id) absl::StrAppend(&obs, " ", det.truth_id);
      obs += "\n";
    }
  }
  if (auto s = WriteTextFile((dir / "observations.dat").string(), obs); !s.ok()) return s;

  nlohmann::json truth = nlohmann::json::object();
  truth["gps_file"] = nullptr;
  truth["poses_file"] = nullptr;
  truth["landmarks_file"] = nullptr;
  if (!d.truth_poses.empty()) {
    std::string text = "# t x y theta\n";
    for (const TimedPose& p : d.truth_poses) {
      absl::StrAppend(&text, G(p.t), " ", G(p.pose.x), " ", G(p.pose.y), " ", G(p.pose.theta), "\n");
    }
    if (auto s = WriteTextFile((dir / "truth_poses.dat").string(), text); !s.ok()) return s;
    truth["poses_file"] = "truth_poses.dat";
  }
  if (!d.truth_landmarks.empty()) {
    std::string text = "# id x y\n";
    for (const TruthLandmark& l : d.truth_landmarks) {
      absl::StrAppend(&text, l.id, " ", G(l.p.x()), " ", G(l.p.y()), "\n");
    }
    if (auto s = WriteTextFile((dir / "truth_landmarks.dat").string(), text); !s.ok()) return s;
    truth["landmarks_file"] = "truth_landmarks.dat";
  }
  if (!d.gps.empty()) {
    std::string text = "# t x y\n";
    for (const TimedPoint& p : d.gps) {
      absl::StrAppend(&text, G(p.t), " ", G(p.p.x()), " ", G(p.p.y()), "\n");
    }
    if (auto s = WriteTextFile((dir / "gps.dat").string(), text); !s.ok()) return s;
    truth["gps_file"] = "gps.dat";
  }

  nlohmann::json motion;
  motion["model"] = ToString(d.motion.model);
  motion["controls_file"] = "controls.dat";
  motion["sigma_v"] = d.motion.noise.sigma_u0;
  if (d.motion.noise.scale_u0 > 0) motion["sigma_v_scale"] = d.motion.noise.scale_u0;
  if (d.motion.control_scale != Eigen::Vector2d::Ones()) {
    motion["control_scale"] = {d.motion.control_scale[0], d.motion.control_scale[1]};
  }
  if (d.motion.control_offset != Eigen::Vector2d::Zero()) {
    motion["control_offset"] = {d.motion.control_offset[0], d.motion.control_offset[1]};
  }
  const std::string ch1 = unicycle ? "sigma_omega" : "sigma_steer";
  motion[ch1] = d.motion.noise.sigma_u1;
  if (d.motion.noise.scale_u1 > 0) motion[ch1 + "_scale"] = d.motion.noise.scale_u1;
  if (!unicycle) {
    motion["wheelbase"] = d.motion.geometry.wheelbase_m;
    motion["encoder_offset"] = d.motion.geometry.encoder_offset_m;
    motion["sensor_offset"] = {d.motion.geometry.sensor_forward_m, d.motion.geometry.sensor_left_m};
  }
  const models::RangeBearingConfig& rb = d.sensor.range_bearing;
  nlohmann::json sensor;
  sensor["type"] = "range_bearing";
  sensor["observations_file"] = "observations.dat";
  sensor["bearing_offset"] = 0.0;
  sensor["signature_column"] = has_sig ? nlohmann::json(4) : nlohmann::json(nullptr);
  sensor["truth_id_column"] = has_id ? nlohmann::json(has_sig ? 5 : 4) : nlohmann::json(nullptr);
  sensor["sigma_range"] = rb.sigma_range_m;
  sensor["sigma_bearing"] = rb.sigma_bearing_rad;
  sensor["min_range"] = rb.min_range_m;
  sensor["max_range"] = rb.max_range_m;
  sensor["fov"] = {rb.fov_min_rad, rb.fov_max_rad};

  nlohmann::json manifest;
  manifest["format"] = "subslam-dataset/1";
  manifest["name"] = d.name;
  manifest["initial_pose"] = {d.initial_pose.x, d.initial_pose.y, d.initial_pose.theta};
  manifest["motion"] = motion;
  manifest["sensor"] = sensor;
  manifest["ground_truth"] = truth;
  if (simulation != nullptr) {
    manifest["simulation"] = {{"scenario", simulation->scenario},
                              {"seed", simulation->seed},
                              {"detection_probability", simulation->detection_probability},
                              {"false_alarm_probability", simulation->false_alarm_probability}};
  }
  return WriteTextFile((dir / "dataset.json").string(), manifest.dump(2) + "\n");
}

}  // namespace subslam::io
