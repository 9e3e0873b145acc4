#include "subslam/posegraph/graph_format.h"

#include <filesystem>
#include <fstream>

#include "absl/strings/str_cat.h"
#include "graph_text.h"
#include "subslam/io/text_table.h"

namespace subslam::posegraph {

const char* ToString(GraphFormat format) {
  switch (format) {
    case GraphFormat::kG2o:
      return "g2o";
    case GraphFormat::kToro:
      return "toro";
    case GraphFormat::kIsam:
      return "isam";
    case GraphFormat::kGtsam:
      return "gtsam";
  }
  return "?";
}

absl::StatusOr<GraphFormat> GraphFormatFromString(const std::string& name) {
  for (GraphFormat f : {GraphFormat::kG2o, GraphFormat::kToro, GraphFormat::kIsam, GraphFormat::kGtsam}) {
    if (name == ToString(f)) return f;
  }
  return absl::InvalidArgumentError(absl::StrCat("unknown graph format \"", name, "\" (g2o, toro, isam, gtsam)"));
}

absl::StatusOr<GraphFormat> GraphFormatFromPath(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".g2o") return GraphFormat::kG2o;
  if (ext == ".graph" || ext == ".toro") return GraphFormat::kToro;
  if (ext == ".isam") return GraphFormat::kIsam;
  return absl::InvalidArgumentError(absl::StrCat(
      path,
      ": the graph format cannot be told from the name; give --format g2o, toro, isam or gtsam (a .txt file "
      "may be iSAM's, whose noise is square-root information, or GTSAM's, whose noise is covariance)"));
}

const char* ToString(NoiseConvention noise) {
  switch (noise) {
    case NoiseConvention::kCovariance:
      return "covariance";
    case NoiseConvention::kInformation:
      return "information";
    case NoiseConvention::kSqrtInformation:
      return "sqrt-information";
  }
  return "?";
}

absl::StatusOr<NoiseConvention> NoiseConventionFromString(const std::string& name) {
  for (NoiseConvention n :
       {NoiseConvention::kCovariance, NoiseConvention::kInformation, NoiseConvention::kSqrtInformation}) {
    if (name == ToString(n)) return n;
  }
  return absl::InvalidArgumentError(
      absl::StrCat("unknown noise convention \"", name, "\" (covariance, information, sqrt-information)"));
}

NoiseConvention DefaultNoise(GraphFormat format) {
  switch (format) {
    case GraphFormat::kG2o:
    case GraphFormat::kToro:
      return NoiseConvention::kInformation;
    case GraphFormat::kIsam:
      return NoiseConvention::kSqrtInformation;
    case GraphFormat::kGtsam:
      return NoiseConvention::kCovariance;
  }
  return NoiseConvention::kInformation;
}

absl::StatusOr<PoseGraph> ParseGraph(std::string_view text, const std::string& source, GraphFormat format,
                                     std::optional<NoiseConvention> noise) {
  const NoiseConvention convention = noise.value_or(DefaultNoise(format));
  PoseGraph graph;
  const absl::Status status =
      internal::ForEachLine(absl::string_view(text.data(), text.size()), source, [&](internal::GraphLine& line) {
        switch (format) {
          case GraphFormat::kG2o:
            return internal::ParseG2oLine(line, convention, &graph);
          case GraphFormat::kToro:
            return internal::ParseToroLine(line, convention, &graph);
          case GraphFormat::kIsam:
            return internal::ParseIsamLine(line, convention, /*gtsam_landmarks=*/false, &graph);
          case GraphFormat::kGtsam:
            return internal::ParseIsamLine(line, convention, /*gtsam_landmarks=*/true, &graph);
        }
        return absl::InternalError("unknown format");
      });
  if (!status.ok()) return status;
  if (graph.poses.empty()) return absl::InvalidArgumentError(absl::StrCat(source, ": the graph has no pose"));
  return graph;
}

absl::StatusOr<PoseGraph> ReadGraph(const std::string& path, const GraphReadOptions& options) {
  absl::StatusOr<GraphFormat> format = options.format.has_value() ? *options.format : GraphFormatFromPath(path);
  if (!format.ok()) return format.status();
  absl::StatusOr<std::string> text = subslam::io::ReadFileToString(path);
  if (!text.ok()) return text.status();
  return ParseGraph(*text, path, *format, options.noise);
}

absl::StatusOr<std::string> FormatGraph(const PoseGraph& graph, const GraphWriteOptions& options) {
  const NoiseConvention noise = options.noise.value_or(DefaultNoise(options.format));
  switch (options.format) {
    case GraphFormat::kG2o:
      return internal::FormatG2o(graph, noise, options.bearing_range_as_points);
    case GraphFormat::kToro:
      return internal::FormatToro(graph, noise);
    case GraphFormat::kIsam:
      return internal::FormatIsam(graph, noise, /*gtsam_landmarks=*/false);
    case GraphFormat::kGtsam:
      return internal::FormatIsam(graph, noise, /*gtsam_landmarks=*/true);
  }
  return absl::InternalError("unknown format");
}

absl::Status WriteGraph(const PoseGraph& graph, const std::string& path, const GraphWriteOptions& options) {
  absl::StatusOr<std::string> text = FormatGraph(graph, options);
  if (!text.ok()) return text.status();
  std::ofstream out(path, std::ios::binary);
  if (!out) return absl::PermissionDeniedError(absl::StrCat(path, ": cannot open for writing"));
  out << *text;
  out.close();
  if (!out) return absl::DataLossError(absl::StrCat(path, ": write failed"));
  return absl::OkStatus();
}

}  // namespace subslam::posegraph
