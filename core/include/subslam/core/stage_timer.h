// Wall-clock time per named stage, as every estimator and back-end reports it
// (report.json's "stages"): StageTimes accumulates seconds per stage over a run, and a
// StageTimer adds the time of its scope to one stage.
#ifndef SUBSLAM_CORE_STAGE_TIMER_H_
#define SUBSLAM_CORE_STAGE_TIMER_H_

#include <map>
#include <string>

#include "absl/time/clock.h"

namespace subslam {

// Wall-clock seconds spent per named stage, accumulated over the run.
using StageTimes = std::map<std::string, double>;

class StageTimer {
 public:
  StageTimer(StageTimes* times, const char* stage) : times_(times), stage_(stage) {}
  ~StageTimer() { (*times_)[stage_] += absl::ToDoubleSeconds(absl::Now() - start_); }
  StageTimer(const StageTimer&) = delete;
  StageTimer& operator=(const StageTimer&) = delete;

 private:
  StageTimes* times_;
  const char* stage_;
  absl::Time start_ = absl::Now();
};

}  // namespace subslam

#endif  // SUBSLAM_CORE_STAGE_TIMER_H_
