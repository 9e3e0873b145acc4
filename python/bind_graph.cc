// subslam.Graph, read_graph: the field's standard pose-landmark graphs, to solve in memory.
#include <pybind11/stl.h>

#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "bindings.h"
#include "convert.h"
#include "graph.h"
#include "subslam/posegraph/graph_format.h"
#include "subslam/posegraph/pose_graph.h"

namespace py = pybind11;

namespace subslam::python {

namespace {

py::dict PoseArrays(const posegraph::PoseGraph& g) {
  const std::vector<posegraph::PoseVertex>& v = g.poses;
  py::dict d;
  d["ids"] = ValueArray<long>(v.size(), [&](size_t k) { return v[k].id; });
  d["estimates"] = RowArray<3>(v.size(), [&](size_t k) { return v[k].estimate.vector(); });
  d["has_estimate"] = ValueArray<bool>(v.size(), [&](size_t k) { return v[k].has_estimate; });
  d["fixed"] = ValueArray<bool>(v.size(), [&](size_t k) { return v[k].fixed; });
  return d;
}

py::dict PointArrays(const posegraph::PoseGraph& g) {
  const std::vector<posegraph::PointVertex>& v = g.points;
  py::dict d;
  d["ids"] = ValueArray<long>(v.size(), [&](size_t k) { return v[k].id; });
  d["estimates"] = RowArray<2>(v.size(), [&](size_t k) { return v[k].estimate; });
  d["has_estimate"] = ValueArray<bool>(v.size(), [&](size_t k) { return v[k].has_estimate; });
  return d;
}

std::shared_ptr<Graph> ReadGraph(const std::string& path, const std::string& format, const std::string& noise) {
  posegraph::GraphReadOptions read;
  read.format =
      ValueOrThrow(format.empty() ? posegraph::GraphFormatFromPath(path) : posegraph::GraphFormatFromString(format));
  if (!noise.empty()) read.noise = ValueOrThrow(posegraph::NoiseConventionFromString(noise));
  auto g = std::make_shared<Graph>();
  g->path = path;
  g->format = *read.format;
  g->noise = read.noise.value_or(posegraph::DefaultNoise(*read.format));
  py::gil_scoped_release unlocked;
  g->graph = ValueOrThrow(posegraph::ReadGraph(path, read));
  return g;
}

// A copy with the given estimates (every pose's, every point's; None: keep the graph's).
std::shared_ptr<Graph> WithEstimates(const Graph& g, const py::object& poses, const py::object& points) {
  auto copy = std::make_shared<Graph>(g);
  copy->estimates_changed = true;
  if (!poses.is_none()) {
    const auto p = CheckedArray(poses, {static_cast<long>(g.graph.poses.size()), 3}, "poses");
    for (size_t k = 0; k < g.graph.poses.size(); ++k) {
      copy->graph.poses[k].estimate = Pose2(p.at(k, 0), p.at(k, 1), WrapAngle(p.at(k, 2)));
      copy->graph.poses[k].has_estimate = true;
    }
  }
  if (!points.is_none()) {
    const auto p = CheckedArray(points, {static_cast<long>(g.graph.points.size()), 2}, "points");
    for (size_t k = 0; k < g.graph.points.size(); ++k) {
      copy->graph.points[k].estimate = {p.at(k, 0), p.at(k, 1)};
      copy->graph.points[k].has_estimate = true;
    }
  }
  ThrowIfError(copy->graph.Validate());
  return copy;
}

}  // namespace

nlohmann::json GraphSource(const Graph& g) {
  return {{"file", g.path},
          {"format", posegraph::ToString(g.format)},
          {"noise", posegraph::ToString(g.noise)},
          {"estimates", g.estimates_changed ? "given from Python" : "the file's"}};
}

void BindGraphs(py::module_& m) {
  py::class_<Graph, std::shared_ptr<Graph>>(m, "Graph", R"doc(
A 2-D pose-landmark graph as the field's files hold it (g2o, TORO, iSAM, GTSAM): poses
(x, y, θ) and points (x, y) in one world frame, with measurements of known association.
solve() takes one in place of a file; with_estimates() gives one your own start.)doc")
      .def_property_readonly(
          "poses", [](const Graph& g) { return PoseArrays(g.graph); },
          "{'ids', 'estimates' (N, 3), 'has_estimate', 'fixed'}")
      .def_property_readonly(
          "points", [](const Graph& g) { return PointArrays(g.graph); }, "{'ids', 'estimates' (M, 2), 'has_estimate'}")
      .def_property_readonly("num_measurements", [](const Graph& g) { return g.graph.num_measurements(); })
      .def(
          "error",
          [](const Graph& g) {
            const posegraph::GraphError e = posegraph::EvaluateError(g.graph);
            return py::make_tuple(e.error, e.chi2);
          },
          "(½ Σ rᵀΩr, Σ rᵀΩr) at the graph's estimates")
      .def("with_estimates", &WithEstimates, py::arg("poses") = py::none(), py::arg("points") = py::none(),
           "A copy whose poses (N, 3) and/or points (M, 2) start from these estimates (solve with initial='file').")
      .def(
          "write",
          [](const Graph& g, const std::string& path, const std::string& format) {
            posegraph::GraphWriteOptions options;
            options.format = ValueOrThrow(posegraph::GraphFormatFromString(format));
            ThrowIfError(posegraph::WriteGraph(g.graph, path, options));
          },
          py::arg("path"), py::arg("format") = "g2o")
      .def("__repr__", [](const Graph& g) {
        return "<subslam.Graph " + g.path + ": " + std::to_string(g.graph.poses.size()) + " poses, " +
               std::to_string(g.graph.points.size()) + " points, " + std::to_string(g.graph.num_measurements()) +
               " measurements>";
      });
  m.def("read_graph", &ReadGraph, py::arg("path"), py::arg("format") = "", py::arg("noise") = "",
        "Reads a graph file; format: g2o, toro, isam or gtsam (default: from the file name); noise: "
        "covariance, information or sqrt-information (default: the format's).");
}

}  // namespace subslam::python
