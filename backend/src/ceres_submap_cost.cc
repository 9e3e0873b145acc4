#include "subslam/backend/ceres_submap_cost.h"

#include <Eigen/Cholesky>
#include <algorithm>

#include "subslam/backend/submap_factor.h"
#include "subslam/core/check.h"

namespace subslam::backend {

SubmapCostFunction::SubmapCostFunction(const LocalSubmap& submap, std::vector<int> block_of_feature)
    : submap_(submap), block_of_feature_(std::move(block_of_feature)) {
  const Eigen::LLT<Eigen::MatrixXd> llt(submap.covariance);
  SUBSLAM_CHECK(llt.info() == Eigen::Success) << "local map covariance not positive definite";
  L_ = llt.matrixL();
  const int n = submap.num_landmarks();
  if (block_of_feature_.empty()) {
    for (int i = 0; i < n; ++i) block_of_feature_.push_back(i);
  }
  SUBSLAM_CHECK(static_cast<int>(block_of_feature_.size()) == n) << "one block per feature";
  for (int b : block_of_feature_) num_landmark_blocks_ = std::max(num_landmark_blocks_, b + 1);
  set_num_residuals(3 + 2 * n);
  mutable_parameter_block_sizes()->push_back(3);
  mutable_parameter_block_sizes()->push_back(3);
  for (int b = 0; b < num_landmark_blocks_; ++b) mutable_parameter_block_sizes()->push_back(2);
}

bool SubmapCostFunction::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const int n = submap_.num_landmarks();
  const int m = 3 + 2 * n;
  const Pose2 start(parameters[0][0], parameters[0][1], parameters[0][2]);
  const Pose2 end(parameters[1][0], parameters[1][1], parameters[1][2]);
  std::vector<Eigen::Vector2d> landmarks(n);
  for (int i = 0; i < n; ++i) {
    const double* p = parameters[2 + block_of_feature_[i]];
    landmarks[i] = Eigen::Vector2d(p[0], p[1]);
  }
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
  for (int b = 0; b < num_landmark_blocks_; ++b) any_landmark = any_landmark || jacobians[2 + b] != nullptr;
  if (any_landmark) {
    const Eigen::MatrixXd W = whiten(lin.J_landmarks);
    for (int b = 0; b < num_landmark_blocks_; ++b) {
      if (jacobians[2 + b] != nullptr) Eigen::Map<RowMajor>(jacobians[2 + b], m, 2).setZero();
    }
    for (int i = 0; i < n; ++i) {
      double* J = jacobians[2 + block_of_feature_[i]];
      if (J != nullptr) Eigen::Map<RowMajor>(J, m, 2) += W.middleCols<2>(2 * i);
    }
  }
  return true;
}

}  // namespace subslam::backend
