// A navigation stack's loop: controls and scans go to RBPF local maps (FastSLAM 2.0) joined
// by the sparse EIF, and after every step the stack reads the online pose and its
// covariance — the estimate it would steer by. The data comes from a data-set directory
// here; a robot would fill subslam::Scan (range [m], bearing [rad] in the vehicle frame)
// from its sensor and call Predict / Update the same way.
//
//   navigation_loop DATASET_DIR
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "subslam/frontend/local_mapper.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/io/steps.h"
#include "subslam/pipeline/submap_slam.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DATASET_DIR\n", argv[0]);
    return 2;
  }
  absl::StatusOr<subslam::io::Dataset> dataset = subslam::io::ReadDataset(argv[1]);
  if (!dataset.ok()) {
    std::fprintf(stderr, "%s\n", std::string(dataset.status().message()).c_str());
    return 1;
  }
  const std::vector<subslam::io::Step> steps = subslam::io::BuildSteps(*dataset);
  if (steps.empty()) return 1;

  // Local maps: 100 particles; a map closes when its particles' lineage collapses or after
  // 10 s (SubmapPolicyOptions). Back-end: the EIF (the default), joining each closed map
  // inside the Update() that closed it; `backend.background = true` joins on a thread of its
  // own instead, the online pose then one join behind.
  auto mapper = std::make_unique<subslam::frontend::RbpfLocalMapper>(
      dataset->motion.MakeModel(), dataset->sensor.range_bearing, subslam::frontend::FastSlamOptions{},
      subslam::frontend::SubmapPolicyOptions{}, /*t_start=*/steps.front().t);
  subslam::pipeline::BackendOptions backend;
  subslam::pipeline::SubmapSlam slam(std::move(mapper), dataset->initial_pose, backend);

  double next_print = steps.front().t;
  for (const subslam::io::Step& step : steps) {
    slam.Predict(step.control, step.dt);
    if (step.scan_index >= 0) {
      if (absl::Status updated = slam.Update(dataset->scans[step.scan_index]); !updated.ok()) {
        std::fprintf(stderr, "%s\n", std::string(updated.message()).c_str());  // a malformed scan, a failed join
        return 1;
      }
    }
    slam.RecordStep(step.t);                                    // kept for the final, smoothed trajectory
    const subslam::Pose2 pose = slam.pose();                    // world frame, (x, y, θ)
    const Eigen::Matrix3d covariance = slam.pose_covariance();  // of (x, y, θ)
    if (step.t >= next_print) {
      std::printf("t %6.1f s  pose (%7.2f, %7.2f, %6.3f)  position sd %.2f m\n", step.t, pose.x, pose.y, pose.theta,
                  std::sqrt(covariance(0, 0) + covariance(1, 1)));
      next_print += 10.0;
    }
  }
  if (absl::Status finished = slam.Finish(); !finished.ok()) {
    std::fprintf(stderr, "%s\n", std::string(finished.message()).c_str());
    return 1;
  }
  const subslam::Trajectory final_trajectory = slam.FinalTrajectory();
  std::printf("%zu local maps joined into %zu landmarks; final pose (%.2f, %.2f, %.3f)\n", slam.local_maps().size(),
              slam.Map().size(), final_trajectory.back().pose.x, final_trajectory.back().pose.y,
              final_trajectory.back().pose.theta);
  return slam.local_maps().empty() ? 1 : 0;
}
