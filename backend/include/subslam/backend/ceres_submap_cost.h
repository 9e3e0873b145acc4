// One local map as one Ceres residual block (../shared/design.md, "The submap factor"):
// residual W (h(X) ⊖ z) of size 3 + 2n with W = L⁻¹, Q = L Lᵀ the local map's covariance
// (so ‖residual‖² = rᵀ Q⁻¹ r), heading entry wrapped; parameter blocks: start anchor
// (x, y, θ), end anchor (x, y, θ), then each associated landmark (x, y). The Jacobian is
// analytic (LinearizeSubmapFactor), checked against numerical differentiation.
#ifndef SUBSLAM_BACKEND_CERES_SUBMAP_COST_H_
#define SUBSLAM_BACKEND_CERES_SUBMAP_COST_H_

#include <Eigen/Core>
#include <ceres/cost_function.h>

#include "subslam/graph/local_submap.h"

namespace subslam::backend {

class SubmapCostFunction final : public ceres::CostFunction {
 public:
  explicit SubmapCostFunction(const LocalSubmap& submap);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  LocalSubmap submap_;
  Eigen::MatrixXd L_;  // lower Cholesky factor of the covariance
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_CERES_SUBMAP_COST_H_
