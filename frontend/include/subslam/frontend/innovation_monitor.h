// Filter divergence as a persistent failure of the normalised innovation test.
//
// A consistent filter's innovations ν with covariance S make ε = νᵀ S⁻¹ ν a χ² variable
// with dim ν degrees of freedom, independent from scan to scan, so the sum over the last
// `window_scans` scans with associated detections is χ² with the summed dimension. The
// window fails when that sum exceeds its χ² quantile at `probability`. The associations
// are gated, which truncates each ε from above, so under a consistent filter a window
// fails with probability below 1 − probability; a diverging filter, whose innovations
// crowd the gate, fails window after window. An episode is a run of consecutive failing
// windows; the report gives their number and the longest, in scans.
#ifndef SUBSLAM_FRONTEND_INNOVATION_MONITOR_H_
#define SUBSLAM_FRONTEND_INNOVATION_MONITOR_H_

#include <deque>
#include <map>
#include <string>

#include "absl/status/status.h"

namespace subslam::frontend {

struct InnovationTestOptions {
  int window_scans = 20;       // scans with associations per window; 0 turns the test off
  double probability = 0.999;  // the window's χ² quantile

  absl::Status Validate() const;
};

class InnovationMonitor {
 public:
  explicit InnovationMonitor(const InnovationTestOptions& options) : options_(options) {}

  // One scan's normalised innovation squared and its dimension (nothing when dof = 0).
  void Add(double nis, int dof);

  long windows_tested() const { return tested_; }
  long windows_failed() const { return failed_; }
  long episodes() const { return episodes_; }
  long longest_episode_scans() const { return longest_; }
  bool failing() const { return run_ > 0; }
  // The counts under `prefix` ("innovation_windows_tested", …) for an estimator's Counters().
  void AddCounters(std::map<std::string, double>* counters) const;

 private:
  InnovationTestOptions options_;
  std::deque<std::pair<double, int>> window_;
  double sum_ = 0.0;
  long dof_ = 0;
  long tested_ = 0, failed_ = 0, episodes_ = 0, longest_ = 0, run_ = 0;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_INNOVATION_MONITOR_H_
