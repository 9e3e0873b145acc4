// The calibrate job (`subslam calibrate`): a robot's odometry and sensor estimated from its
// own data set (calibration/robot_calibration.h), starting from a SLAM run over it, and
// written as a manifest fragment with its uncertainty (`calibration.json`, read back by
// `subslam run --calibration`; io/calibration_fragment.h).
#ifndef SUBSLAM_PIPELINE_CALIBRATE_PIPELINE_H_
#define SUBSLAM_PIPELINE_CALIBRATE_PIPELINE_H_

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "absl/status/statusor.h"
#include "subslam/calibration/robot_calibration.h"
#include "subslam/io/dataset.h"
#include "subslam/pipeline/run_pipeline.h"

namespace subslam::pipeline {

struct CalibrateOptions {
  // The run the fit starts from (its final trajectory and, with unknown association, its
  // map). Default: the flagship, RBPF local maps joined by the EIF, with the data set's own
  // noise; known association follows `calibration.known_association`.
  RunOptions start;
  calibration::CalibrationOptions calibration;
  std::string out_dir;        // empty: write nothing
  std::string source;         // what was calibrated, for calibration.json
  nlohmann::json invocation;  // the tool's command line and flags

  CalibrateOptions();
  absl::Status Validate() const;
};

struct CalibrateResult {
  std::string source;
  io::MotionConfig motion_before;  // the data set's values the fit started from
  models::RangeBearingConfig sensor_before;
  calibration::RobotCalibration calibration;
  int start_landmarks = 0;                     // in the start run's map
  std::optional<double> start_rms_position_m;  // the start run vs the ground truth
  std::optional<double> rms_position_m;        // the fitted scan poses vs the ground truth
  double wall_seconds = 0.0;
};

absl::StatusOr<CalibrateResult> RunCalibration(io::Dataset dataset, const CalibrateOptions& options);

// calibration.json: "manifest_fragment" (the motion and sensor keys of dataset.json),
// "standard_errors" (the same keys), "before" (the data set's values),
// "detection_probability_by_range", "fit" and "build"/"invocation".
nlohmann::json CalibrationJson(const CalibrateResult& result, const nlohmann::json& invocation);

// The summary the tool prints: each value before and after, with its standard error.
std::string CalibrationTable(const CalibrateResult& result);

}  // namespace subslam::pipeline

#endif  // SUBSLAM_PIPELINE_CALIBRATE_PIPELINE_H_
