#include "subslam/posegraph/graph_format.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <filesystem>

#include "posegraph/synthetic_graph.h"
#include "test_util.h"

namespace subslam::posegraph {
namespace {

::testing::AssertionResult Contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "\"" << text << "\" does not contain \"" << part << "\"";
}

// The graph file's error message, or "" when it parses.
std::string ParseError(const std::string& text, GraphFormat format,
                       std::optional<NoiseConvention> noise = std::nullopt) {
  auto g = ParseGraph(text, "test.graph", format, noise);
  return g.ok() ? "" : std::string(g.status().message());
}

TEST(GraphFormat, ReadsG2oWithKnownValues) {
  const std::string text =
      "# a comment\n"
      "VERTEX_SE2 0 0 0 0\n"
      "VERTEX_SE2 1 1.0 0.5 0.1\n"
      "VERTEX_XY 7 3 4\n"
      "FIX 0\n"
      "\n"
      "EDGE_SE2 0 1 1 0 0 100 0 0 100 0 400\n"
      "EDGE_SE2_XY 1 7 2.0 3.0 4 1 9\n"
      "EDGE_BEARING_SE2_XY 0 7 0.9 25\n";
  auto g = ParseGraph(text, "mem", GraphFormat::kG2o);
  ASSERT_TRUE(g.ok()) << g.status();
  ASSERT_EQ(g->poses.size(), 2u);
  ASSERT_EQ(g->points.size(), 1u);
  EXPECT_TRUE(g->poses[0].fixed);
  EXPECT_FALSE(g->poses[1].fixed);
  EXPECT_TRUE(g->HasEstimates());
  EXPECT_EQ(g->points[0].id, 7);
  ASSERT_EQ(g->odometry.size(), 1u);
  EXPECT_EQ(g->odometry[0].information(2, 2), 400.0);
  ASSERT_EQ(g->point_measurements.size(), 1u);
  EXPECT_EQ(g->point_measurements[0].information(0, 1), 1.0);
  EXPECT_EQ(g->point_measurements[0].information(1, 0), 1.0);
  ASSERT_EQ(g->bearing_measurements.size(), 1u);
  EXPECT_TRUE(g->Validate().ok());
  // The error by hand. Odometry: (z⁻¹ ∘ x0⁻¹ ∘ x1) = (0, 0.5, 0.1) → 100·0.25 + 400·0.01.
  // Point: x1⁻¹ · (3, 4) − (2, 3); bearing: atan2(4, 3) − 0.9.
  const Eigen::Vector2d p = TransformTo(Pose2(1.0, 0.5, 0.1), Eigen::Vector2d(3, 4)) - Eigen::Vector2d(2, 3);
  const double point_chi2 = 4 * p.x() * p.x() + 2 * p.x() * p.y() + 9 * p.y() * p.y();
  const double b = std::atan2(4.0, 3.0) - 0.9;
  const GraphError e = EvaluateError(*g);
  EXPECT_NEAR(e.chi2, 100 * 0.25 + 400 * 0.01 + point_chi2 + 25 * b * b, 1e-9);
  EXPECT_NEAR(e.error, 0.5 * e.chi2, 1e-12);
}

TEST(GraphFormat, ReadsTheNoiseUnderEachConvention) {
  const std::string line = "ODOMETRY 0 1 1 0 0 2 1 0 3 0 4\n";
  // Information as written: symmetric [[2,1,0],[1,3,0],[0,0,4]].
  auto info = ParseGraph(line, "m", GraphFormat::kIsam, NoiseConvention::kInformation);
  ASSERT_TRUE(info.ok()) << info.status();
  Eigen::Matrix3d expected;
  expected << 2, 1, 0, 1, 3, 0, 0, 0, 4;
  EXPECT_TRUE(testing::MatricesNear(expected, info->odometry[0].information, 1e-12));
  // iSAM's default: square-root information R (upper triangular), Ω = RᵀR.
  auto sqrt_info = ParseGraph(line, "m", GraphFormat::kIsam);
  ASSERT_TRUE(sqrt_info.ok()) << sqrt_info.status();
  Eigen::Matrix3d R;
  R << 2, 1, 0, 0, 3, 0, 0, 0, 4;
  EXPECT_TRUE(testing::MatricesNear(R.transpose() * R, sqrt_info->odometry[0].information, 1e-12));
  // GTSAM's: covariance.
  auto covariance = ParseGraph(line, "m", GraphFormat::kGtsam);
  ASSERT_TRUE(covariance.ok()) << covariance.status();
  EXPECT_TRUE(testing::MatricesNear(expected.inverse(), covariance->odometry[0].information, 1e-12));
  // TORO's order I11 I12 I22 I33 I13 I23.
  auto toro = ParseGraph("EDGE2 0 1 1 0 0 2 1 3 4 0.5 0.25\n", "m", GraphFormat::kToro);
  ASSERT_TRUE(toro.ok()) << toro.status();
  Eigen::Matrix3d toro_expected;
  toro_expected << 2, 1, 0.5, 1, 3, 0.25, 0.5, 0.25, 4;
  EXPECT_TRUE(testing::MatricesNear(toro_expected, toro->odometry[0].information, 1e-12));
}

TEST(GraphFormat, GtsamReadsLandmarksAsBearingRange) {
  const std::string text =
      "ODOMETRY 0 1 1 0 0 0.0001 0 0 4e-06 0 4e-06\n"
      "LANDMARK 1 5 3 4 0.4 0 0.4\n"
      "BR 1 6 0.5 10 0.1 0.2\n";
  auto gtsam = ParseGraph(text, "m", GraphFormat::kGtsam);
  ASSERT_TRUE(gtsam.ok()) << gtsam.status();
  ASSERT_EQ(gtsam->bearing_range_measurements.size(), 2u);
  const BearingRangeMeasurement& m = gtsam->bearing_range_measurements[0];
  EXPECT_NEAR(m.bearing, std::atan2(4.0, 3.0), 1e-15);
  EXPECT_NEAR(m.range, 5.0, 1e-15);
  // σ_b = √(0.4/10) = 0.2 rad, σ_r = √0.4 m.
  EXPECT_NEAR(m.information(0, 0), 25.0, 1e-12);
  EXPECT_NEAR(m.information(1, 1), 2.5, 1e-12);
  EXPECT_NEAR(gtsam->odometry[0].information(0, 0), 1e4, 1e-6);
  EXPECT_NEAR(gtsam->bearing_range_measurements[1].information(0, 0), 100.0, 1e-9);
  // iSAM's own reading of the same LANDMARK line: a Cartesian sighting, R = [[0.4,0],[0,0.4]].
  auto isam = ParseGraph(text, "m", GraphFormat::kIsam);
  ASSERT_TRUE(isam.ok()) << isam.status();
  ASSERT_EQ(isam->point_measurements.size(), 1u);
  EXPECT_NEAR(isam->point_measurements[0].information(0, 0), 0.16, 1e-15);
  // Pose and landmark ids are separate spaces: landmark 1 is not pose 1.
  auto shared = ParseGraph("ODOMETRY 0 1 1 0 0 1 0 0 1 0 1\nLANDMARK 0 1 1 1 1 0 1\n", "m", GraphFormat::kIsam);
  ASSERT_TRUE(shared.ok()) << shared.status();
  EXPECT_EQ(shared->poses.size(), 2u);
  EXPECT_EQ(shared->points.size(), 1u);
}

TEST(GraphFormat, RoundTripsEveryFormat) {
  const testing::SyntheticGraph points = testing::MakeSyntheticGraph(40, 12, testing::Sightings::kPoint, 3);
  const testing::SyntheticGraph polar = testing::MakeSyntheticGraph(40, 12, testing::Sightings::kBearingRange, 4);
  PoseGraph chain = points.graph;  // poses only, for TORO
  chain.ClearPoints();
  struct Case {
    const PoseGraph* graph;
    GraphFormat format;
    std::optional<NoiseConvention> noise;
  };
  PoseGraph with_estimates = points.graph;
  for (size_t i = 0; i < with_estimates.poses.size(); ++i) {
    with_estimates.poses[i].estimate = points.true_poses[i];
    with_estimates.poses[i].has_estimate = true;
  }
  for (size_t j = 0; j < with_estimates.points.size(); ++j) {
    with_estimates.points[j].estimate = points.true_points[j];
    with_estimates.points[j].has_estimate = true;
  }
  with_estimates.poses[0].fixed = true;
  const Case cases[] = {{&with_estimates, GraphFormat::kG2o, std::nullopt},
                        {&with_estimates, GraphFormat::kG2o, NoiseConvention::kCovariance},
                        {&points.graph, GraphFormat::kIsam, std::nullopt},
                        {&polar.graph, GraphFormat::kIsam, std::nullopt},
                        {&polar.graph, GraphFormat::kGtsam, std::nullopt},
                        {&with_estimates, GraphFormat::kIsam, NoiseConvention::kInformation},
                        {&chain, GraphFormat::kToro, std::nullopt}};
  for (const Case& c : cases) {
    SCOPED_TRACE(ToString(c.format));
    GraphWriteOptions write;
    write.format = c.format;
    write.noise = c.noise;
    auto text = FormatGraph(*c.graph, write);
    ASSERT_TRUE(text.ok()) << text.status();
    auto back = ParseGraph(*text, "round trip", c.format, c.noise);
    ASSERT_TRUE(back.ok()) << back.status();
    ASSERT_EQ(back->poses.size(), c.graph->poses.size());
    ASSERT_EQ(back->points.size(), c.graph->points.size());
    ASSERT_EQ(back->odometry.size(), c.graph->odometry.size());
    ASSERT_EQ(back->point_measurements.size(), c.graph->point_measurements.size());
    ASSERT_EQ(back->bearing_range_measurements.size(), c.graph->bearing_range_measurements.size());
    for (size_t i = 0; i < back->poses.size(); ++i) {
      EXPECT_EQ(back->poses[i].id, c.graph->poses[i].id);
      // g2o and TORO declare every vertex (one without an estimate at the origin).
      if (c.graph->poses[i].has_estimate || c.format == GraphFormat::kIsam || c.format == GraphFormat::kGtsam) {
        EXPECT_EQ(back->poses[i].has_estimate, c.graph->poses[i].has_estimate);
        EXPECT_EQ(back->poses[i].estimate.vector(), c.graph->poses[i].estimate.vector());
      }
    }
    for (size_t e = 0; e < back->odometry.size(); ++e) {
      EXPECT_EQ(back->odometry[e].z.vector(), c.graph->odometry[e].z.vector());
      EXPECT_TRUE(testing::MatricesNear(c.graph->odometry[e].information, back->odometry[e].information, 1e-12));
    }
    for (size_t e = 0; e < back->point_measurements.size(); ++e) {
      EXPECT_EQ(back->point_measurements[e].z, c.graph->point_measurements[e].z);
      EXPECT_TRUE(testing::MatricesNear(c.graph->point_measurements[e].information,
                                        back->point_measurements[e].information, 1e-12));
    }
    for (size_t e = 0; e < back->bearing_range_measurements.size(); ++e) {
      const auto& a = c.graph->bearing_range_measurements[e];
      const auto& b = back->bearing_range_measurements[e];
      EXPECT_NEAR(a.bearing, b.bearing, 1e-15);
      EXPECT_NEAR(a.range, b.range, 1e-13);
      EXPECT_TRUE(testing::MatricesNear(a.information, b.information, 1e-12));
    }
    // Written again, the text is the same.
    auto again = FormatGraph(*back, write);
    ASSERT_TRUE(again.ok());
    if (!c.noise.has_value() && c.format != GraphFormat::kGtsam) {
      EXPECT_EQ(*again, *text);
    }
  }
}

TEST(GraphFormat, KeepsTimeOrderWhenWriting) {
  const std::string text =
      "LANDMARK 0 9 1 0 1 0 1\n"
      "ODOMETRY 0 1 1 0 0 1 0 0 1 0 1\n"
      "LANDMARK 1 9 1 1 1 0 1\n"
      "LANDMARK 1 8 2 1 1 0 1\n"
      "ODOMETRY 1 2 1 0 0 1 0 0 1 0 1\n";
  auto g = ParseGraph(text, "m", GraphFormat::kIsam);
  ASSERT_TRUE(g.ok()) << g.status();
  GraphWriteOptions write;
  write.format = GraphFormat::kIsam;
  auto out = FormatGraph(*g, write);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(*out, text);
}

TEST(GraphFormat, RefusesBadLinesNamingFileLineAndField) {
  struct Case {
    GraphFormat format;
    std::string text;
    std::string expected;  // in the message
  };
  const Case cases[] = {
      {GraphFormat::kG2o, "VERTEX_SE2 0 0 0\n", "test.graph:1: VERTEX_SE2: missing field 'theta'"},
      {GraphFormat::kG2o, "VERTEX_SE2 0 0 0 0 7\n", "field(s) beyond the 4 expected"},
      {GraphFormat::kG2o, "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 x 0 0\n",
       "test.graph:2: VERTEX_SE2: field 'x' (field 2) is not a number"},
      {GraphFormat::kG2o, "VERTEX_SE2 0 0 0 nan\n", "field 'theta' (field 4) is not finite"},
      {GraphFormat::kG2o, "VERTEX_SE2 -1 0 0 0\n", "is a negative id"},
      {GraphFormat::kG2o, "VERTEX_SE2 1.5 0 0 0\n", "is not an integer id"},
      {GraphFormat::kG2o, "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n", "unknown tag"},
      {GraphFormat::kG2o, "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 0 0 0 0\n", "defined twice"},
      {GraphFormat::kG2o, "VERTEX_XY 3 0 0\nEDGE_SE2 0 3 1 0 0 1 0 0 1 0 1\n", "names point 3, not a pose"},
      {GraphFormat::kG2o, "FIX 4\n", "no pose vertex 4"},
      {GraphFormat::kG2o, "EDGE_SE2 0 1 1 0 0 1 0 0 -1 0 1\n", "information not positive definite"},
      {GraphFormat::kG2o, "EDGE_SE2 0 0 1 0 0 1 0 0 1 0 1\n", "from a vertex to itself"},
      {GraphFormat::kG2o, "EDGE_SE2_XY 7 7 1 0 1 0 1\n", "from a vertex to itself"},
      {GraphFormat::kToro, "EDGE2 0 1 1 0 0 1 0 1 1 0\n", "missing field 'I23'"},
      {GraphFormat::kToro, "VERTEX_SE2 0 0 0 0\n", "unknown tag (TORO reads"},
      {GraphFormat::kIsam, "ODOMETRY 0 1 1 0 0 1 0 0 0 0 1\n", "square-root information is singular"},
      {GraphFormat::kIsam, "BR 0 1 0.1 5 0 0.1\n", "field 'sigma_bearing' (field 5) is not positive"},
      // Found by fuzzing (scripts/fuzz.sh): σ = 9.6e-294 once gave an infinite information.
      {GraphFormat::kIsam, "ODOMETRY 5 0 164 -3263.210 -16 0.003 0 0 06 0 4\nBR 100 012 98 8 096e-0295 .4\n",
       "test.graph:2: BR: noise: a standard deviation so small that its information 1/σ² is not finite"},
      {GraphFormat::kGtsam, "LANDMARK 0 1 3 4 1e-320 0 1e-320\n", "its information is not finite"},
      {GraphFormat::kGtsam, "ODOMETRY 0 1 1 0 0 1 0 0 1 0 1\nLANDMARK 1 5 3 4 0.4 0 0.5\n",
       "test.graph:2: LANDMARK: GTSAM's bearing-range reading needs a covariance c·I"},
      {GraphFormat::kGtsam, "ODOMETRY 0 1 1 0 0 1 2 0 1 0 1\n", "covariance not positive definite"},
      {GraphFormat::kIsam, "# only a comment\n", "the graph has no pose"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    EXPECT_TRUE(Contains(ParseError(c.text, c.format), c.expected));
  }
}

TEST(GraphFormat, WriterRefusesWhatAFormatCannotHold) {
  const testing::SyntheticGraph polar = testing::MakeSyntheticGraph(10, 6, testing::Sightings::kBearingRange, 5);
  const testing::SyntheticGraph points = testing::MakeSyntheticGraph(10, 6, testing::Sightings::kPoint, 5);
  GraphWriteOptions write;
  write.format = GraphFormat::kToro;
  EXPECT_TRUE(Contains(std::string(FormatGraph(points.graph, write).status().message()), "TORO holds poses only"));
  write.format = GraphFormat::kG2o;
  EXPECT_TRUE(Contains(std::string(FormatGraph(polar.graph, write).status().message()), "no bearing-range edge"));
  write.bearing_range_as_points = true;
  auto converted = FormatGraph(polar.graph, write);
  ASSERT_TRUE(converted.ok());
  EXPECT_TRUE(Contains(*converted, "# bearing-range measurements written as EDGE_SE2_XY"));
  write.format = GraphFormat::kGtsam;
  EXPECT_TRUE(Contains(std::string(FormatGraph(points.graph, write).status().message()), "Cartesian sightings"));
  PoseGraph bearing = points.graph;
  bearing.bearing_measurements.push_back({0, 0, 0.1, 1.0});
  write.format = GraphFormat::kIsam;
  EXPECT_TRUE(Contains(std::string(FormatGraph(bearing, write).status().message()), "no bearing-only line"));
  EXPECT_FALSE(WriteGraph(points.graph, "/nonexistent_dir/graph.isam", write).ok());
}

TEST(GraphFormat, FormatFromPathAndNames) {
  EXPECT_EQ(*GraphFormatFromPath("a/b.g2o"), GraphFormat::kG2o);
  EXPECT_EQ(*GraphFormatFromPath("intel.graph"), GraphFormat::kToro);
  EXPECT_EQ(*GraphFormatFromPath("x.isam"), GraphFormat::kIsam);
  EXPECT_TRUE(Contains(std::string(GraphFormatFromPath("victoria_park.txt").status().message()), "--format"));
  EXPECT_FALSE(GraphFormatFromString("gtsam2").ok());
  EXPECT_EQ(*NoiseConventionFromString("sqrt-information"), NoiseConvention::kSqrtInformation);
  EXPECT_FALSE(NoiseConventionFromString("precision").ok());
  EXPECT_FALSE(ReadGraph("/nonexistent/graph.g2o").ok());
}

// The field's standard known-association graph (../shared/data/graphs), when present.
TEST(GraphFormat, ReadsTheVictoriaParkGraph) {
  const std::string path =
      std::filesystem::path(testing::VictoriaParkDir()).parent_path().string() + "/graphs/victoria_park.txt";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent";
  GraphReadOptions read;
  read.format = GraphFormat::kGtsam;
  auto g = ReadGraph(path, read);
  ASSERT_TRUE(g.ok()) << g.status();
  EXPECT_EQ(g->poses.size(), 6969u);
  EXPECT_EQ(g->points.size(), 151u);
  EXPECT_EQ(g->odometry.size(), 6968u);
  EXPECT_EQ(g->bearing_range_measurements.size(), 3640u);
  EXPECT_TRUE(g->Validate().ok());
  // In GTSAM's reading the same lines are written back.
  GraphWriteOptions write;
  write.format = GraphFormat::kGtsam;
  auto text = FormatGraph(*g, write);
  ASSERT_TRUE(text.ok()) << text.status();
  auto back = ParseGraph(*text, "again", GraphFormat::kGtsam);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->bearing_range_measurements.size(), 3640u);
  EXPECT_NEAR(back->bearing_range_measurements[100].range, g->bearing_range_measurements[100].range, 1e-12);
}

}  // namespace
}  // namespace subslam::posegraph
