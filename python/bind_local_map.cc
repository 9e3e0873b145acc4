// subslam.LocalMap, read_local_maps, write_local_maps: local maps as objects, so that a map
// made in Python (or by other software) can be joined.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <string>
#include <vector>

#include "bindings.h"
#include "convert.h"
#include "subslam/core/local_submap.h"
#include "subslam/io/submaps_jsonl.h"

namespace py = pybind11;

namespace subslam::python {
namespace {

LocalSubmap MakeLocalMap(int id, double t_start, double t_end, const py::handle& mean, const py::handle& covariance,
                         const std::vector<int>& feature_ids, const std::vector<double>& existence) {
  LocalSubmap s;
  s.id = id;
  s.t_start = t_start;
  s.t_end = t_end;
  const py::array_t<double> m = CheckedArray(mean, {-1}, "mean");
  const long n = static_cast<long>(m.shape(0));
  const py::array_t<double> c = CheckedArray(covariance, {n, n}, "covariance");
  if (n < 3 || (n - 3) % 2 != 0) {
    throw py::value_error("mean: expected 3 + 2n values (end pose x, y, θ, then each landmark's x, y)");
  }
  const long landmarks = (n - 3) / 2;
  if (!feature_ids.empty() && static_cast<long>(feature_ids.size()) != landmarks) {
    throw py::value_error("feature_ids: expected one id per landmark in the mean");
  }
  if (!existence.empty() && static_cast<long>(existence.size()) != landmarks) {
    throw py::value_error("existence: expected one value per landmark in the mean");
  }
  s.mean = Eigen::Map<const Eigen::VectorXd>(m.data(), n);
  s.covariance =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(c.data(), n, n);
  s.landmarks.resize(landmarks);
  for (long i = 0; i < landmarks; ++i) {
    s.landmarks[i].local_id = feature_ids.empty() ? static_cast<int>(i) : feature_ids[i];
    if (!existence.empty()) s.landmarks[i].existence = existence[i];
  }
  ThrowIfError(s.Validate());
  return s;
}

std::vector<int> FeatureIds(const LocalSubmap& s) {
  std::vector<int> ids;
  for (const LocalSubmapLandmark& l : s.landmarks) ids.push_back(l.local_id);
  return ids;
}

std::vector<double> Existence(const LocalSubmap& s) {
  std::vector<double> p;
  for (const LocalSubmapLandmark& l : s.landmarks) p.push_back(l.existence);
  return p;
}

// The features' true landmark ids (-1: false alarm or unknown), for evaluation.
std::vector<int> TruthIds(const LocalSubmap& s) {
  std::vector<int> ids;
  for (const LocalSubmapLandmark& l : s.landmarks) ids.push_back(l.truth_id.value_or(-1));
  return ids;
}

}  // namespace

void BindLocalMaps(py::module_& m) {
  py::class_<LocalSubmap>(m, "LocalMap", R"doc(
A local map reduced to one Gaussian, the unit a front-end hands to a back-end
(docs/conventions.md, "The submap factor"). The map starts at its anchor, the end of the
previous map (or the initial pose), with no uncertainty; `mean` = [end pose x, y, θ, then
each landmark's x, y], in the anchor's frame [m, rad], with its (3 + 2n)² covariance.)doc")
      .def(py::init(&MakeLocalMap), py::arg("id"), py::arg("t_start"), py::arg("t_end"), py::arg("mean"),
           py::arg("covariance"), py::arg("feature_ids") = std::vector<int>{},
           py::arg("existence") = std::vector<double>{},
           "Checked as a joiner checks it: sizes, finite values, a symmetric positive-definite covariance; "
           "feature ids default to 0..n-1, existence to 1.")
      .def_readonly("id", &LocalSubmap::id)
      .def_readonly("t_start", &LocalSubmap::t_start)
      .def_readonly("t_end", &LocalSubmap::t_end)
      .def_property_readonly("mean", [](const LocalSubmap& s) { return Eigen::VectorXd(s.mean); })
      .def_property_readonly("covariance", [](const LocalSubmap& s) { return Eigen::MatrixXd(s.covariance); })
      .def_property_readonly("end_pose", [](const LocalSubmap& s) { return Eigen::Vector3d(s.mean.head<3>()); })
      .def_property_readonly("num_landmarks", &LocalSubmap::num_landmarks)
      .def_property_readonly("feature_ids", &FeatureIds)
      .def_property_readonly("existence", &Existence)
      .def_property_readonly("truth_ids", &TruthIds, "each feature's true landmark id when known (-1: none)")
      .def("__repr__", [](const LocalSubmap& s) {
        return "<subslam.LocalMap " + std::to_string(s.id) + ": " + std::to_string(s.num_landmarks()) +
               " landmarks, t " + std::to_string(s.t_start) + " .. " + std::to_string(s.t_end) + " s>";
      });
  m.def(
      "read_local_maps",
      [](const std::string& path) {
        py::gil_scoped_release unlocked;
        return ValueOrThrow(io::ReadSubmapsJsonl(path));
      },
      py::arg("path"), "Reads recorded local maps (submaps.jsonl, docs/formats.md).");
  m.def(
      "write_local_maps",
      [](const std::string& path, const std::vector<LocalSubmap>& maps) {
        ThrowIfError(io::WriteSubmapsJsonl(path, maps));
      },
      py::arg("path"), py::arg("maps"), "Writes local maps as submaps.jsonl.");
}

}  // namespace subslam::python
