// libFuzzer target for the graph-file readers (posegraph/graph_format.h): the first byte
// picks the format and the noise convention, the rest is the file's text. Whatever the
// text, ParseGraph must return a graph or an error (never crash, hang or read out of
// bounds); a graph it returns must be one that Validate(), EvaluateError() and
// FormatGraph() handle, and what FormatGraph() writes must read back with the same counts.
// Built and run by scripts/fuzz.sh (clang, -fsanitize=fuzzer,address,undefined).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "subslam/posegraph/graph_format.h"

namespace {

using subslam::posegraph::GraphFormat;
using subslam::posegraph::NoiseConvention;

void Require(bool condition) {
  if (!condition) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const GraphFormat formats[] = {GraphFormat::kG2o, GraphFormat::kToro, GraphFormat::kIsam, GraphFormat::kGtsam};
  const GraphFormat format = formats[data[0] % 4];
  std::optional<NoiseConvention> noise;
  switch ((data[0] / 4) % 4) {
    case 1:
      noise = NoiseConvention::kCovariance;
      break;
    case 2:
      noise = NoiseConvention::kInformation;
      break;
    case 3:
      noise = NoiseConvention::kSqrtInformation;
      break;
    default:
      break;
  }
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  auto graph = subslam::posegraph::ParseGraph(text, "fuzz", format, noise);
  if (!graph.ok()) {
    Require(!graph.status().message().empty());
    return 0;
  }
  (void)graph->Validate();
  (void)subslam::posegraph::EvaluateError(*graph);
  subslam::posegraph::GraphWriteOptions write;
  write.format = format;
  write.noise = noise;
  write.bearing_range_as_points = true;
  auto written = subslam::posegraph::FormatGraph(*graph, write);
  if (!written.ok()) return 0;  // what the format cannot hold (said in the error)
  auto back = subslam::posegraph::ParseGraph(*written, "fuzz (written)", format, noise);
  if (!back.ok()) {
    // Written information can lose definiteness only by rounding at the edge of what a
    // double holds; anything else is a writer bug.
    const std::string message(back.status().message());
    Require(message.find("not positive definite") != std::string::npos ||
            message.find("singular") != std::string::npos || message.find("not finite") != std::string::npos);
    return 0;
  }
  Require(back->poses.size() == graph->poses.size());
  Require(back->odometry.size() == graph->odometry.size());
  return 0;
}
