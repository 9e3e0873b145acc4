// Binary-tree map joining (Combined SLAM §6.2; Fast Map Joining; Paz et al.'s
// divide-and-conquer SLAM): local maps are joined pairwise, level by level, until one map
// remains, instead of each into one ever-growing global map.
//
// Every node of the tree is a map of the node kind — dense EKF (backend/ekf_joiner.h) or
// sparse EIF (backend/eif_joiner.h) — in the frame of its first anchor; a leaf is one
// local map. Two neighbouring nodes share a boundary anchor (the left's last anchor is
// the right's anchor 0), and joining them (MapJoiner::JoinMap) associates the right's
// landmarks with the left's (the shared association module, every left landmark near a
// right feature a candidate), brings the right into the left's frame and fuses.
//
// Rotated local maps: the grouped association of a whole-map join does not test a map's
// rotation (association::SubmapAssociationOptions::map_rotation_sigma_rad), so each new local map is
// tested before it becomes a leaf, against the local map before it alone (that map's leaf:
// the new map starts at its last anchor, and the landmarks it shares with it are what the
// test fits the rotation to). A map that fails becomes a leaf rotated back and widened
// (association::RotatedBack), as the sequential joiners join it. In the tree every map but the first
// starts the right node of exactly one join, which does not test it. The test is the
// sequential joiners' against one map only (they look at the last recent_maps maps, so a
// map after a map of no feature is tested there and not here), with the relative
// uncertainty of two consecutive maps instead of the global marginals. Its time is the
// stage "leaf_rotation_test".
//
// Modes:
//  * running (default): a binary counter — each new leaf is pushed on a stack and the
//    two top nodes are joined while they have the same level, so the partial tree is
//    always up to date with O(log n) nodes; the whole map is available at any time by
//    folding the stack right to left (on demand, cached until the next local map), and
//    the online anchor is the stack's nodes chained end to start (exact until a loop
//    between two nodes is closed by their join), or the folded map's (an option);
//  * batch: leaves are kept, and Finish() joins them level by level (pairs (0,1), (2,3),
//    …; an odd node is carried up).
// For n = 2^k local maps both build the same tree.
//
// The result equals sequential joining within the linearisation error (both are first-
// order), and exactly at convergence for the EIF relinearised at the end (tested).
// Not thread-safe.
#ifndef SUBSLAM_BACKEND_TREE_JOINER_H_
#define SUBSLAM_BACKEND_TREE_JOINER_H_

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "subslam/association/map_rotation_spread.h"
#include "subslam/association/submap_association.h"
#include "subslam/backend/map_joiner.h"
#include "subslam/core/local_submap.h"

namespace subslam::backend {

struct TreeJoinerOptions {
  bool running = true;  // false: batch (the tree is built at Finish())
  // The online anchor (LastAnchor) from the whole map folded on demand instead of the
  // stack's nodes chained end to start. Chained, the anchor cannot use the landmarks of
  // the older nodes until their join, and in a small world revisited all the time (a
  // room) it drifts like dead reckoning between joins; folded, it is the sequential
  // joiner's, at the price of folding the stack after every local map (docs/limits.md:
  // about twice the back-end's time on a room, ten times on a park).
  bool online_anchor_from_whole_map = false;
};

class TreeJoiner final : public MapJoiner {
 public:
  // `prototype`: an empty joiner of the node kind with its options, whose anchor 0 is the
  // initial pose (e.g. an EkfJoiner with keep_anchors, or an EifJoiner).
  TreeJoiner(std::unique_ptr<MapJoiner> prototype, const TreeJoinerOptions& options);

  std::string Name() const override { return "tree-" + prototype_->Name(); }
  // Joins what remains into one map (and lets the root finish, e.g. relinearise).
  absl::Status Finish() override;

  // The whole map: after Finish() the root; before, the stack folded on demand.
  const SubmapGraph& graph() const override { return Whole().graph(); }
  Eigen::MatrixXd JointCovariance(const std::vector<int>& anchors, const std::vector<int>& landmarks) const override {
    return Whole().JointCovariance(anchors, landmarks);
  }
  std::vector<Eigen::Matrix3d> AnchorCovariances() const override { return Whole().AnchorCovariances(); }
  std::vector<Eigen::Matrix2d> LandmarkCovariances() const override { return Whole().LandmarkCovariances(); }
  const std::vector<int>& last_association() const override { return Whole().last_association(); }
  const association::SubmapAssociator& associator() const override { return Whole().associator(); }
  // Chained over the nodes (no fold), or the folded map's (online_anchor_from_whole_map).
  Pose2 LastAnchor() const override;
  Eigen::Matrix3d LastAnchorCovariance() const override;
  // Summed over the nodes (each holds its subtree's), plus "fold" for on-demand folds and
  // "leaf_rotation_test" for the rotation tests of new local maps.
  std::map<std::string, double> stage_times() const override;
  const JoinerCounters& counters() const override;
  // The whole map's (e.g. the Ceres root's solve figures).
  JoinerExtras Extras() const override { return Whole().Extras(); }

  // An empty tree of the same node kind and options.
  std::unique_ptr<MapJoiner> NewEmpty(const Pose2& initial_pose) const override;

  int num_nodes() const { return static_cast<int>(nodes_.size()); }
  int tree_joins() const { return tree_joins_; }  // JoinMap calls that built the tree

 protected:
  absl::Status JoinLocalMap(const LocalSubmap& submap) override;

 private:
  struct Node {
    std::unique_ptr<MapJoiner> map;
    int level = 0;
    // map's LastAnchorCovariance(), kept until map changes (Chain asks at every local map,
    // and only the newest nodes change).
    mutable std::optional<Eigen::Matrix3d> last_anchor_covariance;
  };
  const MapJoiner& Whole() const;
  // `submap` rotated back and widened when the rotation test against the previous local
  // map's leaf finds it rotated (nullopt: joined as it is, or the first map). Records the
  // test's fit in rotation_spread_.
  std::optional<LocalSubmap> RotatedAgainstPrevious(const LocalSubmap& submap);
  // The node kind's association options ask for the rotation test.
  bool TestsRotation() const;
  // The last anchor chained over the nodes' last anchors, and its covariance (first order)
  // unless `covariance` is null.
  void Chain(Pose2* pose, Eigen::Matrix3d* covariance) const;

  std::unique_ptr<MapJoiner> prototype_;
  TreeJoinerOptions options_;
  Pose2 initial_pose_;
  std::vector<Node> nodes_;                   // left to right (running: levels strictly decreasing)
  std::unique_ptr<MapJoiner> previous_leaf_;  // a copy of the last local map's leaf
  long maps_widened_ = 0;                     // leaves joined rotated back and widened
  // The maps' rotation spread over the leaves' rotation tests (map_rotation_spread.h); the
  // leaves count the maps joined widened by it.
  association::MapRotationSpread rotation_spread_;
  double rotation_test_seconds_ = 0.0;
  bool finished_ = false;
  int tree_joins_ = 0;
  absl::Status status_;
  mutable std::unique_ptr<MapJoiner> folded_;  // cache of the folded stack
  mutable double fold_seconds_ = 0.0;
  mutable JoinerCounters counters_;
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_TREE_JOINER_H_
