// What every back-end that joins local maps into the global map offers the pipeline
// (pipeline/submap_slam.h) and the benchmarks, so they run on identical input:
// sequential joining of LocalSubmaps in time order, the estimate as a SubmapGraph (anchor
// k = start of local map k, in the world frame, P0 fixed at the initial pose; global
// landmarks; the association of every feature), and marginal covariances of anchors and
// landmarks.
#ifndef SUBSLAM_BACKEND_MAP_JOINER_H_
#define SUBSLAM_BACKEND_MAP_JOINER_H_

#include <Eigen/Core>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/association/submap_association.h"
#include "subslam/core/local_submap.h"
#include "subslam/core/submap_graph.h"

namespace subslam::backend {

struct JoinerCounters {
  long joins = 0;
  long associated = 0;  // features matched to an existing landmark
  long new_landmarks = 0;
  long relinearizations = 0;           // Gauss-Newton iterations spent relinearising
  long relinearizations_diverged = 0;  // stopped at their best iterate (cost rises in a row)
  // Gauss-Newton runs stopped by a predicted step, before another factorisation.
  long relinearizations_predicted_converged = 0;
  // Relinearisations set off after a join by each trigger (the EIF's
  // relinearize_heading_change and relinearize_linearization_chi2).
  long relinearized_on_heading = 0;
  long relinearized_on_linearization_error = 0;
  long jcbb_truncated = 0;  // joins whose JCBB search hit its node budget
  // Loop closures dropped under an uncertain start anchor: too few pairings, or ambiguous.
  long loop_closures_thin = 0;
  long loop_closures_ambiguous = 0;
  // Loop closures made under an uncertain start anchor that the next local maps did or
  // did not confirm (association.loop_confirmation_maps: the sequential EIF, and every
  // whole-map join); unconfirmed ones were undone.
  long loop_closures_confirmed = 0;
  long loop_closures_unconfirmed = 0;
  // Closing maps of unconfirmed loop closures joined again with their first association
  // (the joiner restored to the state it was made in), not a second search.
  long associations_replayed = 0;
  // Local maps found rotated beyond their covariance and joined widened
  // (association::SubmapAssociationOptions::map_rotation_sigma_rad).
  long maps_widened = 0;
  // Local maps joined with their features widened by the maps' measured rotation spread
  // (association::SubmapAssociationOptions::map_rotation_spread_probability).
  long maps_spread = 0;
  long rejected_joins = 0;  // failed validation: joined again without associations
  // Revisions of the association (landmark_revision.h): passes run, landmarks merged into
  // another, features split off to a landmark of their own.
  long revision_passes = 0;
  long landmarks_merged = 0;
  long features_split = 0;
  // EIF factor maintenance: joins absorbed by an incremental update of the factor, full
  // factorisations (of them, those that reused the last symbolic analysis: the same
  // pattern, as in Gauss-Newton iterations; those ordered by nested dissection), and
  // updates that failed and fell back to one.
  long incremental_updates = 0;
  long full_factorizations = 0;
  long nested_dissection_factorizations = 0;
  long reused_analyses = 0;
  long failed_updates = 0;
  // Association's candidate landmarks, those dropped under the joiner's marginal bound
  // before any recovery, and the recovery's work: columns of L⁻¹ solved, rows reached.
  long candidates = 0;
  long candidates_bounded_out = 0;
  long covariance_columns = 0;
  long covariance_reach = 0;

  JoinerCounters& operator+=(const JoinerCounters& o);
  JoinerCounters operator-(const JoinerCounters& o) const;  // the change from o

  // Every counter with its name in the reports (report.json: "join_" + name in a run's
  // estimator counters, name in `subslam join`'s counts), in one list.
  struct Field {
    const char* name;
    long JoinerCounters::*member;
  };
  static std::span<const Field> Fields();
};

// What one join did, as a solver's summary reports one solve: the local map, the wall
// time, the outcome, and the change of the joiner's counters over it (features associated,
// new landmarks, Gauss-Newton iterations, merges, loop-closure decisions, …).
struct JoinSummary {
  int map_id = -1;
  double seconds = 0.0;
  absl::Status status;
  JoinerCounters counts;
  // The joint innovation d² of the pairings the join's associations chose, and its
  // degrees of freedom (association::SubmapAssociation::pairings_d2; 0 dof: none, or a joiner that
  // does not report it): the local map against the map, a χ² variable for consistent maps.
  double association_d2 = 0.0;
  long association_dof = 0;
};

// What a joiner reports beyond JoinerCounters and its stage times, named as report.json
// names them (e.g. the Ceres back-end's solves, iterations and costs, and Ceres's
// termination): figures are numbers, notes text. Empty for most joiners.
struct JoinerExtras {
  std::map<std::string, double> figures;
  std::map<std::string, std::string> notes;
};

class MapJoiner {
 public:
  virtual ~MapJoiner() = default;

  virtual std::string Name() const = 0;
  // Joins the next local map (its start anchor is the last anchor) and records what the
  // join did (last_join()). Errors: an invalid local map, a start time before the
  // previous end, or a numerical failure.
  absl::Status Join(const LocalSubmap& submap);
  const JoinSummary& last_join() const { return last_join_; }
  // Called once after the last join (relinearisation at the end, if configured).
  virtual absl::Status Finish() = 0;

  // The estimate (headings wrapped) and the association table.
  virtual const SubmapGraph& graph() const = 0;
  int num_anchors() const { return graph().num_anchors(); }
  int num_landmarks() const { return graph().num_landmarks(); }
  Pose2 anchor(int k) const { return graph().anchors()[k]; }
  Eigen::Vector2d landmark(int j) const { return graph().landmarks()[j]; }

  // Marginal covariances (anchor 0 is fixed: zero).
  virtual Eigen::MatrixXd JointCovariance(const std::vector<int>& anchors, const std::vector<int>& landmarks) const = 0;
  Eigen::Matrix3d AnchorCovariance(int k) const { return JointCovariance({k}, {}); }
  Eigen::Matrix2d LandmarkCovariance(int j) const { return JointCovariance({}, {j}); }
  // Every anchor's and every landmark's marginal at once (the final trajectory's and the
  // map's covariances): by default one JointCovariance per variable; a joiner may answer
  // more cheaply in bulk (the EIF does, from its inverse on the factor's pattern).
  virtual std::vector<Eigen::Matrix3d> AnchorCovariances() const;
  virtual std::vector<Eigen::Matrix2d> LandmarkCovariances() const;

  // The last anchor and its marginal covariance: the reference of the online pose. A
  // joiner may answer without forming the whole map (the tree joiner does), and without a
  // decision it has not taken yet (the EIF: a loop closure that waits for confirmation).
  virtual Pose2 LastAnchor() const { return anchor(num_anchors() - 1); }
  virtual Eigen::Matrix3d LastAnchorCovariance() const { return AnchorCovariance(num_anchors() - 1); }

  // For the last joined map: the global landmark of each feature.
  virtual const std::vector<int>& last_association() const = 0;
  // Accumulated wall time per stage (seconds).
  virtual std::map<std::string, double> stage_times() const = 0;
  virtual const JoinerCounters& counters() const = 0;
  virtual JoinerExtras Extras() const { return {}; }
  // What association keeps per landmark (signatures, truth ids).
  virtual const association::SubmapAssociator& associator() const = 0;

  // Revisable association (landmark_revision.h). ReviseAssociation runs one pass: the
  // merge and split tests on the current estimate, their decisions applied and the
  // estimate solved again; joiners run it on their own schedule too. MergeLandmarks and
  // SplitFeature apply one decision asked for from outside (tools, tests): errors for
  // unknown landmarks, factors or features, for a pair one local map holds as distinct,
  // and for a landmark with a single feature (nothing to split from). A joiner that
  // cannot revise (it keeps no factors to re-key) answers Unimplemented.
  virtual absl::Status ReviseAssociation() { return absl::OkStatus(); }
  virtual absl::Status MergeLandmarks(int /*keep*/, int /*drop*/) {
    return absl::UnimplementedError(Name() + " cannot merge landmarks");
  }
  virtual absl::Status SplitFeature(int /*factor*/, int /*feature*/) {
    return absl::UnimplementedError(Name() + " cannot split features");
  }

  // Tree joining (backend/tree_joiner.h). A joiner that supports it returns an empty
  // joiner of its kind and options whose anchor 0 is `initial_pose`, a deep copy, and
  // joins a whole map `right` of its kind whose anchor 0 (the identity: right's frame)
  // is this joiner's last anchor: right's landmarks are associated with this map's,
  // its anchors and landmarks are brought into this frame, and its factors are added.
  virtual std::unique_ptr<MapJoiner> NewEmpty(const Pose2& /*initial_pose*/) const { return nullptr; }
  virtual std::unique_ptr<MapJoiner> Clone() const { return nullptr; }
  virtual absl::Status JoinMap(const MapJoiner& /*right*/) {
    return absl::UnimplementedError(Name() + " cannot join whole maps");
  }

 protected:
  // The join itself, which each joiner implements (Join wraps it with its summary).
  virtual absl::Status JoinLocalMap(const LocalSubmap& submap) = 0;
  // An association the join made: its pairings' joint d² and dof, summed into the summary.
  void RecordAssociationInnovation(double d2, long dof) {
    association_d2_ += d2;
    association_dof_ += dof;
  }

 private:
  JoinSummary last_join_;
  double association_d2_ = 0.0;  // of the join in progress
  long association_dof_ = 0;
};

// Revision passes on `joiner` until one changes nothing (at most `max_passes`: merges and
// splits could alternate), what a joiner's Finish() runs.
absl::Status ReviseUntilSettled(MapJoiner& joiner, int max_passes = 50);

// The map `j` seen as one local map from its anchor 0 (which must be the identity):
// mean [last anchor, every landmark], their joint marginal covariance, each landmark's
// mean signature and truth id; id, start and end times from j's first and last local
// maps. What a tree join associates with the map on its left. Without `with_covariance`
// the covariance is left empty (0 × 0): all that association by truth ids reads, without
// recovering the joint marginal.
LocalSubmap SummarizeAsLocalSubmap(const MapJoiner& j, bool with_covariance = true);
// The summary of `right` for a whole-map join onto a map that ends at `left_t_end` (s);
// an error if right starts before.
absl::StatusOr<LocalSubmap> SummarizeForJoin(const MapJoiner& right, double left_t_end, bool with_covariance = true);

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_MAP_JOINER_H_
