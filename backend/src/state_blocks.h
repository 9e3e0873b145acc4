// The state blocks of a selection of anchors and landmarks, for the joiners' marginal
// covariance queries (private to the back-end).
#ifndef SUBSLAM_BACKEND_SRC_STATE_BLOCKS_H_
#define SUBSLAM_BACKEND_SRC_STATE_BLOCKS_H_

#include <vector>

namespace subslam::backend {

struct StateBlocks {
  std::vector<int> offsets;  // where each block sits in the state (−1: not a state variable)
  std::vector<int> sizes;    // 3 (anchor) or 2 (landmark)
  int total = 0;             // rows of the selection
};

// The listed anchors, then the listed landmarks.
inline StateBlocks SelectBlocks(const std::vector<int>& anchors, const std::vector<int>& landmarks,
                                const std::vector<int>& anchor_offset, const std::vector<int>& landmark_offset) {
  StateBlocks b;
  for (int k : anchors) {
    b.offsets.push_back(anchor_offset[k]);
    b.sizes.push_back(3);
  }
  for (int j : landmarks) {
    b.offsets.push_back(landmark_offset[j]);
    b.sizes.push_back(2);
  }
  for (int s : b.sizes) b.total += s;
  return b;
}

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_SRC_STATE_BLOCKS_H_
