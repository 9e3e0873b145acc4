// What the data-set fuzz targets share: a small valid data set's text files in memory
// (under the directory "fuzz"), reading a data set from such files, and the invariants
// the estimators rely on (docs/formats.md, "Data-set directory"), checked on every data
// set the reader accepts, before and after the input rules.
#ifndef SUBSLAM_FUZZ_DATASET_FUZZ_H_
#define SUBSLAM_FUZZ_DATASET_FUZZ_H_

#include <cmath>
#include <cstdlib>
#include <map>
#include <string>

#include "absl/strings/str_cat.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/io/input_screening.h"
#include "subslam/io/steps.h"

namespace subslam::fuzz {

inline void Require(bool condition) {
  if (!condition) std::abort();
}

inline void CheckAcceptedDataset(const io::Dataset& d) {
  Require(d.initial_pose.vector().allFinite() && std::abs(d.initial_pose.theta) <= M_PI);
  Require(d.sensor.range_bearing.Validate().ok());
  for (size_t k = 1; k < d.controls.size(); ++k) Require(d.controls[k].t > d.controls[k - 1].t);
  for (size_t k = 0; k < d.scans.size(); ++k) {
    Require(!d.scans[k].detections.empty());
    if (k > 0) Require(d.scans[k].t > d.scans[k - 1].t);
    for (const Detection& det : d.scans[k].detections) {
      Require(std::isfinite(det.range_m) && det.range_m > 0.0);
      Require(std::isfinite(det.bearing_rad) && std::abs(det.bearing_rad) <= M_PI);
    }
  }
  for (size_t k = 1; k < d.truth_poses.size(); ++k) Require(d.truth_poses[k].t > d.truth_poses[k - 1].t);
  double t_prev = -INFINITY;
  for (const io::Step& step : io::BuildSteps(d)) {
    Require(std::isfinite(step.t) && step.t >= t_prev && step.dt >= 0.0 && std::isfinite(step.dt));
    Require(step.control.allFinite());
    t_prev = step.t;
  }
}

// The text files of a small valid data set, by path.
inline std::map<std::string, std::string> ValidTextFiles() {
  return {{"fuzz/controls.dat", "0 1.0 0.1\n0.1 1.0 0.1\n0.2 1.2 -0.2\n"},
          {"fuzz/observations.dat", "0.1 5.0 0.3 1 7\n0.1 6.0 -0.3 2 7\n0.2 4.0 3.0 -1 1\n"},
          {"fuzz/gps.dat", "0 0 0\n0.2 0.2 0.01\n"},
          {"fuzz/truth_poses.dat", "0 0 0 0\n0.1 0.1 0 0.01\n"},
          {"fuzz/truth_landmarks.dat", "1 4 2\n2 5 -2\n"}};
}

// Reads the data set "fuzz" from `files` (fuzz/dataset.json among them): an error must
// say something, and an accepted data set must hold the invariants above.
inline void ReadAndCheck(const std::map<std::string, std::string>& files) {
  const io::FileReader read = [&files](const std::string& path) -> absl::StatusOr<std::string> {
    const auto it = files.find(path);
    if (it == files.end()) return absl::NotFoundError(absl::StrCat(path, ": cannot open file"));
    return it->second;
  };
  absl::StatusOr<io::Dataset> d = io::ReadDataset("fuzz", read);
  if (!d.ok()) {
    Require(!d.status().message().empty());
    return;
  }
  CheckAcceptedDataset(*d);
  // The input rules the run applies next (io/input_screening.h) keep those invariants.
  io::ScreenInputs(io::InputScreeningOptions{}, &*d);
  CheckAcceptedDataset(*d);
}

}  // namespace subslam::fuzz

#endif  // SUBSLAM_FUZZ_DATASET_FUZZ_H_
