#include "subslam/backend/ceres_joiner.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

#include "subslam/backend/eif_joiner.h"
#include "synthetic_run.h"
#include "test_util.h"

namespace subslam::backend {
namespace {

// The Ceres back-end ends at the iterated EIF's optimum, and what it answers (graph,
// marginals) is that solution, adopted by its EIF: a graph written after Finish holds
// Ceres's estimate, not the one before the solve.
TEST(CeresJoiner, FinishesAtTheIteratedEifOptimumAndAnswersWithIt) {
  const SyntheticRun run = MakeRun(7, 12, 3.0);
  CeresJoinerOptions options;
  options.eif = ConvergingKnownAssociation();
  options.eif.relinearize_linearization_chi2 = 0.0;  // Ceres, not the EIF, iterates
  CeresJoiner ceres(run.anchors[0], options);
  EifJoiner reference(run.anchors[0], ConvergingKnownAssociation());
  for (const LocalSubmap& s : run.submaps) {
    ASSERT_TRUE(ceres.Join(s).ok());
    ASSERT_TRUE(reference.Join(s).ok());
  }
  const SubmapGraph before = ceres.graph();
  ASSERT_TRUE(ceres.Finish().ok());
  ASSERT_TRUE(reference.Finish().ok());
  ASSERT_TRUE(ceres.last_solve().has_value());
  EXPECT_GT(ceres.last_solve()->iterations, 0);
  EXPECT_EQ(ceres.Extras().figures.at("ceres_solves"), 1.0);
  EXPECT_TRUE(ceres.stage_times().contains("ceres_solve_and_adopt"));
  double moved = 0.0;
  for (int k = 1; k < ceres.num_anchors(); ++k) {
    Eigen::Vector3d e = ceres.anchor(k).vector() - reference.anchor(k).vector();
    e[2] = WrapAngle(e[2]);
    EXPECT_LT(e.cwiseAbs().maxCoeff(), 1e-6) << "anchor " << k;
    moved = std::max(moved, (ceres.anchor(k).vector() - before.anchors()[k].vector()).cwiseAbs().maxCoeff());
    EXPECT_TRUE(testing::MatricesNear(ceres.AnchorCovariance(k), reference.AnchorCovariance(k), 1e-7));  // estimates 1e-6 apart
  }
  EXPECT_GT(moved, 1e-6);  // the solve changed the estimate the joiner answers with
  for (int j = 0; j < ceres.num_landmarks(); ++j) {
    EXPECT_LT((ceres.landmark(j) - reference.landmark(j)).cwiseAbs().maxCoeff(), 1e-6);
  }
}

TEST(CeresJoiner, SolvesOnItsSchedule) {
  const SyntheticRun run = MakeRun(7, 12, 3.0);
  CeresJoinerOptions options;
  options.eif = ConvergingKnownAssociation();
  options.solve_every = 3;
  CeresJoiner ceres(run.anchors[0], options);
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(ceres.Join(s).ok());
  const int during = static_cast<int>(run.submaps.size()) / 3;
  EXPECT_EQ(ceres.Extras().figures.at("ceres_solves"), during);
  ASSERT_TRUE(ceres.Finish().ok());
  EXPECT_EQ(ceres.Extras().figures.at("ceres_solves"), during + 1);
}

TEST(CeresJoinerOptions, RejectsANegativeSchedule) {
  CeresJoinerOptions options;
  options.solve_every = -1;
  EXPECT_FALSE(options.Validate().ok());
}

// The counters' table names every member once: operator+= and the reports iterate it.
TEST(JoinerCounters, FieldsCoverEveryCounterOnce) {
  EXPECT_EQ(JoinerCounters::Fields().size() * sizeof(long), sizeof(JoinerCounters));
  std::set<std::string> names;
  JoinerCounters a, b;
  long value = 1;
  for (const JoinerCounters::Field& f : JoinerCounters::Fields()) {
    EXPECT_TRUE(names.insert(f.name).second) << f.name;
    b.*f.member = value++;
  }
  a += b;
  a += b;
  for (const JoinerCounters::Field& f : JoinerCounters::Fields()) EXPECT_EQ(a.*f.member, 2 * (b.*f.member));
}

}  // namespace
}  // namespace subslam::backend
