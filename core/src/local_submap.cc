#include "subslam/core/local_submap.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <set>

#include "absl/strings/str_cat.h"

namespace subslam {

absl::Status LocalSubmap::Validate() const {
  const auto error = [this](auto&&... parts) {
    return absl::InvalidArgumentError(absl::StrCat("local map ", id, ": ", parts...));
  };
  const Eigen::Index n = 3 + 2 * static_cast<Eigen::Index>(landmarks.size());
  if (mean.size() != n) return error("state has ", mean.size(), " entries, expected ", n);
  if (covariance.rows() != n || covariance.cols() != n) {
    return error("covariance is ", covariance.rows(), "x", covariance.cols(), ", expected ", n, "x", n);
  }
  if (!std::isfinite(t_start) || !std::isfinite(t_end) || t_end < t_start) {
    return error("time span [", t_start, ", ", t_end, "] is not a finite interval");
  }
  if (!mean.allFinite()) return error("state has a non-finite entry");
  if (!covariance.allFinite()) return error("covariance has a non-finite entry");
  if (std::abs(WrapAngle(mean[2]) - mean[2]) > 1e-12) return error("heading is not wrapped");
  std::set<int> ids;
  for (const LocalSubmapLandmark& l : landmarks) {
    if (!ids.insert(l.local_id).second) return error("local id ", l.local_id, " repeats");
    if (!(l.existence >= 0.0 && l.existence <= 1.0)) {
      return error("landmark ", l.local_id, ": existence ", l.existence, " outside [0, 1]");
    }
  }
  const double scale = std::max(1.0, covariance.cwiseAbs().maxCoeff());
  if ((covariance - covariance.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    return error("covariance is not symmetric");
  }
  const Eigen::LLT<Eigen::MatrixXd> llt(covariance);
  if (llt.info() != Eigen::Success) return error("covariance is not positive definite");
  // Joiners whiten by the covariance's Cholesky factor: past this condition number the
  // information it carries is rounding error (and CHOLMOD fails on the sum). The factor's
  // reciprocal condition estimate settles the usual case (1/κ₁ ≤ λ_min/λ_max, and
  // λ_min ≥ 1/‖C⁻¹‖₁ ≈ rcond·‖C‖₁; the factor 10³ leaves room for the estimate's error).
  const double norm1 = covariance.cwiseAbs().colwise().sum().maxCoeff();
  if (llt.rcond() >= 1e3 * kMinRelativeEigenvalue && llt.rcond() * norm1 >= 1e3 * kMinVariance) {
    return absl::OkStatus();
  }
  const Eigen::VectorXd eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(covariance).eigenvalues();
  if (!(eigenvalues.minCoeff() >= kMinRelativeEigenvalue * eigenvalues.maxCoeff())) {
    return error("covariance is numerically singular (eigenvalues ", eigenvalues.minCoeff(), " to ",
                 eigenvalues.maxCoeff(), "; the smallest must be at least ", kMinRelativeEigenvalue,
                 " of the largest)");
  }
  if (!(eigenvalues.minCoeff() >= kMinVariance)) {
    return error("covariance is nearly rigid (smallest eigenvalue ", eigenvalues.minCoeff(), "; at least ",
                 kMinVariance, " m² or rad²)");
  }
  return absl::OkStatus();
}

int LocalSubmap::RegularizeDegenerateCovariance() {
  if (Validate().ok() || !covariance.allFinite() || covariance.rows() != mean.size() ||
      covariance.cols() != mean.size()) {
    return 0;
  }
  const double scale = std::max(1.0, covariance.cwiseAbs().maxCoeff());
  if ((covariance - covariance.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) return 0;
  // Positive semidefinite to rounding only: a clearly negative eigenvalue is not a
  // degenerate map but a wrong one.
  const Eigen::VectorXd eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(covariance).eigenvalues();
  if (eigenvalues.minCoeff() < -1e-9 * std::max(eigenvalues.maxCoeff(), 0.0)) return 0;
  const Eigen::MatrixXd original = covariance;
  double variance = kRegularizationVariance;
  for (int round = 1; round <= kMaxRegularizationRounds; ++round, variance *= 10.0) {
    covariance = original;
    covariance.diagonal().array() += variance;
    if (Validate().ok()) {
      covariance_repairs += round;
      return round;
    }
  }
  covariance = original;
  return 0;
}

}  // namespace subslam
