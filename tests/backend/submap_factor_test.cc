// The submap factor's residual and its analytic Jacobians against numerical differentiation.
#include "subslam/backend/submap_factor.h"

#include <gtest/gtest.h>

#include <vector>

#include "synthetic_run.h"
#include "test_util.h"

namespace subslam::backend {
namespace {

using testing::MatricesNear;

TEST(SubmapFactor, JacobiansMatchNumericalDifferentiation) {
  const SyntheticRun run = MakeRun(3, 3);
  const LocalSubmap& s = run.submaps[1];
  std::vector<Eigen::Vector2d> lms;
  for (const LocalSubmapLandmark& l : s.landmarks) lms.push_back(run.landmarks[*l.truth_id]);
  for (const Pose2& start : testing::TestPoses()) {
    const Pose2 end = Compose(start, Pose2(3.0, 1.0, 2.5));
    const SubmapFactorLinearization lin = LinearizeSubmapFactor(s, start, end, lms);
    // The residual-only evaluation (cost) equals the linearisation's, and is what the
    // Jacobians are differentiated against.
    const auto residual = [&](const Pose2& a, const Pose2& b, const std::vector<Eigen::Vector2d>& l) {
      return SubmapResidual(s, a, b, l);
    };
    EXPECT_TRUE(MatricesNear(lin.residual, residual(start, end, lms), 1e-12));
    std::vector<int> angle_rows = {2};
    EXPECT_TRUE(testing::JacobianMatches(
        lin.J_start,
        [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return residual(Pose2::FromVector(v), end, lms); },
        start.vector(), angle_rows));
    EXPECT_TRUE(testing::JacobianMatches(
        lin.J_end,
        [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return residual(start, Pose2::FromVector(v), lms); },
        end.vector(), angle_rows));
    Eigen::VectorXd flat(2 * lms.size());
    for (size_t i = 0; i < lms.size(); ++i) flat.segment<2>(2 * i) = lms[i];
    EXPECT_TRUE(testing::JacobianMatches(
        lin.J_landmarks,
        [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
          std::vector<Eigen::Vector2d> l(lms.size());
          for (size_t i = 0; i < l.size(); ++i) l[i] = v.segment<2>(2 * i);
          return residual(start, end, l);
        },
        flat, angle_rows));
  }
}

}  // namespace
}  // namespace subslam::backend
