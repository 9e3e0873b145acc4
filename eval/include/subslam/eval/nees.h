// Normalised estimation error squared (NEES) and the consistency tests built on it
// (Combined SLAM §7 Eqs. 18-20; ISEIF §4 Eqs. 34-35; Bar-Shalom et al., "Estimation
// with Applications to Tracking and Navigation", §5.4).
//
//   NEES ε = (x − x̂)ᵀ P⁻¹ (x − x̂), heading differences wrapped.
//   Over N Monte Carlo runs the average NEES ε̄ = (1/N) Σ εᵢ is consistent at level
//   1 − a when it lies in [χ²_{N·n}(a/2) / N, χ²_{N·n}(1 − a/2) / N]  (two-sided).
//   Consistency index CI = ε / χ²_n(0.95); CI < 1 is the paper's "consistent".
// Pure functions, thread-safe.
#ifndef SUBSLAM_EVAL_NEES_H_
#define SUBSLAM_EVAL_NEES_H_

#include <Eigen/Core>
#include <optional>

#include "subslam/core/pose2.h"

namespace subslam::eval {

// Smallest eigenvalue / largest below which a pose covariance counts as singular.
inline constexpr double kMinRelativeEigenvalue = 1e-12;

// Pose NEES; nullopt when the covariance is singular (see kMinRelativeEigenvalue) or
// not positive definite.
std::optional<double> PoseNees(const Pose2& truth, const Pose2& estimate, const Eigen::Matrix3d& covariance);

// Point (landmark) NEES.
std::optional<double> PointNees(const Eigen::Vector2d& truth, const Eigen::Vector2d& estimate,
                                const Eigen::Matrix2d& covariance);

struct NeesBounds {
  double lower = 0.0;
  double upper = 0.0;
  bool Contains(double average_nees) const { return average_nees >= lower && average_nees <= upper; }
};

// Two-sided bounds for the average NEES of `num_runs` runs of a `dof`-dimensional state
// at the given confidence (0.95 → the 2.5% and 97.5% quantiles). For dof = 3 and 50 runs
// this gives [2.36, 3.72] (ISEIF §4).
NeesBounds AverageNeesBounds(int dof, int num_runs, double confidence = 0.95);

// CI = nees / χ²_dof(confidence).
double ConsistencyIndex(double nees, int dof, double confidence = 0.95);

}  // namespace subslam::eval

#endif  // SUBSLAM_EVAL_NEES_H_
