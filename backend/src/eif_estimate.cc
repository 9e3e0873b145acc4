// EifEstimate: the estimate and its rows in the state vector.

#include "eif_estimate.h"

#include <utility>

namespace subslam::backend {

EifEstimate::EifEstimate(const Pose2& initial_pose) : graph(initial_pose) {
  anchor_offset.push_back(-1);  // P0 is fixed
  anchor_theta.push_back(initial_pose.theta);
}

int EifEstimate::AddAnchor(const Pose2& pose, double theta) {
  const int k = graph.AddAnchor(pose);
  anchor_theta.push_back(theta);
  anchor_offset.push_back(dim);
  dim += 3;
  return k;
}

int EifEstimate::AddLandmark(const Eigen::Vector2d& position) {
  const int j = graph.AddLandmark(position);
  AddRowsOfNewestLandmark();
  return j;
}

void EifEstimate::AddRowsOfNewestLandmark() {
  landmark_offset.push_back(dim);
  dim += 2;
}

void EifEstimate::RemoveRowsOfLandmark(int drop) {
  const int removed = landmark_offset[drop];
  landmark_offset.erase(landmark_offset.begin() + drop);
  for (int& o : anchor_offset) o -= o > removed ? 2 : 0;
  for (int& o : landmark_offset) o -= o > removed ? 2 : 0;
  dim -= 2;
  owner_of_row_valid_ = false;
}

Pose2 EifEstimate::AnchorPose(int k) const {
  const Pose2& p = graph.anchors()[k];
  return Pose2(p.x, p.y, anchor_theta[k]);
}

std::vector<Eigen::Vector2d> EifEstimate::FactorLandmarks(const SubmapFactor& record) const {
  std::vector<Eigen::Vector2d> landmarks;
  landmarks.reserve(record.landmark_of_feature.size());
  for (int j : record.landmark_of_feature) landmarks.push_back(graph.landmarks()[j]);
  return landmarks;
}

std::vector<int> EifEstimate::LastAnchorRows() const {
  if (graph.num_anchors() < 2) return {};
  const int offset = anchor_offset[graph.num_anchors() - 1];
  return {offset, offset + 1, offset + 2};
}

Eigen::VectorXd EifEstimate::StateVector() const {
  Eigen::VectorXd x(dim);
  for (int k = 1; k < graph.num_anchors(); ++k) {
    const Pose2& p = graph.anchors()[k];
    x.segment<3>(anchor_offset[k]) << p.x, p.y, anchor_theta[k];
  }
  for (int j = 0; j < graph.num_landmarks(); ++j) {
    x.segment<2>(landmark_offset[j]) = graph.landmarks()[j];
  }
  return x;
}

void EifEstimate::SetState(const Eigen::VectorXd& x) {
  for (int k = 1; k < graph.num_anchors(); ++k) {
    const Eigen::Vector3d v = x.segment<3>(anchor_offset[k]);
    anchor_theta[k] = v[2];
    graph.anchor(k) = Pose2(v[0], v[1], WrapAngle(v[2]));
  }
  for (int j = 0; j < graph.num_landmarks(); ++j) {
    graph.landmark(j) = x.segment<2>(landmark_offset[j]);
  }
}

void EifEstimate::SetStateRows(const Eigen::VectorXd& x, const std::vector<int>& rows) {
  EnsureOwnerOfRow();
  for (int row : rows) {
    const int owner = owner_of_row_[row];
    if (owner >= 0) {  // anchor `owner`: one coordinate
      const int c = row - anchor_offset[owner];
      Pose2& p = graph.anchor(owner);
      if (c == 0) p.x = x[row];
      if (c == 1) p.y = x[row];
      if (c == 2) {
        anchor_theta[owner] = x[row];
        p.theta = WrapAngle(x[row]);
      }
    } else {
      const int j = -owner - 1;
      graph.landmark(j)[row - landmark_offset[j]] = x[row];
    }
  }
}

void EifEstimate::EnsureOwnerOfRow() {
  if (!owner_of_row_valid_) {
    owner_of_row_.assign(dim, 0);
    for (int k = 1; k < graph.num_anchors(); ++k) {
      for (int c = 0; c < 3; ++c) owner_of_row_[anchor_offset[k] + c] = k;
    }
    for (int j = 0; j < graph.num_landmarks(); ++j) {
      for (int c = 0; c < 2; ++c) owner_of_row_[landmark_offset[j] + c] = -j - 1;
    }
    owner_of_row_valid_ = true;
    return;
  }
  // Rows added since: the newest anchors' and landmarks' (offsets increase).
  const int known = static_cast<int>(owner_of_row_.size());
  if (known == dim) return;
  owner_of_row_.resize(dim, 0);
  for (int k = graph.num_anchors() - 1; k >= 1 && anchor_offset[k] >= known; --k) {
    for (int c = 0; c < 3; ++c) owner_of_row_[anchor_offset[k] + c] = k;
  }
  for (int j = graph.num_landmarks() - 1; j >= 0 && landmark_offset[j] >= known; --j) {
    for (int c = 0; c < 2; ++c) owner_of_row_[landmark_offset[j] + c] = -j - 1;
  }
}

}  // namespace subslam::backend
