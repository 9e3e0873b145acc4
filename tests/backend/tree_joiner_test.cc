#include "subslam/backend/tree_joiner.h"

#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <numeric>
#include <set>
#include <utility>

#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/ekf_joiner.h"
#include "synthetic_run.h"
#include "test_util.h"

namespace subslam::backend {
namespace {

Eigen::VectorXd MarginalSigmas(const MapJoiner& j) {
  Eigen::VectorXd s(3 * (j.num_anchors() - 1) + 2 * j.num_landmarks());
  for (int k = 1; k < j.num_anchors(); ++k) s.segment<3>(3 * (k - 1)) = j.AnchorCovariance(k).diagonal().cwiseSqrt();
  for (int l = 0; l < j.num_landmarks(); ++l) {
    s.segment<2>(3 * (j.num_anchors() - 1) + 2 * l) = j.LandmarkCovariance(l).diagonal().cwiseSqrt();
  }
  return s;
}

// The landmarks of two joiners are numbered differently (the tree creates them in
// another order): map each to the true landmark of the features joined to it.
std::map<int, int> TruthOfLandmark(const MapJoiner& j) {
  std::map<int, int> out;
  for (const SubmapFactor& f : j.graph().factors()) {
    for (int i = 0; i < f.submap.num_landmarks(); ++i) out[f.landmark_of_feature[i]] = *f.submap.landmarks[i].truth_id;
  }
  return out;
}

// Largest |a − b| / σ_b over anchors and landmarks (landmarks paired by truth id).
double MaxNormalizedDifference(const MapJoiner& a, const MapJoiner& b) {
  EXPECT_EQ(a.num_anchors(), b.num_anchors());
  EXPECT_EQ(a.num_landmarks(), b.num_landmarks());
  double worst = 0.0;
  for (int k = 1; k < b.num_anchors(); ++k) {
    Eigen::Vector3d d = a.anchor(k).vector() - b.anchor(k).vector();
    d[2] = WrapAngle(d[2]);
    worst = std::max(worst, d.cwiseQuotient(b.AnchorCovariance(k).diagonal().cwiseSqrt()).cwiseAbs().maxCoeff());
  }
  std::map<int, int> landmark_of_truth;
  for (const auto& [l, t] : TruthOfLandmark(a)) landmark_of_truth[t] = l;
  for (const auto& [l, t] : TruthOfLandmark(b)) {
    const Eigen::Vector2d d = a.landmark(landmark_of_truth.at(t)) - b.landmark(l);
    worst = std::max(worst, d.cwiseQuotient(b.LandmarkCovariance(l).diagonal().cwiseSqrt()).cwiseAbs().maxCoeff());
  }
  return worst;
}

EkfJoinerOptions EkfKnown() {
  EkfJoinerOptions o;
  o.association.known_association = true;
  return o;
}

std::unique_ptr<TreeJoiner> Tree(std::unique_ptr<MapJoiner> prototype, bool running) {
  TreeJoinerOptions o;
  o.running = running;
  return std::make_unique<TreeJoiner>(std::move(prototype), o);
}

// Relinearised to convergence, the information-form tree reaches the same optimum as
// the sequential EIF (batch Gauss-Newton on the same graph), in both modes, with nodes
// as the sequential joiner's or without spare slots (EifJoinerOptions::ForTreeNode).
TEST(TreeJoiner, EifTreeEqualsSequentialEifAtConvergence) {
  const SyntheticRun run = MakeRun(7, 12, 3.0);
  EifJoiner sequential(run.anchors[0], ConvergingKnownAssociation());
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(sequential.Join(s).ok());
  ASSERT_TRUE(sequential.Finish().ok());
  for (const auto& [running, node] :
       {std::pair{true, ConvergingKnownAssociation()}, std::pair{false, ConvergingKnownAssociation()},
        std::pair{true, ConvergingKnownAssociation().ForTreeNode()}}) {
    SCOPED_TRACE(::testing::Message() << (running ? "running" : "batch")
                                      << (node.incremental_factorization ? "" : ", tree nodes"));
    auto tree = Tree(std::make_unique<EifJoiner>(run.anchors[0], node), running);
    for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(tree->Join(s).ok());
    ASSERT_TRUE(tree->Finish().ok());
    EXPECT_EQ(tree->num_nodes(), 1);
    EXPECT_EQ(tree->tree_joins(), 11);  // n − 1 joins of two maps
    EXPECT_EQ(tree->counters().joins, 12);
    EXPECT_LT(MaxNormalizedDifference(*tree, sequential), 1e-8);
    // The marginals agree too (the same Λ at the same point).
    EXPECT_TRUE(testing::MatricesNear(sequential.AnchorCovariance(12), tree->AnchorCovariance(12), 1e-9));
  }
}

// The covariance-form tree and sequential EKF joining are two first-order approximations
// of the same posterior: with little noise (small linearisation error) they agree to a
// small fraction of a standard deviation, and their marginal σ within a few percent.
TEST(TreeJoiner, EkfTreeEqualsSequentialEkfWithinTheLinearizationError) {
  const SyntheticRun run = MakeRun(5, 12, 0.2);
  EkfJoiner sequential(run.anchors[0], EkfKnown());
  auto tree = Tree(std::make_unique<EkfJoiner>(run.anchors[0], EkfKnown()), true);
  for (const LocalSubmap& s : run.submaps) {
    ASSERT_TRUE(sequential.Join(s).ok());
    ASSERT_TRUE(tree->Join(s).ok());
  }
  ASSERT_TRUE(tree->Finish().ok());
  EXPECT_LT(MaxNormalizedDifference(*tree, sequential), 0.01);
  const Eigen::VectorXd ratio = MarginalSigmas(*tree).cwiseQuotient(MarginalSigmas(sequential));
  EXPECT_LT((ratio.array() - 1.0).abs().maxCoeff(), 0.02);
  EXPECT_EQ(tree->counters().associated, sequential.counters().associated);
}

// For 2^k local maps the running binary counter and the batch level-by-level build make
// the same tree, so the same map.
TEST(TreeJoiner, RunningAndBatchBuildTheSameTree) {
  const SyntheticRun run = MakeRun(3, 8, 1.0);
  auto running = Tree(std::make_unique<EkfJoiner>(run.anchors[0], EkfKnown()), true);
  auto batch = Tree(std::make_unique<EkfJoiner>(run.anchors[0], EkfKnown()), false);
  for (const LocalSubmap& s : run.submaps) {
    ASSERT_TRUE(running->Join(s).ok());
    ASSERT_TRUE(batch->Join(s).ok());
  }
  EXPECT_EQ(running->num_nodes(), 1);  // 8 = 2³: the counter has one node
  EXPECT_EQ(batch->num_nodes(), 8);    // batch: leaves until Finish()
  ASSERT_TRUE(running->Finish().ok());
  ASSERT_TRUE(batch->Finish().ok());
  EXPECT_TRUE(testing::MatricesNear(StackedEstimate(*batch), StackedEstimate(*running), 1e-12));
}

// The running tree's whole map is available at any time (folded on demand), and the
// online anchor chained over the stack equals the folded map's last anchor when no
// landmark is shared between the stack's nodes (here: only forward motion, no loop yet).
TEST(TreeJoiner, RunningTreeGivesTheWholeMapAtAnyTime) {
  const SyntheticRun run = MakeRun(4, 12, 1.0);
  auto tree = Tree(std::make_unique<EkfJoiner>(run.anchors[0], EkfKnown()), true);
  EkfJoiner sequential(run.anchors[0], EkfKnown());
  for (int k = 0; k < 7; ++k) {
    ASSERT_TRUE(tree->Join(run.submaps[k]).ok());
    ASSERT_TRUE(sequential.Join(run.submaps[k]).ok());
    EXPECT_EQ(tree->num_anchors(), k + 2);
    EXPECT_EQ(tree->num_landmarks(), sequential.num_landmarks());
  }
  EXPECT_EQ(tree->num_nodes(), 3);  // 7 = 4 + 2 + 1
  // Chained online anchor vs the folded map's: first order, the same to within the
  // fusions of landmarks shared between nodes.
  const Pose2 chained = tree->LastAnchor();
  const Pose2 folded = tree->anchor(tree->num_anchors() - 1);
  const Eigen::Matrix3d sigma = tree->AnchorCovariance(tree->num_anchors() - 1);
  EXPECT_LT((chained.translation() - folded.translation()).norm(), 3.0 * std::sqrt(sigma.trace()));
  EXPECT_GT(tree->stage_times().at("fold"), 0.0);
}

// Unknown association across tree joins: no wrong merge on loops where the sequential
// joiners make none.
TEST(TreeJoiner, AssociatesWithoutTruth) {
  for (uint64_t seed : {11, 12, 13}) {
    const SyntheticRun run = MakeRun(seed);
    auto tree = Tree(std::make_unique<EkfJoiner>(run.anchors[0], EkfJoinerOptions()), true);
    for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(tree->Join(s).ok());
    ASSERT_TRUE(tree->Finish().ok());
    std::map<int, std::set<int>> truths_of_landmark;
    for (const auto& f : tree->graph().factors()) {
      for (int i = 0; i < f.submap.num_landmarks(); ++i) {
        truths_of_landmark[f.landmark_of_feature[i]].insert(*f.submap.landmarks[i].truth_id);
      }
    }
    int wrong = 0;
    for (const auto& [l, truths] : truths_of_landmark) wrong += static_cast<int>(truths.size()) - 1;
    EXPECT_EQ(wrong, 0) << "seed " << seed;
    EXPECT_GT(tree->counters().associated, 20) << "seed " << seed;
    EXPECT_EQ(tree->num_anchors(), 13);
  }
}

TEST(TreeJoiner, NodesMustSupportMapJoins) {
  const SyntheticRun run = MakeRun(2, 3);
  EkfJoinerOptions dropping;
  dropping.keep_anchors = false;
  auto tree = Tree(std::make_unique<EkfJoiner>(run.anchors[0], dropping), true);
  ASSERT_TRUE(tree->Join(run.submaps[0]).ok());
  EXPECT_FALSE(tree->Join(run.submaps[1]).ok());  // the join of two leaves needs the anchors
}

// A map's summary without its covariance keeps everything association by truth ids
// reads (means, truth ids, times) and leaves the joint marginal unrecovered.
TEST(SummarizeAsLocalSubmap, WithoutCovarianceKeepsWhatAssociationByTruthReads) {
  const SyntheticRun run = MakeRun(4, 5, 1.0);
  EifJoiner joiner(Pose2(), ConvergingKnownAssociation());  // a tree node's frame: anchor 0 the identity
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(joiner.Join(s).ok());
  const LocalSubmap full = SummarizeAsLocalSubmap(joiner);
  const LocalSubmap means_only = SummarizeAsLocalSubmap(joiner, /*with_covariance=*/false);
  ASSERT_GT(full.num_landmarks(), 0);
  EXPECT_EQ(full.covariance.rows(), full.mean.size());
  EXPECT_EQ(means_only.covariance.size(), 0);
  EXPECT_TRUE(testing::MatricesNear(full.mean, means_only.mean, 0.0));
  EXPECT_EQ(means_only.t_start, full.t_start);
  EXPECT_EQ(means_only.t_end, full.t_end);
  ASSERT_EQ(means_only.num_landmarks(), full.num_landmarks());
  for (int i = 0; i < full.num_landmarks(); ++i)
    EXPECT_EQ(means_only.landmarks[i].truth_id, full.landmarks[i].truth_id);
}

}  // namespace
}  // namespace subslam::backend
