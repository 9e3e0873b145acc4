// One-to-one matching of estimated landmarks to true landmarks within a radius: the
// matching with the most pairs, and among those the smallest sum of squared distances
// (minimum-cost maximum flow on the bipartite graph of pairs within the radius).
//
// A greedy matching, nearest pair first, is maximal but not maximum: on a map displaced
// by a metre or two, the nearest-first choice can take the one true landmark a second
// estimate could reach while the first had another within the radius, and the second is
// then counted surplus although each estimate has a true landmark of its own.
#ifndef SUBSLAM_EVAL_LANDMARK_MATCHING_H_
#define SUBSLAM_EVAL_LANDMARK_MATCHING_H_

#include <Eigen/Core>
#include <utility>
#include <vector>

namespace subslam::eval {

struct LandmarkMatching {
  std::vector<std::pair<int, int>> pairs;  // (estimate index, truth index), by estimate index
  std::vector<char> near_truth;            // per estimate: some true landmark within the radius
};

LandmarkMatching MatchWithinRadius(const std::vector<Eigen::Vector2d>& estimates,
                                   const std::vector<Eigen::Vector2d>& truth, double radius_m);

}  // namespace subslam::eval

#endif  // SUBSLAM_EVAL_LANDMARK_MATCHING_H_
