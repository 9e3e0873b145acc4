// The EKF-SLAM local mapper (the EKF-EIF and RBPF-EKF configurations' front-end): EKF-SLAM
// (ekf_slam.h) per local map under the same SubmapPolicy and LocalSubmap contract as the
// RBPF. Its Gaussian is exported directly — the pose and the landmarks whose existence
// reaches the policy's export threshold (0.95 by default), with their exact covariance.
// The particle criteria of the policy do not apply (diversity is always 1).
#ifndef SUBSLAM_FRONTEND_EKF_LOCAL_MAPPER_H_
#define SUBSLAM_FRONTEND_EKF_LOCAL_MAPPER_H_

#include <memory>

#include "subslam/frontend/ekf_slam.h"
#include "subslam/frontend/local_mapper.h"

namespace subslam::frontend {

class EkfLocalMapper final : public LocalMapper {
 public:
  EkfLocalMapper(std::unique_ptr<models::MotionModel> motion, const models::RangeBearingConfig& sensor,
                 const EkfSlamOptions& ekf, const SubmapPolicyOptions& policy, double t_start,
                 double min_existence = 0.95);

  std::string Name() const override { return "ekf"; }
  const std::vector<int>& last_scan_features() const override { return filter_.last_scan_features(); }
  const EkfSlam& filter() const { return filter_; }

 private:
  void FilterPredict(const Eigen::Vector2d& u, double dt) override { filter_.Predict(u, dt); }
  absl::Status FilterUpdate(const Scan& scan) override { return filter_.Update(scan); }
  void FilterReset() override { filter_.Reset(Pose2()); }
  SubmapStatus FilterStatus() const override;
  Pose2 FilterPose() const override { return filter_.pose(); }
  Eigen::Matrix3d FilterPoseCovariance() const override { return filter_.pose_covariance(); }
  MomentMatchedGaussian Export() const override { return filter_.Export(min_existence_); }
  StageTimes FilterStageTimes() const override { return filter_.stage_times(); }
  std::map<std::string, double> FilterCounters() const override { return filter_.Counters(); }

  EkfSlam filter_;
  double min_existence_;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_EKF_LOCAL_MAPPER_H_
