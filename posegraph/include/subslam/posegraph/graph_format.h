// Reading and writing PoseGraphs in the field's standard 2-D graph files
// (docs/formats.md, "Graph files"). Every format states the convention of its noise
// numbers, which --noise overrides; nothing is guessed from the numbers.
//
//   format  lines                                                        noise numbers
//   g2o     VERTEX_SE2 id x y θ · VERTEX_XY id x y · FIX id…              information, upper
//           EDGE_SE2 i j dx dy dθ I11 I12 I13 I22 I23 I33                 triangle row by row
//           EDGE_SE2_XY i j x y I11 I12 I22 · EDGE_BEARING_SE2_XY i j b I
//   toro    VERTEX2 id x y θ                                              information, TORO's
//           EDGE2 i j dx dy dθ I11 I12 I22 I33 I13 I23                    order
//   isam    ODOMETRY i j dx dy dθ + 6 (EDGE2: the same)                   square-root
//           LANDMARK i j lx ly + 3 (a Cartesian sighting, robot frame)    information R (upper
//           BR i j bearing range σ_b σ_r (standard deviations always)     triangular, Ω = RᵀR)
//           POINT2 id x y · VERTEX2 id x y θ (estimates)
//   gtsam   the isam lines as GTSAM's load2D reads them: noise numbers     covariance, upper
//           are covariances, and each LANDMARK is a bearing-range          triangle row by row
//           measurement (b, r) of (lx, ly) with σ_b = √(c11/10), σ_r = √c11
//           (GTSAM's reading, defined for c11 = c22 only; GTSAM's own load2D
//           also takes |c11 − c22| < 10⁻⁴, ignores c12 and otherwise quietly uses
//           σ = 1 — here such a line is an error)
//
// Ids: g2o's vertices share one id space; in isam / gtsam files pose ids (ODOMETRY) and
// landmark ids (LANDMARK, BR) are separate. Lines starting with '#' and blank lines are
// skipped. Any other line — an unknown tag, a missing or extra field, a field that is not
// a number, an id of the wrong kind, noise that is not positive definite — is an error
// naming the file, line and field.
#ifndef SUBSLAM_POSEGRAPH_GRAPH_FORMAT_H_
#define SUBSLAM_POSEGRAPH_GRAPH_FORMAT_H_

#include <optional>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/posegraph/pose_graph.h"

namespace subslam::posegraph {

enum class GraphFormat { kG2o, kToro, kIsam, kGtsam };
const char* ToString(GraphFormat format);  // g2o, toro, isam, gtsam
absl::StatusOr<GraphFormat> GraphFormatFromString(const std::string& name);
// From the file name: .g2o → g2o, .graph / .toro → toro, .isam → isam; otherwise an
// error asking for --format (a .txt file may be iSAM's or GTSAM's).
absl::StatusOr<GraphFormat> GraphFormatFromPath(const std::string& path);

enum class NoiseConvention { kCovariance, kInformation, kSqrtInformation };
const char* ToString(NoiseConvention noise);  // covariance, information, sqrt-information
absl::StatusOr<NoiseConvention> NoiseConventionFromString(const std::string& name);
NoiseConvention DefaultNoise(GraphFormat format);

struct GraphReadOptions {
  std::optional<GraphFormat> format;     // default: GraphFormatFromPath
  std::optional<NoiseConvention> noise;  // default: DefaultNoise(format)
};

absl::StatusOr<PoseGraph> ReadGraph(const std::string& path, const GraphReadOptions& options = {});
// The same from text in memory (`source` names it in errors); the format is required.
absl::StatusOr<PoseGraph> ParseGraph(std::string_view text, const std::string& source, GraphFormat format,
                                     std::optional<NoiseConvention> noise = std::nullopt);

struct GraphWriteOptions {
  GraphFormat format = GraphFormat::kG2o;
  std::optional<NoiseConvention> noise;  // default: DefaultNoise(format)
  // g2o has no bearing-range edge: write each as a Cartesian sighting at the measured
  // point with the covariance carried through the polar-to-Cartesian Jacobian (a
  // linearisation, so not the same problem; a comment line in the file says so). false:
  // such a graph is an error for g2o.
  bool bearing_range_as_points = false;
};

// Writes the graph: the vertices — g2o and TORO declare every one (a vertex without an
// estimate at the origin), iSAM / GTSAM write VERTEX2 / POINT2 only for those with an
// estimate — then the measurements in time order (graph_text.h's writing order: the
// odometry into a pose, then the sightings from it). Numbers are written in the shortest form that reads back to the
// same double. Errors: what the format cannot hold (points in TORO; bearing-only or bearing-range measurements where it
// has no such line; GTSAM's reading, which is not invertible for measurements it did not produce) and an unwritable
// file.
absl::Status WriteGraph(const PoseGraph& graph, const std::string& path, const GraphWriteOptions& options);
absl::StatusOr<std::string> FormatGraph(const PoseGraph& graph, const GraphWriteOptions& options);

}  // namespace subslam::posegraph

#endif  // SUBSLAM_POSEGRAPH_GRAPH_FORMAT_H_
