// subslam.Dataset, read_dataset, simulate, scenarios: data sets as numpy arrays.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>
#include <utility>

#include "absl/strings/str_cat.h"
#include "bindings.h"
#include "command_flags.h"
#include "convert.h"
#include "flag_kwargs.h"
#include "subslam/io/calibration_fragment.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/io/dataset_writer.h"
#include "subslam/io/steps.h"
#include "subslam/sim/scenario.h"
#include "tool_jobs.h"

namespace py = pybind11;

namespace subslam::python {
namespace {

py::dict ControlArrays(const io::Dataset& d) {
  const size_t n = d.controls.size();
  py::dict out;
  out["t"] = ValueArray<double>(n, [&](size_t k) { return d.controls[k].t; });
  out["u"] = RowArray<2>(n, [&](size_t k) { return d.controls[k].u; });
  return out;
}

py::dict ScanArrays(const Scan& scan) {
  const std::vector<Detection>& z = scan.detections;
  py::dict out;
  out["t"] = scan.t;
  out["ranges"] = ValueArray<double>(z.size(), [&](size_t i) { return z[i].range_m; });
  out["bearings"] = ValueArray<double>(z.size(), [&](size_t i) { return z[i].bearing_rad; });
  out["signatures"] = ValueArray<double>(z.size(), [&](size_t i) { return z[i].signature; });
  out["truth_ids"] = ValueArray<long>(z.size(), [&](size_t i) { return z[i].truth_id; });
  return out;
}

py::dict StepArrays(const io::Dataset& d) {
  const std::vector<io::Step> steps = io::BuildSteps(d);
  const size_t n = steps.size();
  py::dict out;
  out["t"] = ValueArray<double>(n, [&](size_t k) { return steps[k].t; });
  out["dt"] = ValueArray<double>(n, [&](size_t k) { return steps[k].dt; });
  out["u"] = RowArray<2>(n, [&](size_t k) { return steps[k].control; });
  out["scan"] = ValueArray<long>(n, [&](size_t k) { return steps[k].scan_index; });
  return out;
}

py::dict TruthArrays(const io::Dataset& d) {
  const std::vector<io::TimedPose>& poses = d.truth_poses;
  const std::vector<io::TruthLandmark>& landmarks = d.truth_landmarks;
  py::dict trajectory, map, out;
  trajectory["t"] = ValueArray<double>(poses.size(), [&](size_t k) { return poses[k].t; });
  trajectory["poses"] = RowArray<3>(poses.size(), [&](size_t k) { return poses[k].pose.vector(); });
  map["ids"] = ValueArray<long>(landmarks.size(), [&](size_t k) { return landmarks[k].id; });
  map["positions"] = RowArray<2>(landmarks.size(), [&](size_t k) { return landmarks[k].p; });
  out["poses"] = trajectory;
  out["landmarks"] = map;
  return out;
}

py::dict GpsArrays(const io::Dataset& d) {
  py::dict out;
  out["t"] = ValueArray<double>(d.gps.size(), [&](size_t k) { return d.gps[k].t; });
  out["positions"] = RowArray<2>(d.gps.size(), [&](size_t k) { return d.gps[k].p; });
  return out;
}

py::dict ModelInfo(const io::Dataset& d) {
  py::dict motion, sensor, out;
  motion["model"] = io::ToString(d.motion.model);
  motion["sigma_v"] = d.motion.noise.sigma_u0;
  motion["sigma_u1"] = d.motion.noise.sigma_u1;
  motion["control_scale"] = std::vector<double>{d.motion.control_scale[0], d.motion.control_scale[1]};
  motion["control_offset"] = std::vector<double>{d.motion.control_offset[0], d.motion.control_offset[1]};
  const models::RangeBearingConfig& rb = d.sensor.range_bearing;
  sensor["sigma_range"] = rb.sigma_range_m;
  sensor["sigma_bearing"] = rb.sigma_bearing_rad;
  sensor["max_range"] = rb.max_range_m;
  sensor["has_signature"] = d.sensor.has_signature;
  sensor["has_truth_id"] = d.sensor.has_truth_id;
  out["motion"] = motion;
  out["sensor"] = sensor;
  return out;
}

// A simulated data set: the scenario's options as `subslam simulate`'s keywords. The data set
// is returned, not written (Dataset.write writes it).
std::shared_ptr<io::Dataset> Simulate(const std::string& scenario, const py::kwargs& kwargs) {
  for (const char* name : {"out", "quiet", "progress"}) {
    if (kwargs.contains(name)) {
      throw py::type_error(absl::StrCat("simulate() got an unexpected keyword argument '", name,
                                        "' (it returns the data set; Dataset.write writes it)"));
    }
  }
  py::kwargs all;
  for (const auto& [key, value] : kwargs) all[key] = value;
  all["scenario"] = scenario;
  tool::InputRequest input;
  {
    FlagScope flags("simulate", all);
    ThrowIfError(cli::CheckFlagsRead(
        {.command = "simulate", .frontend = std::nullopt, .backend = std::nullopt, .scenario = true}));
    input = ValueOrThrow(tool::InputRequestFromFlags("simulate", /*required=*/true));
  }
  py::gil_scoped_release unlocked;
  return std::make_shared<io::Dataset>(ValueOrThrow(tool::ReadInput(input)));
}

}  // namespace

void BindData(py::module_& m) {
  py::class_<io::Dataset, std::shared_ptr<io::Dataset>>(m, "Dataset", R"doc(
A data set: the robot's models, its controls and scans, and whatever ground truth it has.
Read one with read_dataset(), simulate one with simulate(). Arrays are copies; units are
metres, radians and seconds; poses are (x, y, θ) in the data set's world frame.)doc")
      .def_readonly("name", &io::Dataset::name)
      .def_readonly("directory", &io::Dataset::directory, "where it was read from; empty when simulated")
      .def_property_readonly("initial_pose", [](const io::Dataset& d) { return d.initial_pose.vector(); })
      .def_property_readonly("models", &ModelInfo, "the motion and sensor models' settings (a dict)")
      .def_property_readonly("controls", &ControlArrays, "{'t': (N,), 'u': (N, 2)} as recorded")
      .def_property_readonly("num_scans", [](const io::Dataset& d) { return d.scans.size(); })
      .def_property_readonly("num_detections", &io::Dataset::NumDetections)
      .def(
          "scan",
          [](const io::Dataset& d, long i) {
            if (i < 0 || i >= static_cast<long>(d.scans.size())) throw py::index_error("scan index out of range");
            return ScanArrays(d.scans[i]);
          },
          py::arg("index"),
          "{'t', 'ranges', 'bearings', 'signatures' (NaN: none), 'truth_ids' (-1 false alarm, -2 unknown)}")
      .def("steps", &StepArrays, R"doc(
The processing timeline: {'t', 'dt', 'u' (N, 2), 'scan'}. Step k predicts over dt with the
control u (the data set's control scale and offset applied), then updates with scan
`scan` (-1: none). Feed Slam.predict(u[k], dt[k]) and Slam.update(**dataset.scan(scan[k])).)doc")
      .def_property_readonly("truth", &TruthArrays, "{'poses': {'t', 'poses'}, 'landmarks': {'ids', 'positions'}}")
      .def_property_readonly("gps", &GpsArrays, "{'t', 'positions'} in the GPS's own frame")
      .def(
          "write",
          [](const io::Dataset& d, const std::string& directory) { ThrowIfError(io::WriteDataset(d, directory)); },
          py::arg("directory"), "writes dataset.json and its files (docs/formats.md)")
      .def("__repr__", [](const io::Dataset& d) {
        return "<subslam.Dataset '" + d.name + "': " + std::to_string(d.controls.size()) + " controls, " +
               std::to_string(d.scans.size()) + " scans, " + std::to_string(d.NumDetections()) + " detections>";
      });

  m.def(
      "read_dataset",
      [](const std::string& directory, const std::string& calibration) {
        py::gil_scoped_release unlocked;
        io::Dataset d = ValueOrThrow(io::ReadDataset(directory));
        if (!calibration.empty()) ThrowIfError(io::ApplyCalibrationFile(calibration, &d));
        return std::make_shared<io::Dataset>(std::move(d));
      },
      py::arg("directory"), py::arg("calibration") = "",
      "Reads a data-set directory (dataset.json and its files); `calibration`: a calibration.json "
      "whose values replace the manifest's (subslam calibrate).");
  m.def("simulate", &Simulate, py::arg("scenario"),
        "Simulates a scenario (scenarios() lists them) with the options of `subslam simulate` as "
        "keywords: seed=1, alpha=…, beta=…, duration=…, landmarks=…, …");
  m.def("scenarios", &sim::ScenarioNames, "The simulated scenarios' names.");
}

}  // namespace subslam::python
