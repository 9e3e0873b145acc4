#include "subslam/backend/ceres_joiner.h"

#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>

#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/tree_joiner.h"
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
    EXPECT_TRUE(
        testing::MatricesNear(ceres.AnchorCovariance(k), reference.AnchorCovariance(k), 1e-7));  // estimates 1e-6 apart
  }
  EXPECT_GT(moved, 1e-6);  // the solve changed the estimate the joiner answers with
  for (int j = 0; j < ceres.num_landmarks(); ++j) {
    EXPECT_LT((ceres.landmark(j) - reference.landmark(j)).cwiseAbs().maxCoeff(), 1e-6);
  }
}

// As nodes of a binary tree, Ceres joiners join whole maps by the EIF's tree join, and the
// root's Finish() solves once: the same optimum as the sequential Ceres back-end (the
// landmarks, numbered in another order by the tree, paired by their truth ids).
TEST(CeresJoiner, TreeOfCeresNodesSolvesOnceAtTheRootToTheSameOptimum) {
  const SyntheticRun run = MakeRun(7, 12, 3.0);
  CeresJoinerOptions options;
  options.eif = ConvergingKnownAssociation();
  CeresJoiner sequential(run.anchors[0], options);
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(sequential.Join(s).ok());
  ASSERT_TRUE(sequential.Finish().ok());
  const auto truth_of_landmark = [](const MapJoiner& j) {
    std::map<int, int> out;
    for (const SubmapFactor& f : j.graph().factors()) {
      for (int i = 0; i < f.submap.num_landmarks(); ++i)
        out[*f.submap.landmarks[i].truth_id] = f.landmark_of_feature[i];
    }
    return out;
  };
  for (const bool running : {true, false}) {
    TreeJoinerOptions tree_options;
    tree_options.running = running;
    TreeJoiner tree(std::make_unique<CeresJoiner>(run.anchors[0], options), tree_options);
    for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(tree.Join(s).ok());
    ASSERT_TRUE(tree.Finish().ok());
    EXPECT_EQ(tree.Name(), "tree-ceres");
    EXPECT_EQ(tree.Extras().figures.at("ceres_solves"), 1.0);
    ASSERT_EQ(tree.num_anchors(), sequential.num_anchors());
    for (int k = 1; k < tree.num_anchors(); ++k) {
      Eigen::Vector3d e = tree.anchor(k).vector() - sequential.anchor(k).vector();
      e[2] = WrapAngle(e[2]);
      EXPECT_LT(e.cwiseAbs().maxCoeff(), 1e-6) << (running ? "running" : "batch") << " anchor " << k;
    }
    const std::map<int, int> in_tree = truth_of_landmark(tree), in_sequence = truth_of_landmark(sequential);
    ASSERT_EQ(in_tree.size(), in_sequence.size());
    for (const auto& [truth, j] : in_sequence) {
      EXPECT_LT((tree.landmark(in_tree.at(truth)) - sequential.landmark(j)).cwiseAbs().maxCoeff(), 1e-6);
    }
  }
}

// A tree node joins only its own kind.
TEST(CeresJoiner, JoinsOnlyAnotherCeresMap) {
  const SyntheticRun run = MakeRun(3, 2, 1.0);
  CeresJoinerOptions options;
  options.eif = ConvergingKnownAssociation();
  CeresJoiner left(Pose2(), options);
  EifJoiner right(Pose2(), options.eif);
  ASSERT_TRUE(left.Join(run.submaps[0]).ok());
  ASSERT_TRUE(right.Join(run.submaps[1]).ok());
  const absl::Status st = left.JoinMap(right);
  EXPECT_EQ(st.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("not a Ceres map"), std::string::npos);
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
