// One local map as one Ceres residual block (docs/conventions.md, "The submap factor"):
// residual W (h(X) ⊖ z) of size 3 + 2n with W = L⁻¹, Q = L Lᵀ the local map's covariance
// (so ‖residual‖² = rᵀ Q⁻¹ r), heading entry wrapped; parameter blocks: start anchor
// (x, y, θ), end anchor (x, y, θ), then each distinct associated landmark (x, y).
// `block_of_feature[i]` is the landmark block of feature i (two features of one local map
// associated with the same landmark share a block — Ceres forbids a block twice in one
// residual — and their Jacobian columns add). The Jacobian is analytic
// (LinearizeSubmapFactor), checked against numerical differentiation.
#ifndef SUBSLAM_BACKEND_CERES_SUBMAP_COST_H_
#define SUBSLAM_BACKEND_CERES_SUBMAP_COST_H_

#include <ceres/cost_function.h>

#include <Eigen/Core>
#include <vector>

#include "subslam/core/local_submap.h"

namespace subslam::backend {

class SubmapCostFunction final : public ceres::CostFunction {
 public:
  // Without block_of_feature: feature i is block i.
  explicit SubmapCostFunction(const LocalSubmap& submap, std::vector<int> block_of_feature = {});

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  LocalSubmap submap_;
  std::vector<int> block_of_feature_;
  int num_landmark_blocks_ = 0;
  Eigen::MatrixXd L_;  // lower Cholesky factor of the covariance
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_CERES_SUBMAP_COST_H_
