// What every back-end that joins local maps into the global map offers the pipeline
// (apps/submap_slam.h) and the benchmarks, so they run on identical input:
// sequential joining of LocalSubmaps in time order, the estimate as a SubmapGraph (anchor
// k = start of local map k, in the world frame, P0 fixed at the initial pose; global
// landmarks; the association of every feature), and marginal covariances of anchors and
// landmarks.
#ifndef SUBSLAM_BACKEND_MAP_JOINER_H_
#define SUBSLAM_BACKEND_MAP_JOINER_H_

#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "subslam/graph/local_submap.h"
#include "subslam/graph/submap_graph.h"

namespace subslam::backend {

struct JoinerCounters {
  long joins = 0;
  long associated = 0;        // features matched to an existing landmark
  long new_landmarks = 0;
  long relinearizations = 0;  // Gauss-Newton iterations spent relinearising
  long jcbb_truncated = 0;    // joins whose JCBB search hit its node budget
  long rejected_joins = 0;    // failed validation: joined again without associations
};

class MapJoiner {
 public:
  virtual ~MapJoiner() = default;

  virtual std::string Name() const = 0;
  // Joins the next local map (its start anchor is the last anchor). Errors: an invalid
  // local map, a start time before the previous end, or a numerical failure.
  virtual absl::Status Join(const LocalSubmap& submap) = 0;
  // Called once after the last join (relinearisation at the end, if configured).
  virtual absl::Status Finish() = 0;

  // The estimate (headings wrapped) and the association table.
  virtual const SubmapGraph& graph() const = 0;
  int num_anchors() const { return graph().num_anchors(); }
  int num_landmarks() const { return graph().num_landmarks(); }
  Pose2 anchor(int k) const { return graph().anchors()[k]; }
  Eigen::Vector2d landmark(int j) const { return graph().landmarks()[j]; }

  // Marginal covariances (anchor 0 is fixed: zero).
  virtual Eigen::MatrixXd JointCovariance(const std::vector<int>& anchors,
                                          const std::vector<int>& landmarks) const = 0;
  Eigen::Matrix3d AnchorCovariance(int k) const { return JointCovariance({k}, {}); }
  Eigen::Matrix2d LandmarkCovariance(int j) const { return JointCovariance({}, {j}); }

  // For the last joined map: the global landmark of each feature.
  virtual const std::vector<int>& last_association() const = 0;
  // Accumulated wall time per stage (seconds).
  virtual std::map<std::string, double> stage_times() const = 0;
  virtual const JoinerCounters& counters() const = 0;
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_MAP_JOINER_H_
