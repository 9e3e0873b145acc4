// Shared helpers for the subslam tests: named tolerances and one reusable numerical
// Jacobian checker, run on every model at the identity, near it, near ±π and at seeded
// random states.
#ifndef SUBSLAM_TESTS_TEST_UTIL_H_
#define SUBSLAM_TESTS_TEST_UTIL_H_

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "subslam/core/pose2.h"

namespace subslam::testing {

inline constexpr double kExactTolerance = 1e-12;    // algebraic identities
inline constexpr double kJacobianTolerance = 1e-6;  // analytic vs central differences
inline constexpr double kNumericStep = 1e-6;        // central-difference step

// The optional Victoria Park data set (CMake cache variable SUBSLAM_VICTORIA_PARK_DIR).
inline std::string VictoriaParkDir() { return SUBSLAM_VICTORIA_PARK_DIR; }

// Central-difference Jacobian of f at x. Output entries listed in `angle_outputs` are
// differenced with wrapping, so a heading near ±π differentiates correctly.
inline Eigen::MatrixXd NumericalJacobian(const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f,
                                         const Eigen::VectorXd& x, const std::vector<int>& angle_outputs = {}) {
  const Eigen::VectorXd f0 = f(x);
  Eigen::MatrixXd J(f0.size(), x.size());
  for (int i = 0; i < x.size(); ++i) {
    Eigen::VectorXd xp = x, xm = x;
    xp[i] += kNumericStep;
    xm[i] -= kNumericStep;
    Eigen::VectorXd d = f(xp) - f(xm);
    for (int a : angle_outputs) d[a] = WrapAngle(d[a]);
    J.col(i) = d / (2 * kNumericStep);
  }
  return J;
}

// Relative-or-absolute closeness of two matrices, with a readable failure message.
inline ::testing::AssertionResult MatricesNear(const Eigen::MatrixXd& expected, const Eigen::MatrixXd& actual,
                                               double tolerance) {
  if (expected.rows() != actual.rows() || expected.cols() != actual.cols()) {
    return ::testing::AssertionFailure() << "size mismatch";
  }
  const double scale = std::max(1.0, expected.cwiseAbs().maxCoeff());
  const double err = (expected - actual).cwiseAbs().maxCoeff();
  if (err <= tolerance * scale) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "max abs difference " << err << " > " << tolerance * scale << "\nexpected:\n"
                                       << expected << "\nactual:\n"
                                       << actual;
}

// The reusable Jacobian check: `analytic` against central differences of f at x.
inline ::testing::AssertionResult JacobianMatches(const Eigen::MatrixXd& analytic,
                                                  const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f,
                                                  const Eigen::VectorXd& x,
                                                  const std::vector<int>& angle_outputs = {}) {
  return MatricesNear(NumericalJacobian(f, x, angle_outputs), analytic, kJacobianTolerance);
}

// Poses at which every Jacobian is checked: identity, near identity, near ±π, and
// seeded random poses.
inline std::vector<Pose2> TestPoses() {
  std::vector<Pose2> poses = {Pose2(0, 0, 0), Pose2(1e-7, -1e-7, 1e-7), Pose2(1.0, 2.0, kPi - 1e-4),
                              Pose2(-3.0, 0.5, -kPi + 1e-4)};
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-10.0, 10.0), a(-kPi, kPi);
  for (int i = 0; i < 8; ++i) poses.emplace_back(u(rng), u(rng), a(rng));
  return poses;
}

}  // namespace subslam::testing

#endif  // SUBSLAM_TESTS_TEST_UTIL_H_
