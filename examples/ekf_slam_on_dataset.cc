// EKF-SLAM on a data set: read a data-set directory (docs/formats.md), run single-map
// EKF-SLAM with unknown data association over its steps, and print the final pose, the
// map and — when the data set has ground truth — the errors against it.
//
//   ekf_slam_on_dataset DATASET_DIR
#include <cmath>
#include <cstdio>
#include <string>

#include "subslam/eval/trajectory_errors.h"
#include "subslam/frontend/ekf_slam.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/io/steps.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DATASET_DIR\n", argv[0]);
    return 2;
  }
  absl::StatusOr<subslam::io::Dataset> dataset = subslam::io::ReadDataset(argv[1]);
  if (!dataset.ok()) {  // the message names the file, line and field
    std::fprintf(stderr, "%s\n", std::string(dataset.status().message()).c_str());
    return 1;
  }
  subslam::frontend::EkfSlamOptions options;  // nearest-neighbour association, χ² gates
  subslam::frontend::EkfSlam ekf(dataset->motion.MakeModel(), dataset->sensor.range_bearing, dataset->initial_pose,
                                 options);
  subslam::Trajectory trajectory;
  for (const subslam::io::Step& step : subslam::io::BuildSteps(*dataset)) {
    ekf.Predict(step.control, step.dt);  // the control held over dt [s]
    if (step.scan_index >= 0) {
      if (absl::Status updated = ekf.Update(dataset->scans[step.scan_index]); !updated.ok()) {
        std::fprintf(stderr, "%s\n", std::string(updated.message()).c_str());  // a malformed scan
        return 1;
      }
    }
    trajectory.push_back({step.t, ekf.pose(), ekf.pose_covariance()});
  }
  const subslam::Pose2 pose = ekf.pose();  // world frame: x, y [m], θ [rad]
  const Eigen::Matrix3d covariance = ekf.pose_covariance();
  std::printf("final pose (%.3f m, %.3f m, %.4f rad), position sd %.3f m, %zu landmarks\n", pose.x, pose.y, pose.theta,
              std::sqrt(covariance(0, 0) + covariance(1, 1)), ekf.Map().size());
  if (!dataset->truth_poses.empty()) {
    const subslam::eval::TrajectoryErrors e = subslam::eval::ComputeTrajectoryErrors(trajectory, dataset->truth_poses);
    std::printf("against ground truth: RMS position %.3f m, mean pose NEES %.2f\n", e.rms_position_m, e.mean_nees);
  }
  return ekf.Map().empty() ? 1 : 0;
}
