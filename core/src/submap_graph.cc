#include "subslam/core/submap_graph.h"

#include <Eigen/LU>
#include <cstdio>
#include <memory>

#include "absl/strings/str_cat.h"

namespace subslam {

std::vector<int> SubmapGraph::FeatureCounts() const {
  std::vector<int> counts(landmarks_.size(), 0);
  for (const SubmapFactor& f : factors_) {
    for (int j : f.landmark_of_feature) ++counts[j];
  }
  return counts;
}

bool SubmapGraph::CoObserved(int a, int b) const {
  for (const SubmapFactor& f : factors_) {
    bool has_a = false, has_b = false;
    for (int j : f.landmark_of_feature) {
      has_a = has_a || j == a;
      has_b = has_b || j == b;
    }
    if (has_a && has_b) return true;
  }
  return false;
}

absl::Status SubmapGraph::ValidateMerge(int keep, int drop) const {
  const int n = num_landmarks();
  if (keep < 0 || keep >= n || drop < 0 || drop >= n) {
    return absl::InvalidArgumentError(
        absl::StrCat("merge of landmarks ", keep, " and ", drop, ": the map has landmarks 0-", n - 1));
  }
  if (keep == drop) return absl::InvalidArgumentError(absl::StrCat("merge of landmark ", keep, " with itself"));
  if (CoObserved(keep, drop)) {
    return absl::InvalidArgumentError(
        absl::StrCat("merge of landmarks ", keep, " and ", drop, ": one local map holds them as distinct features"));
  }
  return absl::OkStatus();
}

absl::Status SubmapGraph::MergeLandmarks(int keep, int drop) {
  if (absl::Status st = ValidateMerge(keep, drop); !st.ok()) return st;
  for (SubmapFactor& f : factors_) {
    for (int& j : f.landmark_of_feature) j = RenumberAfterMerge(j, keep, drop);
  }
  landmarks_.erase(landmarks_.begin() + drop);
  return absl::OkStatus();
}

absl::Status SubmapGraph::ValidateSplit(int factor, int feature) const {
  if (factor < 0 || factor >= static_cast<int>(factors_.size())) {
    return absl::InvalidArgumentError(absl::StrCat("split: no factor ", factor));
  }
  const std::vector<int>& assoc = factors_[factor].landmark_of_feature;
  if (feature < 0 || feature >= static_cast<int>(assoc.size())) {
    return absl::InvalidArgumentError(absl::StrCat("split: factor ", factor, " has no feature ", feature));
  }
  if (FeatureCounts()[assoc[feature]] < 2) {
    return absl::InvalidArgumentError(absl::StrCat("split of feature ", feature, " of factor ", factor,
                                                   ": its landmark ", assoc[feature], " has no other feature"));
  }
  return absl::OkStatus();
}

absl::StatusOr<int> SubmapGraph::SplitFeature(int factor, int feature) {
  if (absl::Status st = ValidateSplit(factor, feature); !st.ok()) return st;
  SubmapFactor& f = factors_[factor];
  landmarks_.push_back(TransformFrom(anchors_[f.start_anchor], f.submap.landmark(feature)));
  f.landmark_of_feature[feature] = num_landmarks() - 1;
  return num_landmarks() - 1;
}

}  // namespace subslam
