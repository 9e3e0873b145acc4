// The processing timeline: controls and scans merged into time-ordered steps.
//
// Step k at time t_k: predict from t_{k−1} to t_k with the control that was active
// over that interval, then (if the step has a scan) update with its detections. One
// step per distinct time among control records and scans. Before the first control
// record the vehicle is assumed at rest (zero control).
#ifndef SUBSLAM_IO_STEPS_H_
#define SUBSLAM_IO_STEPS_H_

#include <vector>

#include "subslam/io/dataset.h"

namespace subslam::io {

struct Step {
  double t = 0.0;
  double dt = 0.0;                                    // t_k − t_{k−1}; 0 for the first step
  Eigen::Vector2d control = Eigen::Vector2d::Zero();  // active over (t_{k−1}, t_k]
  int scan_index = -1;                                // into Dataset::scans, or −1
};

std::vector<Step> BuildSteps(const Dataset& dataset);

}  // namespace subslam::io

#endif  // SUBSLAM_IO_STEPS_H_
