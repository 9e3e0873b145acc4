// The object behind subslam.Graph (bind_graph.cc), which subslam.solve takes too.
#ifndef SUBSLAM_PYTHON_GRAPH_H_
#define SUBSLAM_PYTHON_GRAPH_H_

#include <nlohmann/json.hpp>
#include <string>

#include "subslam/posegraph/graph_format.h"
#include "subslam/posegraph/pose_graph.h"

namespace subslam::python {

// A graph and what it was read from, which a solve's report records.
struct Graph {
  posegraph::PoseGraph graph;
  std::string path;
  posegraph::GraphFormat format = posegraph::GraphFormat::kG2o;
  posegraph::NoiseConvention noise = posegraph::NoiseConvention::kInformation;
  bool estimates_changed = false;  // with_estimates() gave it estimates of the caller's
};

// What a solve's report says the graph is (SolveOptions::source).
nlohmann::json GraphSource(const Graph& graph);

}  // namespace subslam::python

#endif  // SUBSLAM_PYTHON_GRAPH_H_
