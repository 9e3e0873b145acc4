// What the bindings share: absl::Status as a Python exception, and the library's estimates
// as numpy arrays (poses N×3 as x [m], y [m], θ [rad]; covariances N×3×3 or N×2×2; times in
// seconds). Arrays are copies: Python owns them.
#ifndef SUBSLAM_PYTHON_CONVERT_H_
#define SUBSLAM_PYTHON_CONVERT_H_

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/core/estimates.h"

namespace subslam::python {

// Raises the status as ValueError (invalid argument, out of range), FileNotFoundError (not
// found) or RuntimeError (anything else), its message unchanged (file:line: field). It
// touches no Python object, so it may be called with the GIL released.
void ThrowIfError(const absl::Status& status);
// The C++ exception behind FileNotFoundError (RegisterExceptions translates it).
class FileNotFound : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
void RegisterExceptions();
template <typename T>
T ValueOrThrow(absl::StatusOr<T> value) {
  ThrowIfError(value.status());
  return *std::move(value);
}

// An (n,) array whose element k is value(k).
template <typename T, typename Value>
pybind11::array_t<T> ValueArray(size_t n, Value value) {
  pybind11::array_t<T> array(static_cast<pybind11::ssize_t>(n));
  auto a = array.template mutable_unchecked<1>();
  for (size_t k = 0; k < n; ++k) a(k) = static_cast<T>(value(k));
  return array;
}

// An (n, Cols) array whose row k is row(k), an Eigen vector of Cols values.
template <int Cols, typename Row>
pybind11::array_t<double> RowArray(size_t n, Row row) {
  pybind11::array_t<double> array({static_cast<pybind11::ssize_t>(n), pybind11::ssize_t{Cols}});
  auto a = array.mutable_unchecked<2>();
  for (size_t k = 0; k < n; ++k) {
    const Eigen::Matrix<double, Cols, 1> r = row(k);
    for (int i = 0; i < Cols; ++i) a(k, i) = r[i];
  }
  return array;
}

// An (n, Dim, Dim) array whose matrix k is matrix(k), an Eigen Dim × Dim matrix.
template <int Dim, typename Matrix>
pybind11::array_t<double> MatrixArray(size_t n, Matrix matrix) {
  pybind11::array_t<double> array({static_cast<pybind11::ssize_t>(n), pybind11::ssize_t{Dim}, pybind11::ssize_t{Dim}});
  auto a = array.mutable_unchecked<3>();
  for (size_t k = 0; k < n; ++k) {
    const Eigen::Matrix<double, Dim, Dim> m = matrix(k);
    for (int i = 0; i < Dim; ++i) {
      for (int j = 0; j < Dim; ++j) a(k, i, j) = m(i, j);
    }
  }
  return array;
}

// {"t": (N,), "poses": (N, 3), "covariances": (N, 3, 3)}.
pybind11::dict TrajectoryArrays(const Trajectory& trajectory);
// {"ids": (N,), "positions": (N, 2), "covariances": (N, 2, 2)}.
pybind11::dict LandmarkArrays(const std::vector<LandmarkEstimate>& landmarks);
// A JSON value as Python objects (dict, list, float, …).
pybind11::object JsonToPython(const nlohmann::json& value);

// An array of shape `shape` (−1: any length), as doubles; ValueError naming `what` otherwise.
pybind11::array_t<double> CheckedArray(const pybind11::handle& value, const std::vector<long>& shape,
                                       const std::string& what);

}  // namespace subslam::python

#endif  // SUBSLAM_PYTHON_CONVERT_H_
