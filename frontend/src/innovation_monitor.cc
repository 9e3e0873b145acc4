#include "subslam/frontend/innovation_monitor.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "subslam/models/gating.h"

namespace subslam::frontend {

absl::Status InnovationTestOptions::Validate() const {
  if (window_scans < 0)
    return absl::InvalidArgumentError(absl::StrCat("innovation test window must be >= 0, got ", window_scans));
  if (!(probability > 0.0 && probability < 1.0)) {
    return absl::InvalidArgumentError(absl::StrCat("innovation test probability must be in (0, 1), got ", probability));
  }
  return absl::OkStatus();
}

void InnovationMonitor::Add(double nis, int dof) {
  if (options_.window_scans == 0 || dof <= 0) return;
  if (!std::isfinite(nis)) {  // a broken estimate's innovation: a failed window, not summed
    ++tested_;
    ++failed_;
    if (run_++ == 0) ++episodes_;
    longest_ = std::max(longest_, run_);
    return;
  }
  window_.emplace_back(nis, dof);
  sum_ += nis;
  dof_ += dof;
  if (static_cast<int>(window_.size()) > options_.window_scans) {
    sum_ -= window_.front().first;
    dof_ -= window_.front().second;
    window_.pop_front();
  }
  if (static_cast<int>(window_.size()) < options_.window_scans) return;
  ++tested_;
  if (!(sum_ <= models::ChiSquareQuantile(options_.probability, static_cast<double>(dof_)))) {
    ++failed_;
    if (run_++ == 0) ++episodes_;
    longest_ = std::max(longest_, run_);
  } else {
    run_ = 0;
  }
}

void InnovationMonitor::AddCounters(std::map<std::string, double>* counters) const {
  (*counters)["innovation_windows_tested"] = tested_;
  (*counters)["innovation_windows_failed"] = failed_;
  (*counters)["divergence_episodes"] = episodes_;
  (*counters)["longest_divergence_scans"] = longest_;
}

}  // namespace subslam::frontend
