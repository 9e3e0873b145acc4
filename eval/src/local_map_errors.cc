#include "subslam/eval/local_map_errors.h"

#include <Eigen/Cholesky>
#include <limits>
#include <map>

#include "subslam/eval/nees.h"
#include "subslam/eval/trajectory_errors.h"
#include "subslam/models/gating.h"

namespace subslam::eval {

std::optional<LocalMapNees> EvaluateLocalMap(const LocalSubmap& s, const std::vector<io::TimedPose>& truth_poses,
                                             const std::vector<io::TruthLandmark>& truth_landmarks) {
  if (truth_poses.empty() || s.t_start < truth_poses.front().t - 1e-9 || s.t_end > truth_poses.back().t + 1e-9) {
    return std::nullopt;
  }
  std::map<int, Eigen::Vector2d> truth;
  for (const io::TruthLandmark& l : truth_landmarks) truth[l.id] = l.p;
  const Pose2 start = InterpolatePose(truth_poses, s.t_start);
  const Pose2 end = InterpolatePose(truth_poses, s.t_end);

  LocalMapNees r;
  r.id = s.id;
  std::vector<int> index = {0, 1, 2};
  std::vector<double> error;
  const Pose2 true_end = Between(start, end);
  const Eigen::Vector3d pose_error(s.mean[0] - true_end.x, s.mean[1] - true_end.y,
                                   WrapAngle(s.mean[2] - true_end.theta));
  error = {pose_error[0], pose_error[1], pose_error[2]};
  for (int i = 0; i < s.num_landmarks(); ++i) {
    const std::optional<int>& id = s.landmarks[i].truth_id;
    if (!id.has_value()) {
      ++r.unlabelled;
      continue;
    }
    if (*id < 0) {
      ++r.false_alarms;
      continue;
    }
    auto it = truth.find(*id);
    if (it == truth.end()) {
      ++r.unlabelled;
      continue;
    }
    const Eigen::Vector2d e = s.landmark(i) - TransformTo(start, it->second);
    const std::optional<double> marginal =
        PointNees(TransformTo(start, it->second), s.landmark(i), s.landmark_covariance(i));
    r.landmark_nees.push_back(marginal.value_or(std::numeric_limits<double>::infinity()));
    index.push_back(3 + 2 * i);
    index.push_back(4 + 2 * i);
    error.push_back(e[0]);
    error.push_back(e[1]);
    ++r.landmarks_evaluated;
  }
  const Eigen::Map<const Eigen::VectorXd> e(error.data(), static_cast<Eigen::Index>(error.size()));
  const Eigen::MatrixXd P = s.covariance(index, index);
  Eigen::LLT<Eigen::MatrixXd> llt(P);
  if (llt.info() != Eigen::Success) return std::nullopt;
  r.nees = e.dot(llt.solve(e));
  const Eigen::Matrix3d P_pose = s.covariance.topLeftCorner<3, 3>();
  r.pose_nees = pose_error.dot(P_pose.llt().solve(pose_error));
  r.dof = static_cast<int>(error.size());
  r.lower = models::ChiSquareQuantile(0.025, r.dof);
  r.upper = models::ChiSquareQuantile(0.975, r.dof);
  return r;
}

}  // namespace subslam::eval
