#include "subslam/calibration/robot_calibration.h"

#include <utility>

#include "absl/strings/str_cat.h"
#include "subslam/calibration/internal/calibration_state.h"

namespace subslam::calibration {

absl::Status CalibrationOptions::Validate() const {
  const auto in_open_unit = [](double p) { return p > 0.0 && p < 1.0; };
  if (!in_open_unit(gate_probability) || !in_open_unit(outlier_probability)) {
    return absl::InvalidArgumentError("calibration: gate_probability and outlier_probability must be in (0, 1)");
  }
  if (max_rounds < 1 || max_solver_iterations < 1) {
    return absl::InvalidArgumentError("calibration: max_rounds and max_solver_iterations must be >= 1");
  }
  if (!(scale_prior_sigma >= 0.0)) return absl::InvalidArgumentError("calibration: scale_prior_sigma must be >= 0");
  if (!(relative_tolerance > 0.0) || !(detection_bin_m > 0.0)) {
    return absl::InvalidArgumentError("calibration: relative_tolerance and detection_bin_m must be > 0");
  }
  return absl::OkStatus();
}

namespace {

std::vector<Eigen::Vector3d> StartPoses(const io::Dataset& d, const CalibrationStart& start,
                                        const std::vector<int>& pose_of_scan, int num_poses) {
  std::vector<Eigen::Vector3d> poses(num_poses,
                                     Eigen::Vector3d(d.initial_pose.x, d.initial_pose.y, d.initial_pose.theta));
  for (size_t j = 0; j < pose_of_scan.size(); ++j) {
    if (pose_of_scan[j] > 0)
      poses[pose_of_scan[j]] = Eigen::Vector3d(start.scan_poses[j].x, start.scan_poses[j].y, start.scan_poses[j].theta);
  }
  return poses;
}

}  // namespace

absl::StatusOr<RobotCalibration> CalibrateRobot(const io::Dataset& dataset, const CalibrationStart& start,
                                                const CalibrationOptions& options) {
  if (absl::Status s = options.Validate(); !s.ok()) return s;
  if (dataset.scans.empty()) return absl::InvalidArgumentError("calibration: the data set has no scans");
  if (start.scan_poses.size() != dataset.scans.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("calibration: ", start.scan_poses.size(), " start poses for ", dataset.scans.size(), " scans"));
  }
  if (!start.scan_covariances.empty() && start.scan_covariances.size() != dataset.scans.size()) {
    return absl::InvalidArgumentError("calibration: one start covariance per scan, or none");
  }
  if (options.known_association && !dataset.sensor.has_truth_id) {
    return absl::InvalidArgumentError("calibration: known association needs the detections' true ids");
  }
  if (!options.known_association && start.landmarks.empty()) {
    return absl::InvalidArgumentError("calibration: unknown association needs a map to pair with");
  }
  internal::CalibrationState state(dataset, options);
  state.SetPoses(StartPoses(dataset, start, state.pose_of_scan(), state.num_poses()), start.scan_covariances);
  state.SetLandmarks(start.landmarks, start.landmark_covariances);
  return state.Run();
}

}  // namespace subslam::calibration
