// Adds the wall-clock time of a scope to a named stage of a StageTimes map.
#ifndef SUBSLAM_FRONTEND_INTERNAL_STAGE_TIMER_H_
#define SUBSLAM_FRONTEND_INTERNAL_STAGE_TIMER_H_

#include "absl/time/clock.h"
#include "subslam/frontend/online_estimator.h"

namespace subslam::frontend {

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

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_INTERNAL_STAGE_TIMER_H_
