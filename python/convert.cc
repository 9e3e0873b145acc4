#include "convert.h"

#include <Python.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace py = pybind11;

namespace subslam::python {

void ThrowIfError(const absl::Status& status) {
  if (status.ok()) return;
  const std::string message(status.message());
  switch (status.code()) {
    case absl::StatusCode::kInvalidArgument:
    case absl::StatusCode::kOutOfRange:
    case absl::StatusCode::kFailedPrecondition:
      throw py::value_error(message);
    case absl::StatusCode::kNotFound:
      throw FileNotFound(message);
    default:
      throw std::runtime_error(message);
  }
}

void RegisterExceptions() {
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const FileNotFound& e) {
      PyErr_SetString(PyExc_FileNotFoundError, e.what());
    }
  });
}

py::dict TrajectoryArrays(const Trajectory& trajectory) {
  const auto n = static_cast<py::ssize_t>(trajectory.size());
  py::array_t<double> t(n), poses({n, py::ssize_t{3}}), covariances({n, py::ssize_t{3}, py::ssize_t{3}});
  auto tt = t.mutable_unchecked<1>();
  auto pp = poses.mutable_unchecked<2>();
  auto cc = covariances.mutable_unchecked<3>();
  for (py::ssize_t k = 0; k < n; ++k) {
    const PoseEstimate& e = trajectory[k];
    tt(k) = e.t;
    pp(k, 0) = e.pose.x;
    pp(k, 1) = e.pose.y;
    pp(k, 2) = e.pose.theta;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) cc(k, i, j) = e.covariance(i, j);
    }
  }
  py::dict d;
  d["t"] = t;
  d["poses"] = poses;
  d["covariances"] = covariances;
  return d;
}

py::dict LandmarkArrays(const std::vector<LandmarkEstimate>& landmarks) {
  const auto n = static_cast<py::ssize_t>(landmarks.size());
  py::array_t<long> ids(n);
  py::array_t<double> positions({n, py::ssize_t{2}}), covariances({n, py::ssize_t{2}, py::ssize_t{2}});
  auto ii = ids.mutable_unchecked<1>();
  auto pp = positions.mutable_unchecked<2>();
  auto cc = covariances.mutable_unchecked<3>();
  for (py::ssize_t k = 0; k < n; ++k) {
    const LandmarkEstimate& l = landmarks[k];
    ii(k) = l.id;
    for (int i = 0; i < 2; ++i) {
      pp(k, i) = l.position[i];
      for (int j = 0; j < 2; ++j) cc(k, i, j) = l.covariance(i, j);
    }
  }
  py::dict d;
  d["ids"] = ids;
  d["positions"] = positions;
  d["covariances"] = covariances;
  return d;
}

py::object JsonToPython(const nlohmann::json& value) {
  return py::module_::import("json").attr("loads")(value.dump());
}

py::array_t<double> CheckedArray(const py::handle& value, const std::vector<long>& shape, const std::string& what) {
  py::array_t<double> array;
  try {
    array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
  } catch (const py::error_already_set&) {
  }
  if (!array) throw py::type_error(absl::StrCat(what, ": expected an array of numbers"));
  bool fits = array.ndim() == static_cast<py::ssize_t>(shape.size());
  for (size_t i = 0; fits && i < shape.size(); ++i) fits = shape[i] < 0 || array.shape(i) == shape[i];
  if (!fits) {
    std::vector<std::string> want, got;
    for (long s : shape) want.push_back(s < 0 ? "N" : absl::StrCat(s));
    for (py::ssize_t i = 0; i < array.ndim(); ++i) got.push_back(absl::StrCat(array.shape(i)));
    throw py::value_error(absl::StrCat(what, ": expected shape (", absl::StrJoin(want, ", "), "), got (",
                                       absl::StrJoin(got, ", "), ")"));
  }
  return array;
}

}  // namespace subslam::python
