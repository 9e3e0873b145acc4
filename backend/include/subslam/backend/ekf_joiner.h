// Dense EKF map joining in covariance form (HybridSLAM §4, Brooks & Bailey; Tardós et al.'s
// sequential map joining): the baseline back-end of the RBPF-EKF and EKF-EIF
// configurations and the reference for cost comparisons with the EIF.
//
// State: the mean and the full dense covariance of the anchors P1 … Pk (P0, the initial
// pose, is fixed and not a variable) and the global landmarks, in the order they were
// created — the same variables as the EIF joiner, so the two can be compared block by
// block. Headings are continuous in the state and wrapped in graph().
//
// Per local map (z its mean [end pose, l1 … ln] in the start frame, Q its covariance):
//  1. data association: the same module as the EIF's (association/submap_association.h),
//     with the joint covariance read from the dense covariance;
//  2. augmentation with the local map transformed into the world frame through the start
//     anchor P_s: P_e = P_s ⊕ z_e, L_i = P_s ⊕ l_i, with first-order covariance
//     G_s P_ss G_sᵀ + G_z Q G_zᵀ and cross-covariance P_{x,s} G_sᵀ;
//  3. fusion of the features matched to existing landmarks, by `fusion`:
//     * kZeroNoiseConstraint (HybridSLAM §4, default): every feature is augmented, then
//       each matched copy c and its landmark L are fused by the zero-noise observation
//       c − L = 0 (a Kalman update with R = 0) and the copy is dropped;
//     * kConditionalUpdate: only the end pose and the new features are augmented (with
//       their marginal Q_NN); the matched features are a Kalman update with the local
//       map's measurement model linearised at the current estimate, conditioned on the
//       augmented part (h' = h_M − Q_MN Q_NN⁻¹ r_N, noise Q_MM − Q_MN Q_NN⁻¹ Q_NM). This is
//       the covariance form of the EIF's factor update on the same linearisation, so the
//       two agree to rounding (tested). kZeroNoiseConstraint differs from it only where
//       it linearises the matched rows (at the copy P̂_s ⊕ l_i instead of at L̂_j): the
//       two agree exactly when the matched features' innovations are zero;
//  4. with `keep_anchors` false ("replace the vehicle pose"), the start anchor is
//     marginalised out after the join: its estimate and marginal covariance are frozen
//     at that moment and the state holds only the current anchor and the landmarks.
// Cost per join: O(N²·m) for N state dimensions and m matched features, O(N²) memory —
// the reason for the EIF.
// Not thread-safe.
#ifndef SUBSLAM_BACKEND_EKF_JOINER_H_
#define SUBSLAM_BACKEND_EKF_JOINER_H_

#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/association/landmark_revision.h"
#include "subslam/association/submap_association.h"
#include "subslam/backend/map_joiner.h"

namespace subslam::backend {

enum class EkfFusion { kZeroNoiseConstraint, kConditionalUpdate };
const char* ToString(EkfFusion fusion);  // zero-noise, conditional
absl::StatusOr<EkfFusion> EkfFusionFromString(const std::string& name);

struct EkfJoinerOptions {
  association::SubmapAssociationOptions association;
  EkfFusion fusion = EkfFusion::kZeroNoiseConstraint;
  // false: marginalise each start anchor out once its local map is joined (the papers'
  // baseline); true: keep every anchor (the final trajectory then follows loop closures).
  bool keep_anchors = true;
  // Revisable association (landmark_revision.h): tested every revision.every_joins
  // joins, after a whole-map join and at the end. A merge is a zero-noise constraint
  // between the two landmarks (the copy dropped); a split, which the covariance form
  // cannot undo in place, joins every local map again from the first with the revised
  // association. Not under known association.
  association::LandmarkRevisionOptions revision;

  absl::Status Validate() const;
};

class EkfJoiner final : public MapJoiner {
 public:
  EkfJoiner(const Pose2& initial_pose, const EkfJoinerOptions& options);

  std::string Name() const override { return "ekf"; }
  // Revision passes until one changes nothing.
  absl::Status Finish() override;
  absl::Status ReviseAssociation() override;
  absl::Status MergeLandmarks(int keep, int drop) override;
  absl::Status SplitFeature(int factor, int feature) override;
  const SubmapGraph& graph() const override { return graph_; }
  // Blocks of the dense covariance; an anchor marginalised out (keep_anchors false) has
  // its covariance frozen when it was dropped and zero cross-covariance.
  Eigen::MatrixXd JointCovariance(const std::vector<int>& anchors, const std::vector<int>& landmarks) const override;
  const std::vector<int>& last_association() const override { return last_association_; }
  std::map<std::string, double> stage_times() const override { return times_; }
  const JoinerCounters& counters() const override { return counters_; }
  const association::SubmapAssociator& associator() const override { return associator_; }
  // Tree joining: `right` (an EkfJoiner) is augmented whole through this map's last
  // anchor and its matched landmarks are fused by zero-noise constraints (whatever
  // `fusion` says); both must keep their anchors.
  std::unique_ptr<MapJoiner> NewEmpty(const Pose2& initial_pose) const override;
  std::unique_ptr<MapJoiner> Clone() const override;
  absl::Status JoinMap(const MapJoiner& right) override;

  int state_dimension() const { return static_cast<int>(x_.size()); }
  // Where a variable sits in the state (−1: P0 or an anchor marginalised out).
  int anchor_offset(int k) const { return anchor_offset_[k]; }
  int landmark_offset(int j) const { return landmark_offset_[j]; }
  const Eigen::MatrixXd& covariance() const { return P_; }

 protected:
  absl::Status JoinLocalMap(const LocalSubmap& submap) override;

 private:
  // A pose (3) or point (2) block of a Gaussian given in the frame of an anchor.
  struct Block {
    int offset;
    int size;
  };
  // Appends variables P_s ⊕ z_b for the listed blocks of z ~ N(z, Q), given in the frame
  // of anchor `start` (poses composed, headings kept continuous; points transformed);
  // returns their state offsets.
  std::vector<int> Augment(int start, const Eigen::VectorXd& z, const Eigen::MatrixXd& Q,
                           const std::vector<Block>& blocks);
  // Error: the fusion's innovation covariance is not positive definite (nothing changed).
  absl::Status FuseZeroNoise(const std::vector<std::pair<int, int>>& copy_and_landmark_offsets);
  absl::Status FuseConditional(const LocalSubmap& s, int start, int end, const std::vector<int>& landmark_of_feature,
                               const std::vector<char>& matched);
  // Association of `s` (starting at anchor `start`) with the map, timed and counted: a
  // local map, or with `whole_map_groups` a whole map's summary (association::SubmapAssociator::Associate).
  association::SubmapAssociation AssociateAt(const LocalSubmap& s, int start,
                                             const std::vector<std::vector<int>>* whole_map_groups = nullptr);
  // Join with the given association (−1: a new landmark).
  absl::Status JoinAssociated(const LocalSubmap& s, std::vector<int> assoc);
  // Every local map of the graph joined again, from an empty map, with the graph's
  // association (landmarks renumbered in order of creation); counters and times kept.
  absl::Status Replay();
  // P −= W Wᵀ, kept symmetric.
  void SubtractOuter(const Eigen::MatrixXd& W);
  void DropVariable(int offset, int size);
  Pose2 StatePose(int k) const;
  void WriteBack();

  EkfJoinerOptions options_;
  SubmapGraph graph_;
  association::SubmapAssociator associator_;
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
  std::vector<int> anchor_offset_;  // −1 for P0 and dropped anchors
  std::vector<int> landmark_offset_;
  std::vector<Eigen::Matrix3d> frozen_covariance_;  // per anchor, when dropped
  std::vector<int> last_association_;
  std::map<std::string, double> times_;
  JoinerCounters counters_;
  double last_t_end_ = -1e300;
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_EKF_JOINER_H_
