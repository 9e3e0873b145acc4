// Inputs that cannot be trusted, handled by a fixed rule and counted before a run
// (report.json's "health.inputs"). The reader (dataset_reader.h) has already refused what
// is malformed — non-finite values, times going backwards, a non-positive range; what it
// accepts can still be implausible:
//
//   control spikes   a control channel that departs from the median of the
//                    `kSpikeWindow` records on each side by more than
//                    `control_spike_sigmas` times the larger of the motion model's noise σ
//                    at that median and the neighbours' own spread (1.4826 × their median
//                    absolute deviation): an isolated fault, not a manoeuvre — a step or
//                    the peak of a fast turn moves the neighbours too. The channel is
//                    replaced by the median. The first and last kSpikeWindow records are
//                    left alone.
//   time gaps        an interval between consecutive steps (controls and scans merged)
//                    longer than `time_gap_factor` times the median interval. Nothing is
//                    changed: the prediction over a gap holds the last control, and the
//                    motion model's noise grows with the interval. Counted, with the
//                    longest gap, because a held control over a long gap is a guess.
//   repeated times   control lines with the time of the previous line (the reader keeps
//                    the later one: Dataset::duplicate_control_times). Detections sharing
//                    a time are one scan by definition and are not counted.
//   out of range     detections outside the sensor's [min_range, max_range]: never used
//                    by the filters; counted.
#ifndef SUBSLAM_IO_INPUT_SCREENING_H_
#define SUBSLAM_IO_INPUT_SCREENING_H_

#include "absl/status/status.h"
#include "subslam/io/dataset.h"

namespace subslam::io {

struct InputScreeningOptions {
  static constexpr int kSpikeWindow = 3;  // records on each side of a control judged
  // Spike bound in σ (see above). Under the noise model a departure of 10 σ has
  // probability below 1e-20; Victoria Park's largest is below 1 σ.
  double control_spike_sigmas = 10.0;
  double time_gap_factor = 20.0;       // a gap: longer than this many median intervals
  bool replace_control_spikes = true;  // false: count only

  absl::Status Validate() const;
};

struct InputScreening {
  int control_spikes = 0;  // records with a channel replaced (or that would be)
  int time_gaps = 0;
  double longest_gap_s = 0.0;      // longest interval between steps
  double median_interval_s = 0.0;  // median interval between steps
  int duplicate_control_times = 0;
  long detections_out_of_range = 0;
};

// Screens (and, for control spikes, repairs) `dataset` in place by the rules above.
InputScreening ScreenInputs(const InputScreeningOptions& options, Dataset* dataset);

}  // namespace subslam::io

#endif  // SUBSLAM_IO_INPUT_SCREENING_H_
