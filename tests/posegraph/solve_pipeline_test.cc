#include "subslam/pipeline/solve_pipeline.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "posegraph/synthetic_graph.h"
#include "subslam/posegraph/graph_format.h"

namespace subslam::pipeline {
namespace {

TEST(SolvePipeline, RunsEveryMethodAndWritesTheReportAndSolutions) {
  const testing::SyntheticGraph s = testing::MakeSyntheticGraph(100, 20, testing::Sightings::kBearingRange, 8);
  SolveOptions options;
  options.out_dir = ::testing::TempDir() + "/solve_pipeline";
  std::filesystem::remove_all(options.out_dir);
  options.source = {{"file", "synthetic"}};
  auto r = RunSolve(s.graph, options);
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->methods.size(), SolveMethodNames().size());
  double best = r->initial_error;
  for (const SolveMethodResult& m : r->methods) {
    SCOPED_TRACE(m.name);
    ASSERT_EQ(m.status, "ok");
    EXPECT_NEAR(m.chi2, 2.0 * m.error, 1e-9 * m.chi2);
    EXPECT_GT(m.seconds, 0.0);
    best = std::min(best, m.error);
  }
  // Batch methods from dead reckoning on this short loop and the polished route reach one minimum.
  EXPECT_NEAR(r->methods[0].error, best, 1e-6 * best);
  EXPECT_NEAR(r->methods.back().error, best, 1e-6 * best);
  // report.json: one entry per method with the fields a comparison reads.
  std::ifstream in(options.out_dir + "/report.json");
  const nlohmann::json report = nlohmann::json::parse(in);
  EXPECT_EQ(report["job"], "solve");
  EXPECT_EQ(report["counts"]["poses"], 100);
  ASSERT_EQ(report["methods"].size(), SolveMethodNames().size());
  for (const nlohmann::json& m : report["methods"]) {
    for (const char* field : {"name", "status", "error", "chi2", "iterations", "seconds", "peak_rss_mb"}) {
      EXPECT_TRUE(m.contains(field)) << field;
    }
  }
  // Each solution reads back with its error (the g2o file holds the sightings as points, so
  // the check is on the vertices: they are the method's estimate).
  posegraph::GraphReadOptions read;
  auto solution = posegraph::ReadGraph(options.out_dir + "/submaps-lm.g2o", read);
  ASSERT_TRUE(solution.ok()) << solution.status();
  posegraph::PoseGraph g = s.graph;
  for (size_t i = 0; i < g.poses.size(); ++i) g.poses[i].estimate = solution->poses[i].estimate;
  for (size_t j = 0; j < g.points.size(); ++j) g.points[j].estimate = solution->points[j].estimate;
  EXPECT_NEAR(posegraph::EvaluateError(g).error, r->methods.back().error, 1e-6 * best);
}

TEST(SolvePipeline, ListsAMethodThatDoesNotApplyAndRefusesBadRequests) {
  testing::SyntheticGraph s = testing::MakeSyntheticGraph(30, 8, testing::Sightings::kPoint, 9);
  s.graph.odometry.push_back({29, 0, Between(s.true_poses[29], s.true_poses[0]), Eigen::Matrix3d::Identity()});
  SolveOptions options;
  options.methods = {"lm", "submaps"};
  auto r = RunSolve(s.graph, options);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_EQ(r->methods[0].status, "ok");
  EXPECT_NE(r->methods[1].status.find("chain"), std::string::npos) << r->methods[1].status;
  options.methods = {"lm", "isam2"};
  EXPECT_FALSE(RunSolve(s.graph, options).ok());
  options.methods = {"lm"};
  options.initial_from_file = true;  // the synthetic graph has no estimates
  EXPECT_FALSE(RunSolve(s.graph, options).ok());
}

// The field's standard known-association graph (../shared/data/graphs), when present: in
// GTSAM's reading, the submap route and its polish reach the best minimum known (2,339.22).
TEST(SolvePipeline, ReachesTheBestKnownMinimumOfTheVictoriaParkGraph) {
  const std::string path =
      std::filesystem::path(SUBSLAM_VICTORIA_PARK_DIR).parent_path().string() + "/graphs/victoria_park.txt";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent";
  posegraph::GraphReadOptions read;
  read.format = posegraph::GraphFormat::kGtsam;
  auto graph = posegraph::ReadGraph(path, read);
  ASSERT_TRUE(graph.ok()) << graph.status();
  SolveOptions options;
  options.methods = {"submaps-lm"};
  auto r = RunSolve(*graph, options);
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->methods[0].status, "ok");
  EXPECT_LE(r->methods[0].error, 2339.3);
  EXPECT_GE(r->methods[0].error, 2339.2);
  EXPECT_GT(r->initial_error, 5e7);  // from dead reckoning
}

}  // namespace
}  // namespace subslam::pipeline
