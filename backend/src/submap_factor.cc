#include "subslam/backend/submap_factor.h"

#include "subslam/core/check.h"

namespace subslam::backend {

Eigen::VectorXd PredictSubmap(const Pose2& start, const Pose2& end, const std::vector<Eigen::Vector2d>& landmarks) {
  Eigen::VectorXd h(3 + 2 * landmarks.size());
  h.head<3>() = Between(start, end).vector();
  for (size_t i = 0; i < landmarks.size(); ++i) h.segment<2>(3 + 2 * i) = TransformTo(start, landmarks[i]);
  return h;
}

Eigen::VectorXd SubmapResidual(const LocalSubmap& submap, const Pose2& start, const Pose2& end,
                               const std::vector<Eigen::Vector2d>& landmarks) {
  SUBSLAM_CHECK(static_cast<int>(landmarks.size()) == submap.num_landmarks())
      << "factor has " << landmarks.size() << " landmarks, local map " << submap.num_landmarks();
  Eigen::VectorXd r = PredictSubmap(start, end, landmarks) - submap.mean;
  r[2] = WrapAngle(r[2]);
  return r;
}

SubmapFactorLinearization LinearizeSubmapFactor(const LocalSubmap& submap, const Pose2& start, const Pose2& end,
                                                const std::vector<Eigen::Vector2d>& landmarks) {
  const int n = static_cast<int>(landmarks.size());
  SUBSLAM_CHECK(n == submap.num_landmarks())
      << "factor has " << n << " landmarks, local map " << submap.num_landmarks();
  const int m = 3 + 2 * n;
  SubmapFactorLinearization out;
  out.residual.resize(m);
  out.J_start = Eigen::MatrixXd::Zero(m, 3);
  out.J_end = Eigen::MatrixXd::Zero(m, 3);
  out.J_landmarks = Eigen::MatrixXd::Zero(m, 2 * n);
  Eigen::Matrix3d J_s, J_e;
  const Pose2 relative = Between(start, end, &J_s, &J_e);
  out.residual.head<3>() = relative.vector() - submap.mean.head<3>();
  out.residual[2] = WrapAngle(out.residual[2]);
  out.J_start.topRows<3>() = J_s;
  out.J_end.topRows<3>() = J_e;
  for (int i = 0; i < n; ++i) {
    Matrix23d J_frame;
    Eigen::Matrix2d J_point;
    out.residual.segment<2>(3 + 2 * i) = TransformTo(start, landmarks[i], &J_frame, &J_point) - submap.landmark(i);
    out.J_start.block<2, 3>(3 + 2 * i, 0) = J_frame;
    out.J_landmarks.block<2, 2>(3 + 2 * i, 2 * i) = J_point;
  }
  return out;
}

}  // namespace subslam::backend
