// Runs the README's snippets as another project would: reads a data set, runs EKF-SLAM
// over it, builds RBPF local maps and joins them with the EIF. Exits 0 when both ran and
// every local map joined.
#include <subslam/backend/eif_joiner.h>
#include <subslam/frontend/ekf_slam.h>
#include <subslam/frontend/local_mapper.h>
#include <subslam/io/dataset_reader.h>
#include <subslam/io/steps.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: consumer DATASET_DIR\n");
    return 2;
  }
  auto dataset = subslam::io::ReadDataset(argv[1]);
  if (!dataset.ok()) {
    std::fprintf(stderr, "%s\n", std::string(dataset.status().message()).c_str());
    return 1;
  }
  // The single-map baseline.
  subslam::frontend::EkfSlam ekf(dataset->motion.MakeModel(), dataset->sensor.range_bearing, dataset->initial_pose,
                                 subslam::frontend::EkfSlamOptions{});
  for (const subslam::io::Step& step : subslam::io::BuildSteps(*dataset)) {
    ekf.Predict(step.control, step.dt);
    if (step.scan_index >= 0 && !ekf.Update(dataset->scans[step.scan_index]).ok()) return 1;
  }
  const std::vector<subslam::LandmarkEstimate> ekf_map = ekf.Map();
  const Eigen::Matrix3d ekf_covariance = ekf.pose_covariance();
  std::printf("EKF-SLAM: %zu landmarks, final position sd %.2f m\n", ekf_map.size(),
              std::sqrt(ekf_covariance(0, 0) + ekf_covariance(1, 1)));
  if (ekf_map.empty()) return 1;

  // Local maps joined by the EIF; the first map opens at the data set's first time.
  const double t_start = dataset->controls.empty() ? 0.0 : dataset->controls.front().t;
  subslam::frontend::RbpfLocalMapper mapper(dataset->motion.MakeModel(), dataset->sensor.range_bearing,
                                            subslam::frontend::FastSlamOptions{},
                                            subslam::frontend::SubmapPolicyOptions{}, t_start);
  subslam::backend::EifJoiner joiner(dataset->initial_pose, subslam::backend::EifJoinerOptions{});
  int joined = 0;
  const auto join_closed = [&]() {
    for (subslam::frontend::ClosedLocalMap& closed : mapper.TakeClosed()) {
      if (absl::Status st = joiner.Join(closed.submap); !st.ok()) {
        std::fprintf(stderr, "join: %s\n", std::string(st.message()).c_str());
        return false;
      }
      ++joined;
      // Grow a vector the library allocated, here (Eigen's realloc on its block).
      Eigen::VectorXd& mean = closed.submap.mean;
      const Eigen::VectorXd before = mean;
      mean.conservativeResize(mean.size() + 7);
      if (mean.head(before.size()) != before) {
        std::fprintf(stderr, "a resized local-map mean lost its values\n");
        return false;
      }
    }
    return true;
  };
  for (const subslam::io::Step& step : subslam::io::BuildSteps(*dataset)) {
    mapper.Predict(step.control, step.dt);
    if (step.scan_index >= 0 && !mapper.Update(dataset->scans[step.scan_index]).ok()) return 1;
    if (!join_closed()) return 1;
  }
  mapper.Finish();
  if (!join_closed()) return 1;
  if (absl::Status st = joiner.Finish(); !st.ok()) {
    std::fprintf(stderr, "finish: %s\n", std::string(st.message()).c_str());
    return 1;
  }
  const subslam::Pose2 anchor = joiner.LastAnchor();
  const Eigen::Matrix3d covariance = joiner.LastAnchorCovariance();
  std::printf("joined %d local maps; last anchor (%.2f, %.2f, %.3f), position sd %.2f m\n", joined, anchor.x, anchor.y,
              anchor.theta, std::sqrt(covariance(0, 0) + covariance(1, 1)));
  return joined > 0 ? 0 : 1;
}
