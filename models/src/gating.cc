#include "subslam/models/gating.h"

#include <Eigen/Cholesky>
#include <boost/math/distributions/chi_squared.hpp>

#include "subslam/core/check.h"

namespace subslam::models {

double ChiSquareQuantile(double p, double dof) {
  SUBSLAM_CHECK(p > 0.0 && p < 1.0) << "probability must be in (0, 1), got " << p;
  SUBSLAM_CHECK(dof > 0.0);
  return boost::math::quantile(boost::math::chi_squared_distribution<double>(dof), p);
}

double ChiSquareCdf(double x, double dof) {
  SUBSLAM_CHECK(dof > 0.0);
  if (x <= 0.0) return 0.0;
  return boost::math::cdf(boost::math::chi_squared_distribution<double>(dof), x);
}

std::optional<double> MahalanobisSquared(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& covariance) {
  Eigen::LLT<Eigen::MatrixXd> llt(covariance);
  if (llt.info() != Eigen::Success) return std::nullopt;
  return innovation.dot(llt.solve(innovation));
}

std::optional<double> MahalanobisSquared2(const Eigen::Vector2d& v, const Eigen::Matrix2d& s) {
  const double det = s(0, 0) * s(1, 1) - s(0, 1) * s(1, 0);
  if (!(s(0, 0) > 0.0 && det > 0.0)) return std::nullopt;
  // νᵀ S⁻¹ ν with the 2×2 adjugate; S is symmetric.
  return (s(1, 1) * v[0] * v[0] - 2.0 * s(0, 1) * v[0] * v[1] + s(0, 0) * v[1] * v[1]) / det;
}

}  // namespace subslam::models
