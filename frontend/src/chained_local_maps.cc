#include "subslam/frontend/chained_local_maps.h"

namespace subslam::frontend {

ChainedLocalMaps::ChainedLocalMaps(std::unique_ptr<LocalMapper> mapper, const Pose2& initial_pose)
    : mapper_(std::move(mapper)), anchor_(initial_pose) {}

void ChainedLocalMaps::Update(const io::Scan& scan) {
  last_scan_map_id_ = mapper_->current_map_id();
  mapper_->Update(scan);
  Absorb();
}

void ChainedLocalMaps::Finish() {
  mapper_->Finish();
  Absorb();
}

void ChainedLocalMaps::Absorb() {
  for (ClosedLocalMap& c : mapper_->TakeClosed()) {
    start_anchors_.push_back(anchor_);
    start_anchor_covariances_.push_back(anchor_covariance_);
    Eigen::Matrix3d J_a, J_e;
    const Pose2 next = Compose(anchor_, c.submap.end_pose(), &J_a, &J_e);
    anchor_covariance_ = J_a * anchor_covariance_ * J_a.transpose() +
                         J_e * c.submap.covariance.topLeftCorner<3, 3>() * J_e.transpose();
    anchor_ = next;
    closed_.push_back(std::move(c));
  }
}

Pose2 ChainedLocalMaps::pose() const { return Compose(anchor_, mapper_->local_pose()); }

Eigen::Matrix3d ChainedLocalMaps::pose_covariance() const {
  Eigen::Matrix3d J_a, J_l;
  Compose(anchor_, mapper_->local_pose(), &J_a, &J_l);
  return J_a * anchor_covariance_ * J_a.transpose() +
         J_l * mapper_->local_pose_covariance() * J_l.transpose();
}

std::vector<LandmarkEstimate> ChainedLocalMaps::Map() const {
  std::vector<LandmarkEstimate> out;
  for (size_t k = 0; k < closed_.size(); ++k) {
    const LocalSubmap& s = closed_[k].submap;
    for (int i = 0; i < s.num_landmarks(); ++i) {
      Matrix23d J_pose;
      Eigen::Matrix2d J_point;
      const Eigen::Vector2d p = TransformFrom(start_anchors_[k], s.landmark(i), &J_pose, &J_point);
      const Eigen::Matrix2d cov = J_pose * start_anchor_covariances_[k] * J_pose.transpose() +
                                  J_point * s.landmark_covariance(i) * J_point.transpose();
      out.push_back({s.id * kFeatureIdStride + s.landmarks[i].local_id, p, cov});
    }
  }
  return out;
}

}  // namespace subslam::frontend
