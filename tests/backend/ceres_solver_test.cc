#include "subslam/backend/ceres_solver.h"

#include <gtest/gtest.h>

#include <array>

#include "subslam/backend/ceres_submap_cost.h"
#include "subslam/backend/eif_joiner.h"
#include "synthetic_run.h"
#include "test_util.h"

namespace subslam::backend {
namespace {

TEST(SubmapCostFunction, JacobiansMatchNumericalDifferentiation) {
  const SyntheticRun run = MakeRun(3, 3);
  const LocalSubmap& s = run.submaps[1];
  const SubmapCostFunction cost(s);
  const int n = s.num_landmarks(), m = 3 + 2 * n;
  // All parameters stacked: start (3), end (3), landmarks (2n).
  Eigen::VectorXd x(6 + 2 * n);
  x.head<3>() = Pose2(1.0, -2.0, 3.0).vector();  // near the wrap
  x.segment<3>(3) = Pose2(8.0, 1.0, -2.9).vector();
  for (int i = 0; i < n; ++i) x.segment<2>(6 + 2 * i) = run.landmarks[*s.landmarks[i].truth_id];
  const auto evaluate = [&](const Eigen::VectorXd& v, Eigen::MatrixXd* J) {
    std::vector<const double*> p = {v.data(), v.data() + 3};
    for (int i = 0; i < n; ++i) p.push_back(v.data() + 6 + 2 * i);
    Eigen::VectorXd r(m);
    std::vector<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> blocks;
    std::vector<double*> jac;
    if (J != nullptr) {
      blocks.emplace_back(m, 3);
      blocks.emplace_back(m, 3);
      for (int i = 0; i < n; ++i) blocks.emplace_back(m, 2);
      for (auto& b : blocks) jac.push_back(b.data());
    }
    EXPECT_TRUE(cost.Evaluate(p.data(), r.data(), J != nullptr ? jac.data() : nullptr));
    if (J != nullptr) {
      J->resize(m, 6 + 2 * n);
      int c = 0;
      for (const auto& b : blocks) {
        J->middleCols(c, b.cols()) = b;
        c += static_cast<int>(b.cols());
      }
    }
    return r;
  };
  Eigen::MatrixXd J;
  evaluate(x, &J);
  // The whitened heading residual mixes into every row, so the wrap is handled by
  // perturbing well inside (−π, π] (no angle outputs to unwrap).
  EXPECT_TRUE(testing::JacobianMatches(
      J, [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return evaluate(v, nullptr); }, x, {}));
}

// Two features of one local map on the same landmark share one parameter block: same
// residual as with two equal blocks, and the shared block's Jacobian is their sum.
TEST(SubmapCostFunction, SharedLandmarkBlockSumsTheFeatureJacobians) {
  const SyntheticRun run = MakeRun(3, 3);
  const LocalSubmap& s = run.submaps[1];
  const int n = s.num_landmarks(), m = 3 + 2 * n;
  ASSERT_GE(n, 2);
  std::vector<int> block_of_feature(n);
  for (int i = 0; i < n; ++i) block_of_feature[i] = i == n - 1 ? 0 : i;  // last shares block 0
  const SubmapCostFunction separate(s), shared(s, block_of_feature);
  const double start[3] = {0.5, -1.0, 0.2}, end[3] = {9.0, 1.0, 0.1};
  std::vector<std::array<double, 2>> l(n);
  for (int i = 0; i < n; ++i)
    l[i] = {run.landmarks[*s.landmarks[i].truth_id].x(), run.landmarks[*s.landmarks[i].truth_id].y()};
  l[n - 1] = l[0];
  std::vector<const double*> p_sep = {start, end}, p_sh = {start, end};
  for (int i = 0; i < n; ++i) p_sep.push_back(l[i].data());
  for (int i = 0; i < n - 1; ++i) p_sh.push_back(l[i].data());
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  std::vector<RowMajor> J_sep(n + 2, RowMajor(m, 2)), J_sh(n + 1, RowMajor(m, 2));
  J_sep[0].resize(m, 3);
  J_sep[1].resize(m, 3);
  J_sh[0].resize(m, 3);
  J_sh[1].resize(m, 3);
  std::vector<double*> j_sep, j_sh;
  for (auto& J : J_sep) j_sep.push_back(J.data());
  for (auto& J : J_sh) j_sh.push_back(J.data());
  Eigen::VectorXd r_sep(m), r_sh(m);
  ASSERT_TRUE(separate.Evaluate(p_sep.data(), r_sep.data(), j_sep.data()));
  ASSERT_TRUE(shared.Evaluate(p_sh.data(), r_sh.data(), j_sh.data()));
  EXPECT_TRUE(testing::MatricesNear(r_sep, r_sh, 1e-15));
  EXPECT_TRUE(testing::MatricesNear(J_sep[2] + J_sep[n + 1], J_sh[2], 1e-15));
  EXPECT_TRUE(testing::MatricesNear(J_sep[3], J_sh[3], 1e-15));
}

// Every method converges to the same minimum: the EIF relinearised to convergence.
TEST(SolveWithCeres, AllMethodsEqualTheIteratedEif) {
  const SyntheticRun run = MakeRun(7, 12, 3.0);
  EifJoinerOptions options;
  options.association.known_association = true;
  options.relinearize_heading_change = 0.0;  // the solvers start from the single linearisation
  options.relinearize_linearization_chi2 = 0.0;
  EifJoiner eif(run.anchors[0], options);
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(eif.Join(s).ok());
  const SubmapGraph linearised_once = eif.graph();
  EifJoiner reference(run.anchors[0], ConvergingKnownAssociation());
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(reference.Join(s).ok());
  ASSERT_TRUE(reference.Finish().ok());
  for (const CeresMethod method : {CeresMethod::kGaussNewton, CeresMethod::kLevenbergMarquardt, CeresMethod::kDogleg}) {
    SubmapGraph g = linearised_once;
    CeresSolveOptions o;
    o.method = method;
    absl::StatusOr<CeresSolveReport> r = SolveWithCeres(&g, o);
    ASSERT_TRUE(r.ok()) << r.status();
    EXPECT_LE(r->final_cost, r->initial_cost);
    EXPECT_GT(r->iterations, 0);
    for (int k = 1; k < g.num_anchors(); ++k) {
      Eigen::Vector3d e = g.anchors()[k].vector() - reference.anchor(k).vector();
      e[2] = WrapAngle(e[2]);
      EXPECT_LT(e.cwiseAbs().maxCoeff(), 1e-6) << "method " << static_cast<int>(method) << " anchor " << k;
    }
    for (int j = 0; j < g.num_landmarks(); ++j) {
      EXPECT_LT((g.landmarks()[j] - reference.landmark(j)).cwiseAbs().maxCoeff(), 1e-6);
    }
  }
}

// At the solution, ceres::Covariance's anchor marginals equal the EIF's, relinearised to
// the same point (both invert the Gauss-Newton Hessian).
TEST(SolveWithCeres, CovariancesEqualTheEifMarginalsAtConvergence) {
  const SyntheticRun run = MakeRun(8, 10);
  EifJoiner eif(run.anchors[0], ConvergingKnownAssociation());
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(eif.Join(s).ok());
  ASSERT_TRUE(eif.Finish().ok());
  SubmapGraph g = eif.graph();
  CeresSolveOptions o;
  o.method = CeresMethod::kGaussNewton;
  std::vector<Eigen::Matrix3d> covariances;
  const std::vector<int> which = {0, 3, 10};
  absl::StatusOr<CeresSolveReport> r = SolveWithCeres(&g, o, which, &covariances);
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(covariances.size(), which.size());
  for (size_t i = 0; i < which.size(); ++i) {
    EXPECT_TRUE(testing::MatricesNear(eif.AnchorCovariance(which[i]), covariances[i], 1e-6)) << which[i];
  }
}

// One local map with a grossly wrong end pose: a robust loss keeps the anchors nearer the
// truth than plain least squares.
TEST(SolveWithCeres, RobustLossLimitsABadLocalMap) {
  SyntheticRun run = MakeRun(9, 12);
  // A loop closure that makes the bad map matter: known association through truth ids.
  run.submaps[5].mean[0] += 6.0;  // 60σ off
  EifJoinerOptions options;
  options.association.known_association = true;
  EifJoiner eif(run.anchors[0], options);
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(eif.Join(s).ok());
  SubmapGraph plain = eif.graph(), robust = eif.graph();
  CeresSolveOptions o;
  ASSERT_TRUE(SolveWithCeres(&plain, o).ok());
  o.loss = RobustLoss::kCauchy;
  ASSERT_TRUE(SolveWithCeres(&robust, o).ok());
  EXPECT_LT(AnchorRms(robust, run), AnchorRms(plain, run));
}

TEST(CeresSolveOptions, ValidationRejectsNonsense) {
  CeresSolveOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.loss_scale = 0;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.max_iterations = 0;
  EXPECT_FALSE(o.Validate().ok());
}

}  // namespace
}  // namespace subslam::backend
