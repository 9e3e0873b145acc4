#include "subslam/graph/submap_graph.h"

#include <Eigen/LU>
#include <cstdio>
#include <memory>

#include "absl/strings/str_cat.h"

namespace subslam {

absl::Status SubmapGraph::WriteG2o(const std::string& path) const {
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "w"), &std::fclose);
  if (!f) return absl::UnavailableError(absl::StrCat(path, ": cannot open for writing"));
  const int landmark_base = num_anchors();
  for (int k = 0; k < num_anchors(); ++k) {
    std::fprintf(f.get(), "VERTEX_SE2 %d %.17g %.17g %.17g\n", k, anchors_[k].x, anchors_[k].y,
                 anchors_[k].theta);
  }
  for (int j = 0; j < num_landmarks(); ++j) {
    std::fprintf(f.get(), "VERTEX_XY %d %.17g %.17g\n", landmark_base + j, landmarks_[j].x(),
                 landmarks_[j].y());
  }
  std::fprintf(f.get(), "FIX 0\n");
  for (const SubmapFactor& factor : factors_) {
    const LocalSubmap& s = factor.submap;
    const Eigen::Matrix3d I = s.covariance.topLeftCorner<3, 3>().inverse();
    std::fprintf(f.get(), "EDGE_SE2 %d %d %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
                 factor.start_anchor, factor.end_anchor, s.mean[0], s.mean[1], s.mean[2], I(0, 0),
                 I(0, 1), I(0, 2), I(1, 1), I(1, 2), I(2, 2));
    for (int i = 0; i < s.num_landmarks(); ++i) {
      const Eigen::Matrix2d J = s.landmark_covariance(i).inverse();
      std::fprintf(f.get(), "EDGE_SE2_XY %d %d %.17g %.17g %.17g %.17g %.17g\n",
                   factor.start_anchor, landmark_base + factor.landmark_of_feature[i],
                   s.landmark(i).x(), s.landmark(i).y(), J(0, 0), J(0, 1), J(1, 1));
    }
  }
  if (std::ferror(f.get())) return absl::DataLossError(absl::StrCat(path, ": write failed"));
  return absl::OkStatus();
}

}  // namespace subslam
