#include "subslam/posegraph/dataset_graph.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <filesystem>
#include <set>

#include "subslam/io/dataset_reader.h"
#include "subslam/io/text_table.h"
#include "subslam/posegraph/graph_format.h"

namespace subslam::posegraph {
namespace {

// The simulated data set in tests/data (hybrid-120m's first 60 s: detections carry ids).
io::Dataset TestDataset() {
  auto d = io::ReadDataset(std::string(SUBSLAM_SOURCE_DIR) + "/tests/data/hybrid_60s");
  EXPECT_TRUE(d.ok()) << d.status();
  return *d;
}

TEST(DatasetGraph, HoldsAPosePerScanAndASightingPerIdentifiedDetection) {
  const io::Dataset dataset = TestDataset();
  auto g = GraphFromDataset(dataset, SightingForm::kBearingRange);
  ASSERT_TRUE(g.ok()) << g.status();
  size_t sightings = 0;
  std::set<int> ids;
  for (const Scan& scan : dataset.scans) {
    for (const Detection& d : scan.detections) {
      if (d.truth_id < 0) continue;
      ++sightings;
      ids.insert(d.truth_id);
    }
  }
  EXPECT_EQ(g->poses.size(), dataset.scans.size());
  EXPECT_EQ(g->odometry.size(), dataset.scans.size() - 1);
  EXPECT_EQ(g->points.size(), ids.size());
  EXPECT_EQ(g->bearing_range_measurements.size(), sightings);
  EXPECT_EQ(g->points[0].id, kLandmarkIdOffset + dataset.scans[0].detections[0].truth_id);
  EXPECT_TRUE(g->Validate().ok());
  // Every odometry information is positive definite and no sharper across than the floor allows.
  for (const OdometryMeasurement& m : g->odometry) {
    const Eigen::Vector3d eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(m.information).eigenvalues();
    ASSERT_GT(eigenvalues.minCoeff(), 0.0);
    EXPECT_LE(eigenvalues.maxCoeff() / eigenvalues.minCoeff(), (1.0 + 1.0 / kMinOdometryVarianceRatio) * (1.0 + 1e-9));
  }
  // The Cartesian form: the same sightings at the measured points.
  auto points = GraphFromDataset(dataset, SightingForm::kPoint);
  ASSERT_TRUE(points.ok());
  ASSERT_EQ(points->point_measurements.size(), sightings);
  const BearingRangeMeasurement& polar = g->bearing_range_measurements[0];
  EXPECT_NEAR(points->point_measurements[0].z.norm(), polar.range, 1e-12);
  // A data set without true ids has no graph.
  io::Dataset anonymous = dataset;
  for (Scan& scan : anonymous.scans) {
    for (Detection& d : scan.detections) d.truth_id = kUnknownTruthId;
  }
  EXPECT_FALSE(GraphFromDataset(anonymous, SightingForm::kBearingRange).ok());
}

// What `subslam simulate` writes reads back, and written again gives the same bytes.
TEST(DatasetGraph, WrittenGraphsRoundTripInEveryFormat) {
  const std::string dir = ::testing::TempDir() + "/dataset_graphs";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(WriteDatasetGraphs(TestDataset(), dir).ok());
  for (const char* name : {"graph.isam", "graph.g2o", "graph.toro"}) {
    SCOPED_TRACE(name);
    const std::string path = dir + "/" + name;
    auto g = ReadGraph(path);
    ASSERT_TRUE(g.ok()) << g.status();
    EXPECT_TRUE(g->Validate().ok());
    EXPECT_TRUE(g->HasEstimates());
    GraphWriteOptions write;
    write.format = *GraphFormatFromPath(path);
    auto again = FormatGraph(*g, write);
    ASSERT_TRUE(again.ok()) << again.status();
    auto original = subslam::io::ReadFileToString(path);
    ASSERT_TRUE(original.ok());
    if (DefaultNoise(write.format) == NoiseConvention::kInformation) {
      // Information as written: the same bytes (the first difference shown; files are long).
      size_t at = 0;
      while (at < again->size() && at < original->size() && (*again)[at] == (*original)[at]) ++at;
      EXPECT_EQ(at, original->size()) << "differs at byte " << at << ": " << original->substr(at, 80);
      EXPECT_EQ(again->size(), original->size());
      continue;
    }
    // Square-root information goes through Ω = RᵀR and back: the same measurements, the
    // same information to rounding.
    auto back = ParseGraph(*again, "again", write.format);
    ASSERT_TRUE(back.ok()) << back.status();
    ASSERT_EQ(back->odometry.size(), g->odometry.size());
    ASSERT_EQ(back->bearing_range_measurements.size(), g->bearing_range_measurements.size());
    for (size_t e = 0; e < g->odometry.size(); ++e) {
      ASSERT_EQ(back->odometry[e].z.vector(), g->odometry[e].z.vector());
      const Eigen::Matrix3d& I = g->odometry[e].information;
      ASSERT_LE((back->odometry[e].information - I).cwiseAbs().maxCoeff(), 1e-12 * I.cwiseAbs().maxCoeff()) << e;
    }
    for (size_t e = 0; e < g->bearing_range_measurements.size(); ++e) {
      const BearingRangeMeasurement& m = g->bearing_range_measurements[e];
      ASSERT_EQ(back->bearing_range_measurements[e].bearing, m.bearing);
      ASSERT_EQ(back->bearing_range_measurements[e].range, m.range);
    }
  }
}

}  // namespace
}  // namespace subslam::posegraph
