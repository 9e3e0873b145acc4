// TORO's 2-D text format (graph_format.h): VERTEX2 and EDGE2, whose information entries
// come in TORO's order I11 I12 I22 I33 I13 I23. TORO holds poses only.
#include "absl/strings/str_cat.h"
#include "graph_text.h"

namespace subslam::posegraph::internal {
namespace {

// TORO's order of the six information entries, as indices into the upper triangle row
// by row (I11 I12 I13 I22 I23 I33).
constexpr std::array<int, 6> kToroToUpper = {0, 1, 3, 5, 2, 4};

}  // namespace

absl::Status ParseToroLine(GraphLine& line, NoiseConvention noise, PoseGraph* graph) {
  const absl::string_view tag = line.tag();
  if (tag == "VERTEX2") {
    if (absl::Status s = line.Expect({"id", "x", "y", "theta"}); !s.ok()) return s;
    return ParseVertexEstimate(line, /*pose=*/true, /*shared_ids=*/false, graph);
  }
  if (tag == "EDGE2") {
    return ParseOdometryLine(line, {"I11", "I12", "I22", "I33", "I13", "I23"}, kToroToUpper, noise, graph);
  }
  return line.Error("unknown tag (TORO reads VERTEX2 and EDGE2)");
}

absl::StatusOr<std::string> FormatToro(const PoseGraph& graph, NoiseConvention noise) {
  if (!graph.points.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("TORO holds poses only; the graph has ", graph.points.size(), " points (use g2o or isam)"));
  }
  std::string out;
  for (const PoseVertex& p : graph.poses) {
    absl::StrAppend(&out, "VERTEX2 ", p.id);
    AppendNumbers(&out, {p.estimate.x, p.estimate.y, p.estimate.theta});
    out += '\n';
  }
  for (const OdometryMeasurement& m : graph.odometry) {
    absl::StrAppend(&out, "EDGE2 ", graph.poses[m.from].id, " ", graph.poses[m.to].id);
    AppendNumbers(&out, {m.z.x, m.z.y, m.z.theta});
    const std::vector<double> upper = UpperTriangleFromInformation(m.information, noise);
    for (int k : kToroToUpper) AppendNumbers(&out, {upper[k]});
    out += '\n';
  }
  return out;
}

}  // namespace subslam::posegraph::internal
