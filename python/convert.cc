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
  const size_t n = trajectory.size();
  py::dict d;
  d["t"] = ValueArray<double>(n, [&](size_t k) { return trajectory[k].t; });
  d["poses"] = RowArray<3>(n, [&](size_t k) { return trajectory[k].pose.vector(); });
  d["covariances"] = MatrixArray<3>(n, [&](size_t k) { return trajectory[k].covariance; });
  return d;
}

py::dict LandmarkArrays(const std::vector<LandmarkEstimate>& landmarks) {
  const size_t n = landmarks.size();
  py::dict d;
  d["ids"] = ValueArray<long>(n, [&](size_t k) { return landmarks[k].id; });
  d["positions"] = RowArray<2>(n, [&](size_t k) { return landmarks[k].position; });
  d["covariances"] = MatrixArray<2>(n, [&](size_t k) { return landmarks[k].covariance; });
  return d;
}

py::object JsonToPython(const nlohmann::json& value) { return py::module_::import("json").attr("loads")(value.dump()); }

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
    throw py::value_error(
        absl::StrCat(what, ": expected shape (", absl::StrJoin(want, ", "), "), got (", absl::StrJoin(got, ", "), ")"));
  }
  return array;
}

}  // namespace subslam::python
