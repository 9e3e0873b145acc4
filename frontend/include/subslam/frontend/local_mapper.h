// Local mappers: a SLAM filter run in the frame of the local map's start pose, closed by
// a SubmapPolicy and exported as one Gaussian (LocalSubmap) per local map.
//
// A local map starts at the current pose with zero uncertainty and no landmarks; when the
// policy closes it, its Gaussian over [end pose, features] (in the start frame) is queued
// for TakeClosed() and the next map starts at its end pose. It exports neither features
// too uncertain to join on nor features whose detections show them moving
// (SubmapPolicyOptions). Landmarks near the boundary
// are observed again by the next map, so consecutive maps share features to join on.
//
// Implementations: RbpfLocalMapper (FastSLAM 2.0, moment matching, below) and
// EkfLocalMapper (EKF-SLAM; ekf_local_mapper.h).
#ifndef SUBSLAM_FRONTEND_LOCAL_MAPPER_H_
#define SUBSLAM_FRONTEND_LOCAL_MAPPER_H_

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "subslam/core/local_submap.h"
#include "subslam/frontend/fastslam.h"
#include "subslam/frontend/moment_matching.h"
#include "subslam/frontend/moving_feature_test.h"
#include "subslam/frontend/online_estimator.h"
#include "subslam/frontend/submap_policy.h"

namespace subslam::frontend {

struct ClosedLocalMap {
  LocalSubmap submap;
  CloseReason reason = CloseReason::kKeepOpen;
};

class LocalMapper {
 public:
  virtual ~LocalMapper() = default;
  virtual std::string Name() const = 0;

  void Predict(const Eigen::Vector2d& u, double dt);
  // Processes a scan taken at scan.t, then asks the policy whether to close the map. A
  // malformed scan (CheckScan) is not used: its error is returned, and nothing changes.
  absl::Status Update(const Scan& scan);
  // Closes the open local map (reason kEndOfRun) if it has processed any scan.
  void Finish();
  // Local maps closed since the last call, in order.
  std::vector<ClosedLocalMap> TakeClosed();
  // An error once a closing map could not be exported (its estimate is not finite or not
  // a valid Gaussian): that map and every later one are not closed.
  const absl::Status& status() const { return status_; }

  // The vehicle in the current local map's frame.
  Pose2 local_pose() const { return FilterPose(); }
  Eigen::Matrix3d local_pose_covariance() const { return FilterPoseCovariance(); }
  int current_map_id() const { return map_id_; }
  // The current map's feature id of each detection of the last scan (−1: none).
  virtual const std::vector<int>& last_scan_features() const = 0;
  StageTimes stage_times() const;
  // The mapper's counters (local maps, closes by reason, repairs) and the filter's.
  std::map<std::string, double> Counters() const;
  // Leave this many cores to other threads of the process in the next updates (a mapper
  // with threads of its own uses fewer; the results do not change). Default: ignored.
  virtual void SetSpareCores(int /*cores*/) {}

 protected:
  LocalMapper(const SubmapPolicyOptions& policy, const models::RangeBearingConfig& sensor, double t_start);

  virtual void FilterPredict(const Eigen::Vector2d& u, double dt) = 0;
  virtual absl::Status FilterUpdate(const Scan& scan) = 0;
  virtual void FilterReset() = 0;                 // new map: identity pose, no uncertainty, no landmarks
  virtual SubmapStatus FilterStatus() const = 0;  // elapsed_s and delayed_for_s filled by the caller
  virtual Pose2 FilterPose() const = 0;
  virtual Eigen::Matrix3d FilterPoseCovariance() const = 0;
  virtual MomentMatchedGaussian Export() const = 0;
  virtual StageTimes FilterStageTimes() const = 0;
  virtual std::map<std::string, double> FilterCounters() const = 0;

 private:
  void Close(CloseReason reason);
  // Removes (marginalises out) the features wider than max_feature_sigma_m_ given the
  // end pose (see SubmapPolicyOptions::max_feature_sigma_ratio), and those the
  // moving-feature test finds moving (SubmapPolicyOptions::moving_features).
  void DropUncertainFeatures(MomentMatchedGaussian* g);
  void DropMovingFeatures(MomentMatchedGaussian* g);

  SubmapPolicy policy_;
  double t_ = 0.0, t_map_start_ = 0.0;
  double delayed_since_ = -1.0;
  int map_id_ = 0;
  int scans_in_map_ = 0;
  std::vector<ClosedLocalMap> closed_;
  std::map<std::string, long> closes_by_reason_;
  int repairs_ = 0;
  absl::Status status_;
  double max_feature_sigma_m_ = 0.0;  // 0: export every feature (see max_feature_sigma_ratio)
  long features_too_uncertain_ = 0;   // not exported by that rule
  MovingFeatureTest moving_test_;     // the open map's features
  long moving_features_ = 0;          // not exported as moving
  double export_seconds_ = 0.0;
};

// The RBPF local mapper: FastSLAM 2.0 (fastslam.h) per local map, exported by moment
// matching (moment_matching.h) of the particles on the common feature set.
class RbpfLocalMapper final : public LocalMapper {
 public:
  RbpfLocalMapper(std::unique_ptr<models::MotionModel> motion, const models::RangeBearingConfig& sensor,
                  const FastSlamOptions& fastslam, const SubmapPolicyOptions& policy, double t_start);

  std::string Name() const override { return "rbpf"; }
  const std::vector<int>& last_scan_features() const override { return filter_.last_scan_features(); }
  const FastSlam& filter() const { return filter_; }
  void SetSpareCores(int cores) override {
    filter_.set_thread_limit(cores > 0 ? std::max(1, filter_.threads() - cores) : 0);
  }

 private:
  void FilterPredict(const Eigen::Vector2d& u, double dt) override { filter_.Predict(u, dt); }
  absl::Status FilterUpdate(const Scan& scan) override { return filter_.Update(scan); }
  void FilterReset() override { filter_.Reset(Pose2()); }
  SubmapStatus FilterStatus() const override;
  Pose2 FilterPose() const override { return filter_.pose(); }
  Eigen::Matrix3d FilterPoseCovariance() const override { return filter_.pose_covariance(); }
  MomentMatchedGaussian Export() const override { return filter_.MomentMatched(); }
  StageTimes FilterStageTimes() const override { return filter_.stage_times(); }
  std::map<std::string, double> FilterCounters() const override { return filter_.Counters(); }

  FastSlam filter_;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_LOCAL_MAPPER_H_
