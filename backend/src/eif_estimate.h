// The EIF joiner's estimate and its place in the state vector (private to the back-end).
//
// The state x stacks the anchors P1 … Pk (3 rows each: x, y, θ; P0 is fixed and has no
// rows) and the global landmarks (2 rows each: x, y) at their offsets, in the order they
// were created (a merge removes a landmark's rows and moves the rows after it up).
// Headings are kept continuous in the state (never wrapped, so that every stored linear
// model stays valid); the graph holds them wrapped, as the outputs do.
#ifndef SUBSLAM_BACKEND_SRC_EIF_ESTIMATE_H_
#define SUBSLAM_BACKEND_SRC_EIF_ESTIMATE_H_

#include <Eigen/Core>
#include <vector>

#include "subslam/core/pose2.h"
#include "subslam/core/submap_graph.h"

namespace subslam::backend {

struct EifEstimate {
  explicit EifEstimate(const Pose2& initial_pose);

  // An anchor (`pose` as the graph holds it, `theta` its continuous heading) and a
  // landmark at `position`, each given the next rows of the state; their indices.
  int AddAnchor(const Pose2& pose, double theta);
  int AddLandmark(const Eigen::Vector2d& position);
  // Rows for a landmark the graph has just appended (a split feature's).
  void AddRowsOfNewestLandmark();
  // Landmark `drop`'s rows removed (after the graph merged it), the rows after them moved up.
  void RemoveRowsOfLandmark(int drop);

  Eigen::VectorXd StateVector() const;
  void SetState(const Eigen::VectorXd& x);
  // The same for the listed rows only (the rest already hold x).
  void SetStateRows(const Eigen::VectorXd& x, const std::vector<int>& rows);
  // Anchor k with its continuous heading.
  Pose2 AnchorPose(int k) const;
  // A factor's landmarks, in its features' order.
  std::vector<Eigen::Vector2d> FactorLandmarks(const SubmapFactor& record) const;
  // The last anchor's rows (none before the first join).
  std::vector<int> LastAnchorRows() const;

  SubmapGraph graph;               // headings wrapped
  std::vector<int> anchor_offset;  // −1 for P0
  std::vector<int> landmark_offset;
  std::vector<double> anchor_theta;  // continuous headings
  int dim = 0;

 private:
  // Per state row, its anchor k (≥ 1) or landmark j (as −j − 1), for SetStateRows; valid
  // while owner_of_row_valid_, extended as rows are added.
  void EnsureOwnerOfRow();
  std::vector<int> owner_of_row_;
  bool owner_of_row_valid_ = false;
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_SRC_EIF_ESTIMATE_H_
