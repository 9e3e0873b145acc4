// The interface the run pipeline drives: one estimator over the whole run, fed the
// steps of io::BuildSteps in order (predict over dt with the active control, then
// update with the step's scan, if any). Implemented by the single-map filters
// (DeadReckoning, EkfSlam, FastSlam, SeifSlam) and by the submap pipeline, which wraps a
// local mapper and a back-end behind it.
// Not thread-safe: one estimator per thread.
#ifndef SUBSLAM_FRONTEND_ONLINE_ESTIMATOR_H_
#define SUBSLAM_FRONTEND_ONLINE_ESTIMATOR_H_

#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "subslam/core/estimates.h"
#include "subslam/core/stage_timer.h"
#include "subslam/models/scan.h"

namespace subslam::frontend {

class OnlineEstimator {
 public:
  virtual ~OnlineEstimator() = default;
  virtual std::string Name() const = 0;
  // Predicts over dt ≥ 0 seconds with control u held constant.
  virtual void Predict(const Eigen::Vector2d& u, double dt) = 0;
  // Incorporates one scan of detections taken at the current time. An error says what
  // went wrong: a malformed scan (CheckScan; it is not used, the estimate is unchanged),
  // or, for the submap pipeline, a local map that could not be exported or joined (the
  // run cannot go on; every later Update returns the same error).
  virtual absl::Status Update(const Scan& scan) = 0;
  // Current vehicle pose and its marginal covariance.
  virtual Pose2 pose() const = 0;
  virtual Eigen::Matrix3d pose_covariance() const = 0;
  // The map as reported (e.g. confirmed landmarks only).
  virtual std::vector<LandmarkEstimate> Map() const = 0;
  virtual StageTimes stage_times() const = 0;
  // Estimator-specific counters for the report (e.g. landmarks created, deleted).
  virtual std::map<std::string, double> Counters() const { return {}; }
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_ONLINE_ESTIMATOR_H_
