#include "subslam/io/input_screening.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "absl/strings/str_cat.h"
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

namespace {

// Channel c of the control noise σ at control value u (models::ControlNoise).
double Sigma(const models::ControlNoise& noise, int c, double u) {
  return c == 0 ? noise.sigma_u0 + noise.scale_u0 * std::abs(u) : noise.sigma_u1 + noise.scale_u1 * std::abs(u);
}

}  // namespace

InputScreening ScreenInputs(const InputScreeningOptions& options, Dataset* d) {
  InputScreening out;
  out.duplicate_control_times = d->duplicate_control_times;
  // Control spikes, judged against the records as read (a repair does not feed the next test).
  const std::vector<ControlRecord> read = d->controls;
  const int w = InputScreeningOptions::kSpikeWindow;
  std::vector<double> around(2 * w), deviations(2 * w);
  const auto median = [](std::vector<double>& v) {  // of an even count: the mean of the middle two
    const size_t h = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + h, v.end());
    const double upper = v[h];
    return 0.5 * (upper + *std::max_element(v.begin(), v.begin() + h));
  };
  for (size_t k = w; k + w < read.size(); ++k) {
    bool spike = false;
    for (int c = 0; c < 2; ++c) {
      for (int i = 0; i < w; ++i) {
        around[i] = read[k - w + i].u[c];
        around[w + i] = read[k + 1 + i].u[c];
      }
      const double m = median(around);
      for (int i = 0; i < 2 * w; ++i) deviations[i] = std::abs(around[i] - m);
      // The neighbours' own spread (as a σ: 1.4826 × their median absolute deviation) or
      // the noise model's σ, whichever is larger.
      const double scale = std::max(Sigma(d->motion.noise, c, m), 1.4826 * median(deviations));
      if (std::abs(read[k].u[c] - m) > options.control_spike_sigmas * scale) {
        spike = true;
        if (options.replace_control_spikes) d->controls[k].u[c] = m;
      }
    }
    out.control_spikes += spike ? 1 : 0;
  }
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
