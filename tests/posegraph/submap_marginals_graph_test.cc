#include "subslam/posegraph/submap_marginals_graph.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <filesystem>
#include <random>

#include "subslam/posegraph/graph_format.h"

namespace subslam::posegraph {
namespace {

// A local map over [end pose, n features] with a random symmetric positive-definite
// covariance (correlated blocks: the cross terms the marginals drop).
LocalSubmap RandomLocalMap(int n, std::mt19937* rng) {
  std::normal_distribution<double> normal;
  LocalSubmap s;
  s.mean = Eigen::VectorXd(3 + 2 * n);
  for (int r = 0; r < s.mean.size(); ++r) s.mean[r] = 3.0 * normal(*rng);
  Eigen::MatrixXd A(3 + 2 * n, 3 + 2 * n);
  for (int r = 0; r < A.rows(); ++r) {
    for (int c = 0; c < A.cols(); ++c) A(r, c) = 0.1 * normal(*rng);
  }
  s.covariance = A * A.transpose() + 0.01 * Eigen::MatrixXd::Identity(3 + 2 * n, 3 + 2 * n);
  s.landmarks.resize(n);
  return s;
}

// Two local maps over three anchors and three landmarks (one seen by both), written as
// g2o and read back: every anchor and landmark with its estimate, P0 fixed, one edge per
// map with its end-pose block's information and one sighting per feature with its own
// block's — the local maps' marginals, the cross-covariances dropped.
TEST(SubmapMarginalsGraph, WritesEachLocalMapAsItsMarginalBlocks) {
  std::mt19937 rng(3);
  SubmapGraph graph(Pose2(1.0, 2.0, 0.3));
  const int a1 = graph.AddAnchor(Pose2(4.0, 3.0, -0.2)), a2 = graph.AddAnchor(Pose2(6.0, 1.0, 1.1));
  const int l0 = graph.AddLandmark({5.0, 7.0}), l1 = graph.AddLandmark({-2.0, 4.0}), l2 = graph.AddLandmark({8.0, 0.5});
  graph.AddFactor({RandomLocalMap(2, &rng), 0, a1, {l0, l1}});
  graph.AddFactor({RandomLocalMap(2, &rng), a1, a2, {l1, l2}});
  const std::string path = (std::filesystem::path(::testing::TempDir()) / "submap_marginals.g2o").string();
  ASSERT_TRUE(WriteGraph(SubmapMarginalsGraph(graph), path, {.format = GraphFormat::kG2o}).ok());
  absl::StatusOr<PoseGraph> back = ReadGraph(path);
  ASSERT_TRUE(back.ok()) << back.status();

  ASSERT_EQ(back->poses.size(), 3u);
  ASSERT_EQ(back->points.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    const PoseVertex& v = back->poses[back->FindPose(k)];
    EXPECT_EQ(v.estimate.vector(), graph.anchors()[k].vector());
    EXPECT_EQ(v.fixed, k == 0);
  }
  for (int j = 0; j < 3; ++j) {
    EXPECT_EQ(back->points[back->FindPoint(3 + j)].estimate, graph.landmarks()[j]);
  }
  ASSERT_EQ(back->odometry.size(), 2u);
  ASSERT_EQ(back->point_measurements.size(), 4u);
  int sightings = 0;
  for (const SubmapFactor& f : graph.factors()) {
    const LocalSubmap& s = f.submap;
    const OdometryMeasurement& e = back->odometry[f.start_anchor];
    EXPECT_EQ(back->poses[e.from].id, f.start_anchor);
    EXPECT_EQ(back->poses[e.to].id, f.end_anchor);
    EXPECT_EQ(e.z.vector(), s.mean.head<3>());
    EXPECT_TRUE(e.information.isApprox(s.covariance.topLeftCorner<3, 3>().inverse(), 1e-12));
    for (int i = 0; i < s.num_landmarks(); ++i, ++sightings) {
      const PointMeasurement& m = back->point_measurements[sightings];
      EXPECT_EQ(back->poses[m.pose].id, f.start_anchor);
      EXPECT_EQ(back->points[m.point].id, 3 + f.landmark_of_feature[i]);
      EXPECT_EQ(m.z, s.landmark(i));
      EXPECT_TRUE(m.information.isApprox(s.landmark_covariance(i).inverse(), 1e-12));
    }
  }
}

}  // namespace
}  // namespace subslam::posegraph
