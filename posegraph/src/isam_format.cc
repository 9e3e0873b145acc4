// The iSAM / GTSAM text format (graph_format.h): ODOMETRY / EDGE2, LANDMARK, BR, and the
// estimate lines VERTEX2 and POINT2; read either with the file's own meaning (a LANDMARK
// is a Cartesian sighting) or as GTSAM's load2D reads it (a bearing-range measurement).
#include <cmath>

#include "absl/strings/str_cat.h"
#include "graph_text.h"

namespace subslam::posegraph::internal {
namespace {

// GTSAM's bearing-range reading of a LANDMARK's covariance c11 c12 c22: the Cartesian
// noise taken as that of a point 10 m away, σ_b = √(c11 / 10) rad, σ_r = √c11 m.
constexpr double kGtsamLandmarkRange = 10.0;

}  // namespace

absl::Status ParseIsamLine(GraphLine& line, NoiseConvention noise, bool gtsam_landmarks, PoseGraph* graph) {
  const absl::string_view tag = line.tag();
  if (tag == "VERTEX2" || tag == "POINT2") {
    const bool pose = tag == "VERTEX2";
    absl::Status s = pose ? line.Expect({"id", "x", "y", "theta"}) : line.Expect({"id", "x", "y"});
    if (!s.ok()) return s;
    return ParseVertexEstimate(line, pose, /*shared_ids=*/false, graph);
  }
  if (tag == "ODOMETRY" || tag == "EDGE2") {
    return ParseOdometryLine(line, {"n11", "n12", "n13", "n22", "n23", "n33"}, {0, 1, 2, 3, 4, 5}, noise, graph);
  }
  if (tag == "LANDMARK") {
    if (absl::Status s = line.Expect({"pose", "landmark", "lx", "ly", "n11", "n12", "n22"}); !s.ok()) return s;
    auto ids = line.EdgeIds();
    if (!ids.ok()) return ids.status();
    const auto [a, b] = *ids;
    auto z = line.Numbers(3, 2);
    if (!z.ok()) return z.status();
    auto upper = line.Numbers(5, 3);
    if (!upper.ok()) return upper.status();
    if (gtsam_landmarks) {
      const double c11 = (*upper)[0], c12 = (*upper)[1], c22 = (*upper)[2];
      if (!(c11 > 0.0) || c12 != 0.0 || std::abs(c11 - c22) > 1e-9 * c11) {
        return line.Error(
            absl::StrCat("GTSAM's bearing-range reading needs a covariance c·I (c11 = c22 > 0, c12 = 0); "
                         "found ",
                         c11, " ", c12, " ", c22));
      }
      const double range = std::hypot((*z)[0], (*z)[1]);
      if (!(range > 0.0)) return line.Error("a landmark at the pose itself has no bearing");
      Eigen::Matrix2d information = Eigen::Matrix2d::Zero();
      information(0, 0) = kGtsamLandmarkRange / c11;
      information(1, 1) = 1.0 / c11;
      if (!information.allFinite()) return line.Error("noise: c11 so small that its information is not finite");
      graph->bearing_range_measurements.push_back(
          {graph->PoseIndex(a), graph->PointIndex(b), std::atan2((*z)[1], (*z)[0]), range, information});
      return absl::OkStatus();
    }
    auto information = line.Information(5, 2, noise);
    if (!information.ok()) return information.status();
    graph->point_measurements.push_back(
        {graph->PoseIndex(a), graph->PointIndex(b), Eigen::Vector2d((*z)[0], (*z)[1]), *information});
    return absl::OkStatus();
  }
  if (tag == "BR") {
    if (absl::Status s = line.Expect({"pose", "landmark", "bearing", "range", "sigma_bearing", "sigma_range"});
        !s.ok()) {
      return s;
    }
    auto ids = line.EdgeIds();
    if (!ids.ok()) return ids.status();
    const auto [a, b] = *ids;
    auto v = line.Numbers(3, 4);
    if (!v.ok()) return v.status();
    if (!((*v)[1] > 0.0)) return line.FieldError(4, "is not positive");
    if (!((*v)[2] > 0.0)) return line.FieldError(5, "is not positive");
    if (!((*v)[3] > 0.0)) return line.FieldError(6, "is not positive");
    Eigen::Matrix2d information = Eigen::Matrix2d::Zero();
    information(0, 0) = 1.0 / ((*v)[2] * (*v)[2]);
    information(1, 1) = 1.0 / ((*v)[3] * (*v)[3]);
    if (!information.allFinite()) {
      return line.Error("noise: a standard deviation so small that its information 1/σ² is not finite");
    }
    graph->bearing_range_measurements.push_back(
        {graph->PoseIndex(a), graph->PointIndex(b), (*v)[0], (*v)[1], information});
    return absl::OkStatus();
  }
  return line.Error("unknown tag (the iSAM / GTSAM format reads ODOMETRY, EDGE2, LANDMARK, BR, VERTEX2, POINT2)");
}

absl::StatusOr<std::string> FormatIsam(const PoseGraph& graph, NoiseConvention noise, bool gtsam_landmarks) {
  if (!graph.bearing_measurements.empty()) {
    return absl::InvalidArgumentError("the iSAM / GTSAM format has no bearing-only line (use g2o)");
  }
  if (gtsam_landmarks && !graph.point_measurements.empty()) {
    return absl::InvalidArgumentError(
        "GTSAM reads every LANDMARK line as bearing-range, so Cartesian sightings cannot be written for it (use isam)");
  }
  std::string out;
  for (const PoseVertex& p : graph.poses) {
    if (!p.has_estimate) continue;
    absl::StrAppend(&out, "VERTEX2 ", p.id);
    AppendNumbers(&out, {p.estimate.x, p.estimate.y, p.estimate.theta});
    out += '\n';
  }
  for (const PointVertex& p : graph.points) {
    if (!p.has_estimate) continue;
    absl::StrAppend(&out, "POINT2 ", p.id);
    AppendNumbers(&out, {p.estimate.x(), p.estimate.y()});
    out += '\n';
  }
  for (const MeasurementRef& ref : WritingOrder(graph)) {
    switch (ref.kind) {
      case MeasurementRef::kOdometry: {
        const OdometryMeasurement& m = graph.odometry[ref.index];
        AppendMeasurementLine(&out, "ODOMETRY", graph.poses[m.from].id, graph.poses[m.to].id, {m.z.x, m.z.y, m.z.theta},
                              m.information, noise);
        continue;
      }
      case MeasurementRef::kPoint: {
        const PointMeasurement& m = graph.point_measurements[ref.index];
        AppendMeasurementLine(&out, "LANDMARK", graph.poses[m.pose].id, graph.points[m.point].id, {m.z.x(), m.z.y()},
                              m.information, noise);
        continue;
      }
      case MeasurementRef::kBearingRange: {
        const BearingRangeMeasurement& m = graph.bearing_range_measurements[ref.index];
        const Eigen::Matrix2d& I = m.information;
        if (I(0, 1) != 0.0) {
          return absl::InvalidArgumentError(
              absl::StrCat("bearing-range measurement ", graph.poses[m.pose].id, " -> ", graph.points[m.point].id,
                           ": correlated bearing and range noise has no line in this format"));
        }
        const double c = 1.0 / I(1, 1);  // range variance
        if (gtsam_landmarks && std::abs(I(0, 0) - kGtsamLandmarkRange * I(1, 1)) <= 1e-12 * I(0, 0)) {
          absl::StrAppend(&out, "LANDMARK ", graph.poses[m.pose].id, " ", graph.points[m.point].id);
          AppendNumbers(&out, {m.range * std::cos(m.bearing), m.range * std::sin(m.bearing), c, 0.0, c});
        } else {
          absl::StrAppend(&out, "BR ", graph.poses[m.pose].id, " ", graph.points[m.point].id);
          AppendNumbers(&out, {m.bearing, m.range, 1.0 / std::sqrt(I(0, 0)), std::sqrt(c)});
        }
        break;
      }
      case MeasurementRef::kBearing:
        break;  // refused above
    }
    out += '\n';
  }
  return out;
}

}  // namespace subslam::posegraph::internal
