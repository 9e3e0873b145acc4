#include "subslam/eval/nees.h"

#include <Eigen/Eigenvalues>

#include "subslam/core/check.h"
#include "subslam/models/gating.h"

namespace subslam::eval {

std::optional<double> PoseNees(const Pose2& truth, const Pose2& estimate, const Eigen::Matrix3d& covariance) {
  // A rank-deficient covariance (e.g. the first steps after a zero initial
  // covariance, when only the control noise's two directions have grown) makes the
  // NEES meaningless: such steps are reported as not evaluable.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(covariance, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d lambda = eig.eigenvalues();
  if (!(lambda[0] > kMinRelativeEigenvalue * lambda[2])) return std::nullopt;
  const Eigen::Vector3d e = PoseDifference(truth, estimate);
  return models::MahalanobisSquared(e, covariance);
}

std::optional<double> PointNees(const Eigen::Vector2d& truth, const Eigen::Vector2d& estimate,
                                const Eigen::Matrix2d& covariance) {
  return models::MahalanobisSquared2(truth - estimate, covariance);
}

NeesBounds AverageNeesBounds(int dof, int num_runs, double confidence) {
  SUBSLAM_CHECK(dof > 0 && num_runs > 0 && confidence > 0.0 && confidence < 1.0);
  const double total_dof = static_cast<double>(dof) * num_runs;
  const double tail = (1.0 - confidence) / 2.0;
  return {models::ChiSquareQuantile(tail, total_dof) / num_runs,
          models::ChiSquareQuantile(1.0 - tail, total_dof) / num_runs};
}

double ConsistencyIndex(double nees, int dof, double confidence) {
  return nees / models::ChiSquareQuantile(confidence, dof);
}

}  // namespace subslam::eval
