// In-memory data set: what a `dataset.json` directory (docs/formats.md, "Data-set
// directory") holds once read and checked, and what the simulators produce.
//
// Times are seconds (any origin), angles radians, lengths metres. Controls hold until
// the next control record. Detections are grouped into scans by time; their bearings
// are already in the vehicle (sensor) frame — the manifest's bearing_offset has been
// applied. Ground truth is optional and is used for evaluation only.
#ifndef SUBSLAM_IO_DATASET_H_
#define SUBSLAM_IO_DATASET_H_

#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "subslam/core/pose2.h"
#include "subslam/models/ackermann_model.h"
#include "subslam/models/motion_model.h"
#include "subslam/models/range_bearing_model.h"
#include "subslam/models/scan.h"

namespace subslam::io {

enum class MotionModelType { kUnicycle, kAckermann };
const char* ToString(MotionModelType type);
absl::StatusOr<MotionModelType> MotionModelTypeFromString(const std::string& name);

struct MotionConfig {
  MotionModelType model = MotionModelType::kUnicycle;
  models::AckermannGeometry geometry;  // used by kAckermann only
  // Channel 0 is the speed; channel 1 is ω (unicycle) or the steering angle (ackermann).
  models::ControlNoise noise;
  // The odometry's systematic error, as calibrated (`subslam calibrate`): a reported
  // control u stands for the control Corrected(u) = control_scale ⊙ u + control_offset,
  // which every estimator is given (io::BuildSteps applies it; the noise M(u) is taken at
  // the corrected control). Dataset::controls keep the values as recorded. Defaults: none.
  Eigen::Vector2d control_scale = Eigen::Vector2d::Ones();
  Eigen::Vector2d control_offset = Eigen::Vector2d::Zero();
  Eigen::Vector2d Corrected(const Eigen::Vector2d& u) const { return control_scale.cwiseProduct(u) + control_offset; }

  // Builds the motion model this configuration describes.
  std::unique_ptr<models::MotionModel> MakeModel() const;
};

struct SensorConfig {
  models::RangeBearingConfig range_bearing;
  bool has_signature = false;  // whether detections carry a signature
  bool has_truth_id = false;   // whether detections carry the true landmark id
};

// Control held from time t until the next record: (v [m/s], ω [rad/s] or steer [rad]).
struct ControlRecord {
  double t = 0.0;
  Eigen::Vector2d u = Eigen::Vector2d::Zero();
};

struct TimedPose {
  double t = 0.0;
  Pose2 pose;
};

struct TimedPoint {
  double t = 0.0;
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
};

struct TruthLandmark {
  int id = 0;
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
};

struct Dataset {
  std::string name;
  std::string directory;  // where it was read from; empty when simulated
  Pose2 initial_pose;
  MotionConfig motion;
  SensorConfig sensor;
  std::vector<ControlRecord> controls;  // sorted by t
  std::vector<Scan> scans;              // sorted by t, one per distinct time
  // Optional ground truth (empty when absent).
  std::vector<TimedPose> truth_poses;  // in the frame of initial_pose's parent
  std::vector<TruthLandmark> truth_landmarks;
  std::vector<TimedPoint> gps;  // own frame: align before comparing
  // Control lines that repeated the previous line's time, read as one record (the later
  // line wins; io/dataset_reader.h). Counted in the run's report.
  int duplicate_control_times = 0;

  size_t NumDetections() const;
};

}  // namespace subslam::io

#endif  // SUBSLAM_IO_DATASET_H_
