#include "subslam/frontend/ekf_local_mapper.h"

namespace subslam::frontend {

EkfLocalMapper::EkfLocalMapper(std::unique_ptr<models::MotionModel> motion, const models::RangeBearingConfig& sensor,
                               const EkfSlamOptions& ekf, const SubmapPolicyOptions& policy, double t_start,
                               double min_existence)
    : LocalMapper(policy, sensor, t_start),
      filter_(std::move(motion), sensor, Pose2(), ekf),
      min_existence_(min_existence) {}

SubmapStatus EkfLocalMapper::FilterStatus() const {
  SubmapStatus s;
  s.pose_covariance = filter_.pose_covariance();
  s.confirmed_features = filter_.NumConfirmed();
  s.visible_features = filter_.NumConfirmedWithinRange();
  return s;
}

}  // namespace subslam::frontend
