#include "subslam/io/input_screening.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "absl/strings/str_cat.h"
#include "subslam/io/control_screen.h"
#include "subslam/io/steps.h"

namespace subslam::io {

absl::Status InputScreeningOptions::Validate() const {
  if (!(control_spike_sigmas > 0.0 && std::isfinite(control_spike_sigmas))) {
    return absl::InvalidArgumentError(
        absl::StrCat("control_spike_sigmas must be finite and > 0, got ", control_spike_sigmas));
  }
  if (!(time_gap_factor > 1.0 && std::isfinite(time_gap_factor))) {
    return absl::InvalidArgumentError(absl::StrCat("time_gap_factor must be finite and > 1, got ", time_gap_factor));
  }
  return absl::OkStatus();
}

InputScreening ScreenInputs(const InputScreeningOptions& options, Dataset* d) {
  InputScreening out;
  out.duplicate_control_times = d->duplicate_control_times;
  // Control spikes, judged against the records as read (a repair does not feed the next
  // test), by the rule a caller streaming its controls applies (control_screen.h).
  ControlScreen screen(d->motion.noise, options);
  std::vector<ControlRecord> screened;
  screened.reserve(d->controls.size());
  for (const ControlRecord& r : d->controls) {
    if (std::optional<ControlRecord> judged = screen.Push(r)) screened.push_back(*judged);
  }
  for (const ControlRecord& r : screen.Flush()) screened.push_back(r);
  d->controls = std::move(screened);
  out.control_spikes = screen.control_spikes();
  // Time gaps between steps.
  const std::vector<Step> steps = BuildSteps(*d);
  std::vector<double> intervals;
  intervals.reserve(steps.size());
  for (size_t k = 1; k < steps.size(); ++k) intervals.push_back(steps[k].dt);
  if (!intervals.empty()) {
    std::vector<double> sorted = intervals;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    out.median_interval_s = sorted[sorted.size() / 2];
    const double gap = options.time_gap_factor * out.median_interval_s;
    for (double dt : intervals) {
      out.longest_gap_s = std::max(out.longest_gap_s, dt);
      if (dt > gap) ++out.time_gaps;
    }
  }
  const models::RangeBearingConfig& rb = d->sensor.range_bearing;
  for (const Scan& scan : d->scans) {
    for (const Detection& det : scan.detections) {
      out.detections_out_of_range += det.range_m < rb.min_range_m || det.range_m > rb.max_range_m ? 1 : 0;
    }
  }
  return out;
}

}  // namespace subslam::io
