#include "subslam/io/steps.h"

namespace subslam::io {

std::vector<Step> BuildSteps(const Dataset& dataset) {
  std::vector<Step> steps;
  steps.reserve(dataset.controls.size() + dataset.scans.size());
  size_t ci = 0, si = 0;
  Eigen::Vector2d active = Eigen::Vector2d::Zero();
  bool first = true;
  double t_prev = 0.0;
  while (ci < dataset.controls.size() || si < dataset.scans.size()) {
    const double tc = ci < dataset.controls.size() ? dataset.controls[ci].t : INFINITY;
    const double ts = si < dataset.scans.size() ? dataset.scans[si].t : INFINITY;
    Step step;
    step.t = std::min(tc, ts);
    step.dt = first ? 0.0 : step.t - t_prev;
    step.control = active;  // the control active over (t_prev, t]
    if (ts == step.t) step.scan_index = static_cast<int>(si++);
    if (tc == step.t) active = dataset.motion.Corrected(dataset.controls[ci++].u);  // from t on
    steps.push_back(step);
    t_prev = step.t;
    first = false;
  }
  return steps;
}

}  // namespace subslam::io
