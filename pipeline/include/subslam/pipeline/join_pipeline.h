// The `subslam join` job: run a back-end alone on recorded local maps (submaps.jsonl), so
// back-ends can be compared on identical input and local maps built elsewhere joined.
// The back-end is the one `subslam run` builds (MakeJoiner), joined in the same way.
//
// Outputs (JoinOptions::out_dir, when set):
//   anchors.csv     t,x,y,theta,cov_xx,cov_xy,cov_xt,cov_yy,cov_yt,cov_tt (the trajectory
//                   columns), row k = anchor k: the start of local map k (anchor 0: the
//                   initial pose, fixed) and the end of map k − 1, at that time;
//   landmarks.csv   the global map (id,x,y,cov_xx,cov_xy,cov_yy);
//   graph.g2o       the submap graph in g2o text, its local maps as their marginal blocks
//                   (posegraph/submap_marginals_graph.h);
//   joins.csv       one row per join: map_id,seconds, then the change of every joiner
//                   counter over it (JoinerCounters::Fields' names);
//   report.json     configuration, counts, time per stage, and — when ground truth is given —
//                   anchor and landmark errors.
#ifndef SUBSLAM_PIPELINE_JOIN_PIPELINE_H_
#define SUBSLAM_PIPELINE_JOIN_PIPELINE_H_

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "subslam/core/estimates.h"
#include "subslam/core/local_submap.h"
#include "subslam/io/dataset.h"
#include "subslam/pipeline/submap_slam.h"

namespace subslam::pipeline {

struct JoinOptions {
  // The back-end (not kNone).
  BackendOptions backend = [] {
    BackendOptions o;
    o.kind = Backend::kEif;
    return o;
  }();
  Pose2 initial_pose;   // anchor 0
  std::string out_dir;  // empty: write nothing
  // How the job was invoked, recorded as report.json's "invocation" (the tool: its command
  // line and every flag's value).
  nlohmann::json invocation;
  // Ground truth for the report (optional): true poses (anchors compared at their times)
  // and true landmarks (map errors), and of those the ones the sensor saw, which the map
  // metric matches estimates against (eval::ObservedTruthLandmarks; empty: all).
  std::vector<io::TimedPose> truth_poses;
  std::vector<io::TruthLandmark> truth_landmarks;
  std::vector<io::TruthLandmark> observed_truth_landmarks;
  // GPS fixes of the data set the maps were built on (optional): the anchors, interpolated
  // between them, are compared with them after a rigid alignment (metrics gps_anchors and
  // gps_anchors_online).
  std::vector<io::TimedPoint> gps;
};

// Association against truth_id (when the local maps carry them), from a joined graph's
// association table (factors in time order).
struct AssociationVsTruth {
  // Pairs of features that
  // share a true landmark and were joined to the same global landmark (correct), to
  // different ones (missed), and pairs joined to the same global landmark whose true
  // landmarks differ (wrong).
  long correct = 0, missed = 0, wrong = 0;
  // Of the wrong ones: those where a feature joined to the global landmark was already
  // mixed by the front-end (its detections came from ≥ 2 true landmarks; known when the
  // local maps carry truth_landmarks) — the back-end's own wrong merges are the rest.
  long wrong_with_mixed_feature = 0;
  // Wrong merges counted by all the true landmarks of each feature's detections (when the
  // local maps carry truth_ids; else its majority id): the features joined to one global
  // landmark fall into groups linked by a shared true landmark, and every group beyond
  // the first is a wrong merge. A merge of two features that mix the same two trees with
  // different majorities counts in `wrong`, not here: this is the lower bound, `wrong`
  // the upper.
  long wrong_sharing_no_true_landmark = 0;
  // Re-observations of a true landmark, by how long ago it was last seen: within the
  // last two local maps (recent) or earlier (a loop), and whether they were joined to the
  // same global landmark as then.
  long recent_merged = 0, recent_missed = 0, loop_merged = 0, loop_missed = 0;
};

// Counts them; features without a true id (unknown or false alarm) are left out. The true
// ids are the graph's own local maps', or with `labelled` those of the local map there
// with the same id and the feature with the same local id (a run labels its local maps
// after joining them); features `labelled` does not hold are left out.
AssociationVsTruth CountAssociationsAgainstTruth(const SubmapGraph& graph,
                                                 const std::vector<LocalSubmap>& labelled = {});

struct JoinResult {
  int local_maps = 0;
  std::vector<double> anchor_times;  // s
  Trajectory anchors;                // with marginal covariances
  // Each anchor as the join that made it left it, with its marginal then (the anchor an
  // online pose composes with until the next join; row 0: the initial pose).
  Trajectory anchors_online;
  std::vector<LandmarkEstimate> landmarks;
  double wall_seconds = 0.0;                // joining and Finish (a Ceres solve included), not the online records
  AssociationVsTruth association;           // against the local maps' truth ids
  std::vector<backend::JoinSummary> joins;  // what each join did, in order
  nlohmann::json report;
};

absl::StatusOr<JoinResult> RunJoin(const std::vector<LocalSubmap>& submaps, const JoinOptions& options);

// A short human-readable summary of a join, in the style of the run's SummaryTable: only
// the figures the inputs allow (no association counts for maps without true ids).
std::string JoinSummaryTable(const JoinResult& result);

}  // namespace subslam::pipeline

#endif  // SUBSLAM_PIPELINE_JOIN_PIPELINE_H_
