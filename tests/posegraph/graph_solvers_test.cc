#include <gtest/gtest.h>

#include <boost/math/distributions/chi_squared.hpp>
#include <utility>
#include <vector>

#include "posegraph/synthetic_graph.h"
#include "subslam/posegraph/batch_solver.h"
#include "subslam/posegraph/submap_route.h"
#include "test_util.h"

namespace subslam::posegraph {
namespace {

using testing::MakeSyntheticGraph;
using testing::Sightings;

// Residual dimensions and free variables of a graph (the first pose held).
int ResidualDimensions(const PoseGraph& g) {
  return static_cast<int>(3 * g.odometry.size() + 2 * g.point_measurements.size() +
                          2 * g.bearing_range_measurements.size() + g.bearing_measurements.size());
}
int FreeVariables(const PoseGraph& g) { return static_cast<int>(3 * (g.poses.size() - 1) + 2 * g.points.size()); }

TEST(DeadReckoning, ComposesOdometryAndPlacesPointsAtTheirFirstSighting) {
  PoseGraph g;
  g.PoseIndex(10);
  g.PoseIndex(11);
  g.PoseIndex(12);
  g.PointIndex(0);
  g.PointIndex(1);
  g.odometry.push_back({0, 1, Pose2(1, 0, kPi / 2), Eigen::Matrix3d::Identity()});
  g.odometry.push_back({2, 1, Pose2(1, 0, 0), Eigen::Matrix3d::Identity()});  // backwards: pose 2 → pose 1
  g.point_measurements.push_back({1, 0, Eigen::Vector2d(2, 0), Eigen::Matrix2d::Identity()});
  // Point 1 by bearings only: pose 0's line y = x, pose 1's from (1, 0) along (−1, 1)
  // (world direction 3π/4, bearing π/4 from its heading π/2): they meet at (0.5, 0.5).
  g.bearing_measurements.push_back({0, 1, kPi / 4, 1.0});
  g.bearing_measurements.push_back({1, 1, kPi / 4, 1.0});
  ASSERT_TRUE(InitializeByDeadReckoning(&g).ok());
  EXPECT_NEAR((g.poses[1].estimate.vector() - Eigen::Vector3d(1, 0, kPi / 2)).norm(), 0, 1e-12);
  // Pose 2 ∘ (1, 0, 0) = pose 1, so pose 2 = (1, −1, π/2).
  EXPECT_NEAR((g.poses[2].estimate.vector() - Eigen::Vector3d(1, -1, kPi / 2)).norm(), 0, 1e-12);
  EXPECT_NEAR((g.points[0].estimate - Eigen::Vector2d(1, 2)).norm(), 0, 1e-12);
  EXPECT_NEAR((g.points[1].estimate - Eigen::Vector2d(0.5, 0.5)).norm(), 0.0, 1e-9);
  // Parallel bearing lines (pose 1's along world direction π/4 too) cannot place a point.
  g.bearing_measurements[1].bearing = -kPi / 4;
  auto s = InitializeByDeadReckoning(&g);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(std::string(s.message()).find("parallel"), std::string::npos) << s;
}

TEST(PoseGraph, ValidateRefusesADisconnectedGraph) {
  testing::SyntheticGraph s = MakeSyntheticGraph(10, 6, Sightings::kPoint, 1);
  EXPECT_TRUE(s.graph.Validate().ok());
  s.graph.PointIndex(999);  // never seen
  const absl::Status status = s.graph.Validate();
  EXPECT_FALSE(status.ok());
  EXPECT_NE(std::string(status.message()).find("point 999 is not connected"), std::string::npos) << status;
}

// Levenberg-Marquardt, Dogleg and Gauss-Newton from dead reckoning reach one minimum on a
// well-posed graph, and its χ² is what the noise model predicts: χ² of (residual
// dimensions − variables) degrees of freedom, inside its two-sided 99.8 % interval.
TEST(BatchSolver, MethodsAgreeAndTheMinimumHasTheExpectedChi2) {
  for (Sightings kind : {Sightings::kPoint, Sightings::kBearingRange}) {
    const testing::SyntheticGraph s = MakeSyntheticGraph(120, 24, kind, 11);
    PoseGraph start = s.graph;
    ASSERT_TRUE(InitializeByDeadReckoning(&start).ok());
    std::vector<double> errors;
    for (backend::CeresMethod method : {backend::CeresMethod::kLevenbergMarquardt, backend::CeresMethod::kDogleg,
                                        backend::CeresMethod::kGaussNewton}) {
      PoseGraph g = start;
      backend::CeresSolveOptions options;
      options.method = method;
      auto r = SolveGraphWithCeres(&g, options);
      ASSERT_TRUE(r.ok()) << r.status();
      EXPECT_LT(r->final_error, r->initial_error);
      EXPECT_NEAR(EvaluateError(g).error, r->final_error, 1e-9 * r->final_error);
      errors.push_back(r->final_error);
    }
    EXPECT_NEAR(errors[1], errors[0], 1e-6 * errors[0]);
    EXPECT_NEAR(errors[2], errors[0], 1e-6 * errors[0]);
    const int dof = ResidualDimensions(s.graph) - FreeVariables(s.graph);
    const boost::math::chi_squared chi2(dof);
    EXPECT_GT(2.0 * errors[0], boost::math::quantile(chi2, 0.001));
    EXPECT_LT(2.0 * errors[0], boost::math::quantile(chi2, 0.999));
  }
}

// The submap route, then Levenberg-Marquardt, reaches the batch minimum; the route's own
// estimate is already near it; one pose per local map and several agree, joined in a
// binary tree or in order.
TEST(SubmapRoute, ReachesTheBatchMinimum) {
  for (Sightings kind : {Sightings::kPoint, Sightings::kBearingRange}) {
    SCOPED_TRACE(kind == Sightings::kPoint ? "point" : "bearing-range");
    const testing::SyntheticGraph s = MakeSyntheticGraph(150, 24, kind, 21);
    PoseGraph batch = s.graph;
    for (size_t i = 0; i < batch.poses.size(); ++i) batch.poses[i].estimate = s.true_poses[i];
    for (size_t j = 0; j < batch.points.size(); ++j) batch.points[j].estimate = s.true_points[j];
    // Both solves stop on the step, not on the cost: near the minimum a cost change below
    // Ceres's default function tolerance still moves a loosely seen point by ~1e-5 m.
    backend::CeresSolveOptions exact;
    exact.function_tolerance = 0.0;
    exact.parameter_tolerance = 1e-14;
    ASSERT_TRUE(SolveGraphWithCeres(&batch, exact).ok());
    const double minimum = EvaluateError(batch).error;
    const std::vector<std::pair<int, bool>> settings = {{1, false}, {7, true}, {7, false}, {30, true}};
    for (const auto& [poses_per_map, tree] : settings) {
      SCOPED_TRACE(::testing::Message() << poses_per_map << " poses per map, " << (tree ? "tree" : "in order"));
      PoseGraph g = s.graph;
      g.poses[0].estimate = s.true_poses[0];  // the gauge where the batch solution has it
      g.poses[0].has_estimate = true;
      SubmapRouteOptions options;
      options.poses_per_map = poses_per_map;
      options.tree = tree;
      auto r = SolveBySubmaps(&g, options);
      ASSERT_TRUE(r.ok()) << r.status();
      EXPECT_EQ(r->local_maps, (149 + poses_per_map - 1) / poses_per_map);
      const double route = EvaluateError(g).error;
      EXPECT_LT(route, 1.05 * minimum);
      ASSERT_TRUE(SolveGraphWithCeres(&g, exact).ok());
      EXPECT_NEAR(EvaluateError(g).error, minimum, 1e-6 * minimum);
      for (size_t j = 0; j < g.points.size(); ++j) {
        EXPECT_NEAR((g.points[j].estimate - batch.points[j].estimate).norm(), 0.0, 1e-5);
      }
    }
  }
}

TEST(SubmapRoute, SaysWhereItDoesNotApply) {
  testing::SyntheticGraph s = MakeSyntheticGraph(20, 6, Sightings::kPoint, 2);
  PoseGraph loop = s.graph;
  loop.odometry.push_back({19, 0, Between(s.true_poses[19], s.true_poses[0]), Eigen::Matrix3d::Identity()});
  auto r = SolveBySubmaps(&loop, {});
  EXPECT_EQ(r.status().code(), absl::StatusCode::kUnimplemented);
  EXPECT_NE(std::string(r.status().message()).find("not its next step"), std::string::npos) << r.status();
  PoseGraph bearing = s.graph;
  bearing.bearing_measurements.push_back({0, 0, 0.0, 1.0});
  EXPECT_EQ(SolveBySubmaps(&bearing, {}).status().code(), absl::StatusCode::kUnimplemented);
  SubmapRouteOptions bad;
  bad.poses_per_map = 0;
  EXPECT_FALSE(SolveBySubmaps(&s.graph, bad).ok());
}

}  // namespace
}  // namespace subslam::posegraph
