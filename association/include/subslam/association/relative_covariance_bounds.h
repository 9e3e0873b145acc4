// Upper bounds on the covariance of the difference of two landmarks, C_ab = Cov(l_a − l_b),
// kept between merge passes so that a pair far outside the merge test's gate is not
// asked for its joint marginal again (landmark_revision.h, FindLandmarkMerges).
//
// Why they stay bounds: while the information matrix only grows (joins add factors), every
// marginal covariance, and every covariance of a linear function of the state such as
// l_a − l_b, only shrinks: Λ' ⪰ Λ gives Λ'⁻¹ ⪯ Λ⁻¹. So a C_ab recovered earlier bounds
// today's from above, and d² = Δᵀ C_ab⁻¹ Δ computed with it bounds today's d² from below
// for the current difference Δ of the estimates. A joiner clears the bounds wherever Λ
// may have lost information or changed its layout: a relinearisation (every factor
// moved), a revision (merges renumber the landmarks, splits take features away), an
// undone join.
//
// Usage (one per joiner; FindLandmarkMerges fills it):
//   RelativeCovarianceBounds bounds;
//   FindLandmarkMerges(graph, marginals, pair_covariance, options, radius, touched, loops, &bounds);
//   ...  // joins that only add factors
//   FindLandmarkMerges(...);  // skips the pairs whose bound already puts them outside the gate
//   bounds.Clear();           // after a relinearisation
#ifndef SUBSLAM_ASSOCIATION_RELATIVE_COVARIANCE_BOUNDS_H_
#define SUBSLAM_ASSOCIATION_RELATIVE_COVARIANCE_BOUNDS_H_

#include <Eigen/Core>
#include <cstdint>

#include "absl/container/flat_hash_map.h"

namespace subslam::association {

class RelativeCovarianceBounds {
 public:
  // The bound on Cov(l_a − l_b) (the same for (b, a)), or nullptr if none is kept.
  const Eigen::Matrix2d* Find(int a, int b) const {
    const auto it = bounds_.find(Key(a, b));
    return it == bounds_.end() ? nullptr : &it->second;
  }
  // Keeps C = Cov(l_a − l_b) as recovered now.
  void Insert(int a, int b, const Eigen::Matrix2d& C) { bounds_[Key(a, b)] = C; }
  void Clear() { bounds_.clear(); }
  size_t size() const { return bounds_.size(); }

 private:
  static uint64_t Key(int a, int b) {
    const auto lo = static_cast<uint32_t>(a < b ? a : b), hi = static_cast<uint32_t>(a < b ? b : a);
    return (static_cast<uint64_t>(lo) << 32) | hi;
  }
  absl::flat_hash_map<uint64_t, Eigen::Matrix2d> bounds_;
};

}  // namespace subslam::association

#endif  // SUBSLAM_ASSOCIATION_RELATIVE_COVARIANCE_BOUNDS_H_
