// χ² quantiles and Mahalanobis gating.
//
// The quantiles come from Boost.Math's chi-squared distribution (a maintained
// implementation, not an approximation). A measurement with innovation ν and
// innovation covariance S passes the gate of probability p when
//   d² = νᵀ S⁻¹ ν ≤ χ²_dof(p).
// Pure functions, thread-safe.
#ifndef SUBSLAM_MODELS_GATING_H_
#define SUBSLAM_MODELS_GATING_H_

#include <Eigen/Core>
#include <optional>

namespace subslam::models {

// χ²_dof quantile: the value q with P(X ≤ q) = p for X ~ χ²(dof). 0 < p < 1, dof ≥ 1.
double ChiSquareQuantile(double p, double dof);

// P(X ≤ x) for X ~ χ²(dof).
double ChiSquareCdf(double x, double dof);

// d² = νᵀ S⁻¹ ν; std::nullopt when S is not positive definite.
std::optional<double> MahalanobisSquared(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& covariance);

// Two-dimensional specialisation, the hot path of data association.
std::optional<double> MahalanobisSquared2(const Eigen::Vector2d& innovation, const Eigen::Matrix2d& covariance);

}  // namespace subslam::models

#endif  // SUBSLAM_MODELS_GATING_H_
