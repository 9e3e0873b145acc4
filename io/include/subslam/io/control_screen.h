// The control-spike rule of input_screening.h for a caller that receives controls one at a
// time (a navigation stack): each record is judged against the `kSpikeWindow` records on
// each side of it, as read, so a record comes out once the kSpikeWindow records after it
// have arrived — the screened stream lags the input by kSpikeWindow records (at 100 Hz,
// 30 ms). The first kSpikeWindow records pass unjudged, and Flush() returns the last ones
// unjudged, as the batch rule leaves them: over a whole data set the two give the same
// records, to the bit (ScreenInputs judges with this class).
//
// Usage:
//   io::ControlScreen screen(dataset.motion.noise, io::InputScreeningOptions{});
//   for (const io::ControlRecord& r : incoming) {
//     if (std::optional<io::ControlRecord> out = screen.Push(r)) UseControl(*out);
//   }
//   for (const io::ControlRecord& r : screen.Flush()) UseControl(r);
//   // screen.control_spikes(): the records judged spikes so far
#ifndef SUBSLAM_IO_CONTROL_SCREEN_H_
#define SUBSLAM_IO_CONTROL_SCREEN_H_

#include <deque>
#include <optional>
#include <vector>

#include "subslam/io/dataset.h"
#include "subslam/io/input_screening.h"
#include "subslam/models/motion_model.h"

namespace subslam::io {

class ControlScreen {
 public:
  // `options` must be valid (InputScreeningOptions::Validate); `noise` is the motion model's.
  ControlScreen(const models::ControlNoise& noise, const InputScreeningOptions& options);

  // Takes the next record (times increasing) and returns the record kSpikeWindow before it,
  // screened (a spike's channel replaced by its neighbours' median when
  // options.replace_control_spikes), or nothing while fewer have arrived.
  std::optional<ControlRecord> Push(const ControlRecord& record);
  // The records still held, unjudged, in order; the screen starts over empty (its count
  // stays).
  std::vector<ControlRecord> Flush();
  // Records judged spikes so far (a channel replaced, or that would be).
  int control_spikes() const { return control_spikes_; }

 private:
  models::ControlNoise noise_;
  InputScreeningOptions options_;
  std::deque<ControlRecord> held_;  // as read: the record to judge and its neighbours
  long pushed_ = 0;                 // since the start or the last Flush()
  int control_spikes_ = 0;
  std::vector<double> around_, deviations_;  // a judgement's workspace
};

}  // namespace subslam::io

#endif  // SUBSLAM_IO_CONTROL_SCREEN_H_
