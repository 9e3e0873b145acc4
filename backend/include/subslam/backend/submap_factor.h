// The submap factor of docs/conventions.md: local map k, started at anchor P_s and ended
// at anchor P_e, observed global landmarks L_1 … L_n. Its prediction is
//   h(X) = [ P_s⁻¹ ∘ P_e , P_s⁻¹ · L_1 , … , P_s⁻¹ · L_n ]   (3 + 2n, start frame)
// and its residual r = h(X) ⊖ z (z the local map's mean; heading entry wrapped), with
// covariance Q, the local map's covariance. Jacobians are analytic (Between and
// TransformTo), checked against numerical differentiation in the tests.
#ifndef SUBSLAM_BACKEND_SUBMAP_FACTOR_H_
#define SUBSLAM_BACKEND_SUBMAP_FACTOR_H_

#include <Eigen/Core>
#include <vector>

#include "subslam/core/local_submap.h"
#include "subslam/core/pose2.h"

namespace subslam::backend {

struct SubmapFactorLinearization {
  Eigen::VectorXd residual;     // h(X) ⊖ z, 3 + 2n
  Eigen::MatrixXd J_start;      // (3 + 2n) × 3
  Eigen::MatrixXd J_end;        // (3 + 2n) × 3
  Eigen::MatrixXd J_landmarks;  // (3 + 2n) × 2n; column block i is ∂r/∂L_i (nonzero in row block i only)
};

// h(X) alone.
Eigen::VectorXd PredictSubmap(const Pose2& start, const Pose2& end, const std::vector<Eigen::Vector2d>& landmarks);

// r(X) alone (no Jacobians): what a cost evaluation needs.
Eigen::VectorXd SubmapResidual(const LocalSubmap& submap, const Pose2& start, const Pose2& end,
                               const std::vector<Eigen::Vector2d>& landmarks);

SubmapFactorLinearization LinearizeSubmapFactor(const LocalSubmap& submap, const Pose2& start, const Pose2& end,
                                                const std::vector<Eigen::Vector2d>& landmarks);

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_SUBMAP_FACTOR_H_
