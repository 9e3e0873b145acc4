// What the data-set fuzz targets check on every data set the reader accepts: the
// invariants the estimators rely on (docs/formats.md, "Data-set directory").
#ifndef SUBSLAM_FUZZ_DATASET_FUZZ_CHECK_H_
#define SUBSLAM_FUZZ_DATASET_FUZZ_CHECK_H_

#include <cmath>
#include <cstdlib>

#include "subslam/io/dataset.h"
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

}  // namespace subslam::fuzz

#endif  // SUBSLAM_FUZZ_DATASET_FUZZ_CHECK_H_
