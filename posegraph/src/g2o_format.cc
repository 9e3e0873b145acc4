// The g2o 2-D text format (graph_format.h): vertices with estimates, FIX, and the edges
// EDGE_SE2, EDGE_SE2_XY and EDGE_BEARING_SE2_XY with information matrices.
#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "graph_text.h"

namespace subslam::posegraph::internal {

absl::Status ParseG2oLine(GraphLine& line, NoiseConvention noise, PoseGraph* graph) {
  const absl::string_view tag = line.tag();
  if (tag == "VERTEX_SE2" || tag == "VERTEX_XY") {
    const bool pose = tag == "VERTEX_SE2";
    absl::Status s = pose ? line.Expect({"id", "x", "y", "theta"}) : line.Expect({"id", "x", "y"});
    if (!s.ok()) return s;
    return ParseVertexEstimate(line, pose, /*shared_ids=*/true, graph);
  }
  if (tag == "FIX") {
    if (line.size() == 0) return line.Error("missing field 'id' (field 1)");
    for (int f = 1; f <= line.size(); ++f) {
      auto id = line.Id(f);
      if (!id.ok()) return id.status();
      const int i = graph->FindPose(*id);
      if (i < 0) return line.Error(absl::StrCat("field ", f, ": no pose vertex ", *id, " before this line"));
      graph->poses[i].fixed = true;
    }
    return absl::OkStatus();
  }
  if (tag == "EDGE_SE2" || tag == "EDGE_SE2_XY" || tag == "EDGE_BEARING_SE2_XY") {
    absl::Status s;
    if (tag == "EDGE_SE2") {
      s = line.Expect({"from", "to", "dx", "dy", "dtheta", "I11", "I12", "I13", "I22", "I23", "I33"});
    } else if (tag == "EDGE_SE2_XY") {
      s = line.Expect({"pose", "point", "x", "y", "I11", "I12", "I22"});
    } else {
      s = line.Expect({"pose", "point", "bearing", "I"});
    }
    if (!s.ok()) return s;
    auto ids = line.EdgeIds();
    if (!ids.ok()) return ids.status();
    const auto [a, b] = *ids;
    // One id space: an edge's ends are two vertices. The first end is a pose, the second a
    // pose or a point: not an id of the other kind.
    if (a == b) return line.Error("an edge from a vertex to itself");
    if (graph->FindPoint(a) >= 0) return line.FieldError(1, absl::StrCat("names point ", a, ", not a pose"));
    const bool pose_pose = tag == "EDGE_SE2";
    if (pose_pose ? graph->FindPoint(b) >= 0 : graph->FindPose(b) >= 0) {
      return line.FieldError(
          2, absl::StrCat("names ", pose_pose ? "point " : "pose ", b, ", not a ", pose_pose ? "pose" : "point"));
    }
    if (pose_pose) {
      auto z = line.Numbers(3, 3);
      if (!z.ok()) return z.status();
      auto information = line.Information(6, 3, noise);
      if (!information.ok()) return information.status();
      graph->odometry.push_back(
          {graph->PoseIndex(a), graph->PoseIndex(b), Pose2((*z)[0], (*z)[1], (*z)[2]), *information});
    } else if (tag == "EDGE_SE2_XY") {
      auto z = line.Numbers(3, 2);
      if (!z.ok()) return z.status();
      auto information = line.Information(5, 2, noise);
      if (!information.ok()) return information.status();
      graph->point_measurements.push_back(
          {graph->PoseIndex(a), graph->PointIndex(b), Eigen::Vector2d((*z)[0], (*z)[1]), *information});
    } else {
      auto z = line.Number(3);
      if (!z.ok()) return z.status();
      auto information = line.Information(4, 1, noise);
      if (!information.ok()) return information.status();
      graph->bearing_measurements.push_back({graph->PoseIndex(a), graph->PointIndex(b), *z, (*information)(0, 0)});
    }
    return absl::OkStatus();
  }
  return line.Error(
      "unknown tag (2-D g2o reads VERTEX_SE2, VERTEX_XY, FIX, EDGE_SE2, EDGE_SE2_XY, EDGE_BEARING_SE2_XY)");
}

absl::StatusOr<std::string> FormatG2o(const PoseGraph& graph, NoiseConvention noise, bool bearing_range_as_points) {
  // Points take ids after the largest pose id when the two id spaces overlap.
  long offset = 0;
  for (const PointVertex& p : graph.points) {
    if (graph.FindPose(p.id) >= 0) {
      for (const PoseVertex& q : graph.poses) offset = std::max(offset, q.id + 1);
      break;
    }
  }
  std::string out;
  if (offset > 0) absl::StrAppend(&out, "# point ids are the graph's point ids + ", offset, "\n");
  if (!graph.bearing_range_measurements.empty()) {
    if (!bearing_range_as_points) {
      return absl::InvalidArgumentError("g2o has no bearing-range edge (write them as points, or use isam / gtsam)");
    }
    absl::StrAppend(&out,
                    "# bearing-range measurements written as EDGE_SE2_XY: the measured point, with the "
                    "covariance through the polar-to-Cartesian Jacobian at it\n");
  }
  for (const PoseVertex& p : graph.poses) {
    absl::StrAppend(&out, "VERTEX_SE2 ", p.id);
    AppendNumbers(&out, {p.estimate.x, p.estimate.y, p.estimate.theta});
    out += '\n';
  }
  for (const PointVertex& p : graph.points) {
    absl::StrAppend(&out, "VERTEX_XY ", p.id + offset);
    AppendNumbers(&out, {p.estimate.x(), p.estimate.y()});
    out += '\n';
  }
  for (const PoseVertex& p : graph.poses) {
    if (p.fixed) absl::StrAppend(&out, "FIX ", p.id, "\n");
  }
  for (const MeasurementRef& ref : WritingOrder(graph)) {
    switch (ref.kind) {
      case MeasurementRef::kOdometry: {
        const OdometryMeasurement& m = graph.odometry[ref.index];
        AppendMeasurementLine(&out, "EDGE_SE2", graph.poses[m.from].id, graph.poses[m.to].id, {m.z.x, m.z.y, m.z.theta},
                              m.information, noise);
        continue;
      }
      case MeasurementRef::kPoint: {
        const PointMeasurement& m = graph.point_measurements[ref.index];
        AppendMeasurementLine(&out, "EDGE_SE2_XY", graph.poses[m.pose].id, graph.points[m.point].id + offset,
                              {m.z.x(), m.z.y()}, m.information, noise);
        continue;
      }
      case MeasurementRef::kBearingRange: {
        const BearingRangeMeasurement& m = graph.bearing_range_measurements[ref.index];
        const double c = std::cos(m.bearing), s = std::sin(m.bearing);
        Eigen::Matrix2d J;  // d(x, y) / d(bearing, range)
        J << -m.range * s, c, m.range * c, s;
        const Eigen::Matrix2d covariance = J * m.information.inverse() * J.transpose();
        AppendMeasurementLine(&out, "EDGE_SE2_XY", graph.poses[m.pose].id, graph.points[m.point].id + offset,
                              {m.range * c, m.range * s}, covariance.inverse(), noise);
        continue;
      }
      case MeasurementRef::kBearing: {
        const BearingMeasurement& m = graph.bearing_measurements[ref.index];
        absl::StrAppend(&out, "EDGE_BEARING_SE2_XY ", graph.poses[m.pose].id, " ", graph.points[m.point].id + offset);
        AppendNumbers(&out, {m.bearing});
        AppendNumbers(&out, UpperTriangleFromInformation(Eigen::Matrix<double, 1, 1>(m.information), noise));
        break;
      }
    }
    out += '\n';
  }
  return out;
}

}  // namespace subslam::posegraph::internal
