// SubmapMarginalsGraph: a submap graph's local maps reduced to their marginal blocks.

#include "subslam/posegraph/submap_marginals_graph.h"

#include <Eigen/LU>

namespace subslam::posegraph {

PoseGraph SubmapMarginalsGraph(const SubmapGraph& graph) {
  PoseGraph out;
  for (int k = 0; k < graph.num_anchors(); ++k) {
    const int p = out.PoseIndex(k);
    out.poses[p].estimate = graph.anchors()[k];
    out.poses[p].has_estimate = true;
    out.poses[p].fixed = k == 0;
  }
  const long landmark_base = graph.num_anchors();
  for (int j = 0; j < graph.num_landmarks(); ++j) {
    const int q = out.PointIndex(landmark_base + j);
    out.points[q].estimate = graph.landmarks()[j];
    out.points[q].has_estimate = true;
  }
  for (const SubmapFactor& factor : graph.factors()) {
    const LocalSubmap& s = factor.submap;
    out.odometry.push_back({factor.start_anchor, factor.end_anchor, s.end_pose(),
                            Eigen::Matrix3d(s.covariance.topLeftCorner<3, 3>().inverse())});
    for (int i = 0; i < s.num_landmarks(); ++i) {
      out.point_measurements.push_back({factor.start_anchor,
                                        out.FindPoint(landmark_base + factor.landmark_of_feature[i]), s.landmark(i),
                                        Eigen::Matrix2d(s.landmark_covariance(i).inverse())});
    }
  }
  return out;
}

}  // namespace subslam::posegraph
