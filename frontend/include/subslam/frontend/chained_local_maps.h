// The local mappers behind the OnlineEstimator interface, with the simplest possible
// "back-end": each local map's start anchor is the previous anchor composed with the
// previous map's end pose (first-order covariance propagation). Nothing is fused and no
// loop is ever closed — the dead-reckoned chain of local maps. It lets `subslam run
// --frontend rbpf` run, record submaps.jsonl and be evaluated before a joiner exists;
// the back-ends (EIF, Ceres, EKF joining) replace it.
//
// pose() = anchor ∘ local pose; Map() = every closed local map's features expressed in
// the world through its anchor (features seen by two maps appear twice).
#ifndef SUBSLAM_FRONTEND_CHAINED_LOCAL_MAPS_H_
#define SUBSLAM_FRONTEND_CHAINED_LOCAL_MAPS_H_

#include <memory>
#include <vector>

#include "subslam/frontend/local_mapper.h"
#include "subslam/frontend/online_estimator.h"

namespace subslam::frontend {

class ChainedLocalMaps final : public OnlineEstimator {
 public:
  ChainedLocalMaps(std::unique_ptr<LocalMapper> mapper, const Pose2& initial_pose);

  std::string Name() const override { return mapper_->Name(); }
  void Predict(const Eigen::Vector2d& u, double dt) override { mapper_->Predict(u, dt); }
  void Update(const io::Scan& scan) override;
  Pose2 pose() const override;
  Eigen::Matrix3d pose_covariance() const override;
  std::vector<LandmarkEstimate> Map() const override;
  StageTimes stage_times() const override { return mapper_->stage_times(); }
  std::map<std::string, double> Counters() const override { return mapper_->Counters(); }

  // Closes the open local map; call once after the last step.
  void Finish();
  const std::vector<ClosedLocalMap>& local_maps() const { return closed_; }
  // The local map that processed the last scan, and its feature id per detection.
  int last_scan_map_id() const { return last_scan_map_id_; }
  const std::vector<int>& last_scan_features() const { return mapper_->last_scan_features(); }
  // Feature ids in Map() are map_id · kFeatureIdStride + local id.
  static constexpr int kFeatureIdStride = 1000000;

 private:
  void Absorb();  // chains the anchors of newly closed maps

  std::unique_ptr<LocalMapper> mapper_;
  Pose2 anchor_;
  Eigen::Matrix3d anchor_covariance_ = Eigen::Matrix3d::Zero();
  std::vector<ClosedLocalMap> closed_;
  std::vector<Pose2> start_anchors_;
  std::vector<Eigen::Matrix3d> start_anchor_covariances_;
  int last_scan_map_id_ = 0;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_CHAINED_LOCAL_MAPS_H_
