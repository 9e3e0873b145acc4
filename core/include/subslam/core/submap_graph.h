// The global problem the back-ends solve (docs/conventions.md, "The submap factor"):
// anchor poses P0 … Pk in the world frame (P0 = the initial pose, fixed; Pk = the end pose
// of local map k), global landmarks, and one factor per local map linking its start and
// end anchors and the global landmarks its features were associated with.
//
// Factor k: local map k (a LocalSubmap), start anchor k, end anchor k + 1, and for each of
// its features the global landmark index (the association table).
#ifndef SUBSLAM_CORE_SUBMAP_GRAPH_H_
#define SUBSLAM_CORE_SUBMAP_GRAPH_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/core/local_submap.h"
#include "subslam/core/pose2.h"

namespace subslam {

struct SubmapFactor {
  LocalSubmap submap;
  int start_anchor = 0;
  int end_anchor = 1;
  std::vector<int> landmark_of_feature;  // global landmark index per local feature
};

class SubmapGraph {
 public:
  explicit SubmapGraph(const Pose2& initial_pose) : anchors_{initial_pose} {}

  int AddAnchor(const Pose2& pose) {
    anchors_.push_back(pose);
    return static_cast<int>(anchors_.size()) - 1;
  }
  int AddLandmark(const Eigen::Vector2d& position) {
    landmarks_.push_back(position);
    return static_cast<int>(landmarks_.size()) - 1;
  }
  void AddFactor(SubmapFactor factor) { factors_.push_back(std::move(factor)); }

  // Revision of the association table (association/landmark_revision.h decides when); each
  // checks its request first and changes nothing on an error.
  // MergeLandmarks: every feature of landmark `drop` becomes a feature of `keep` (whose
  // position stays until the joiner solves again); `drop` is erased and the landmarks
  // after it move down by one (RenumberAfterMerge). Errors (ValidateMerge): an unknown or
  // equal pair, or a pair that one local map holds as two distinct features.
  absl::Status ValidateMerge(int keep, int drop) const;
  absl::Status MergeLandmarks(int keep, int drop);
  static int RenumberAfterMerge(int landmark, int keep, int drop) {
    if (landmark == drop) return keep;
    return landmark > drop ? landmark - 1 : landmark;
  }
  // SplitFeature: feature `feature` of factor `factor` leaves its landmark for a new one
  // at the feature's own position through its start anchor (appended; its index is
  // returned). Errors (ValidateSplit): an unknown factor or feature, or a landmark that
  // has no other feature (nothing to split from).
  absl::Status ValidateSplit(int factor, int feature) const;
  absl::StatusOr<int> SplitFeature(int factor, int feature);
  // How many features (over all factors) each landmark has.
  std::vector<int> FeatureCounts() const;
  // Whether some factor holds both landmarks as features.
  bool CoObserved(int a, int b) const;

  int num_anchors() const { return static_cast<int>(anchors_.size()); }
  int num_landmarks() const { return static_cast<int>(landmarks_.size()); }
  const std::vector<Pose2>& anchors() const { return anchors_; }
  const std::vector<Eigen::Vector2d>& landmarks() const { return landmarks_; }
  const std::vector<SubmapFactor>& factors() const { return factors_; }
  Pose2& anchor(int k) { return anchors_[k]; }
  Eigen::Vector2d& landmark(int j) { return landmarks_[j]; }

 private:
  std::vector<Pose2> anchors_;
  std::vector<Eigen::Vector2d> landmarks_;
  std::vector<SubmapFactor> factors_;
};

}  // namespace subslam

#endif  // SUBSLAM_CORE_SUBMAP_GRAPH_H_
