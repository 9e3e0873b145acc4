#include "subslam/backend/ceres_submap_cost.h"

#include <Eigen/Cholesky>

#include "subslam/backend/submap_factor.h"
#include "subslam/graph/internal/check.h"

namespace subslam::backend {

SubmapCostFunction::SubmapCostFunction(const LocalSubmap& submap) : submap_(submap) {
  const Eigen::LLT<Eigen::MatrixXd> llt(submap.covariance);
  SUBSLAM_CHECK(llt.info() == Eigen::Success) << "local map covariance not positive definite";
  L_ = llt.matrixL();
  const int n = submap.num_landmarks();
  set_num_residuals(3 + 2 * n);
  mutable_parameter_block_sizes()->push_back(3);
  mutable_parameter_block_sizes()->push_back(3);
  for (int i = 0; i < n; ++i) mutable_parameter_block_sizes()->push_back(2);
}

bool SubmapCostFunction::Evaluate(double const* const* parameters, double* residuals,
                                  double** jacobians) const {
  const int n = submap_.num_landmarks();
  const int m = 3 + 2 * n;
  const Pose2 start(parameters[0][0], parameters[0][1], parameters[0][2]);
  const Pose2 end(parameters[1][0], parameters[1][1], parameters[1][2]);
  std::vector<Eigen::Vector2d> landmarks(n);
  for (int i = 0; i < n; ++i) landmarks[i] = Eigen::Vector2d(parameters[2 + i][0], parameters[2 + i][1]);
  const SubmapFactorLinearization lin = LinearizeSubmapFactor(submap_, start, end, landmarks);
  const auto whiten = [this](Eigen::MatrixXd A) {
    L_.triangularView<Eigen::Lower>().solveInPlace(A);
    return A;
  };
  Eigen::Map<Eigen::VectorXd>(residuals, m) = whiten(lin.residual);
  if (jacobians == nullptr) return true;
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  if (jacobians[0] != nullptr) Eigen::Map<RowMajor>(jacobians[0], m, 3) = whiten(lin.J_start);
  if (jacobians[1] != nullptr) Eigen::Map<RowMajor>(jacobians[1], m, 3) = whiten(lin.J_end);
  bool any_landmark = false;
  for (int i = 0; i < n; ++i) any_landmark = any_landmark || jacobians[2 + i] != nullptr;
  if (any_landmark) {
    const Eigen::MatrixXd W = whiten(lin.J_landmarks);
    for (int i = 0; i < n; ++i) {
      if (jacobians[2 + i] != nullptr) Eigen::Map<RowMajor>(jacobians[2 + i], m, 2) = W.middleCols<2>(2 * i);
    }
  }
  return true;
}

}  // namespace subslam::backend
