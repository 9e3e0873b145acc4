// The submap route through a PoseGraph (the project's own method, Combined SLAM and
// HybridSLAM's joining applied to a known-association graph): the odometry chain is cut
// into runs of consecutive poses; each run becomes one local map — its poses and the
// points they see solved by Gauss-Newton in the frame of its first pose, then reduced to
// one Gaussian over [last pose, points] (the interior poses marginalised); the local maps
// are joined by the exactly sparse EIF (backend/eif_joiner.h) with the graph's
// association — pairwise in a binary tree (backend/tree_joiner.h), each join iterated to
// convergence, or in order into one growing map; the interior poses are put back through
// their joined anchors.
//
// A local map is a Gaussian approximation of its run (the measurements linearised at the
// run's own solution, which is where dead reckoning is still good), so the joined
// estimate is close to the graph's minimum but not on it: a batch solve
// (batch_solver.h) started there finishes the job in a few iterations where one started
// from dead reckoning stalls.
//
// Needs: the odometry a chain through the poses in their order (pose i − 1 → pose i, the
// time order of iSAM / GTSAM files), no other pose-to-pose measurement, and point or
// bearing-range sightings (a point seen by bearings only is not fixed by one run).
#ifndef SUBSLAM_POSEGRAPH_SUBMAP_ROUTE_H_
#define SUBSLAM_POSEGRAPH_SUBMAP_ROUTE_H_

#include <map>
#include <string>

#include "absl/status/statusor.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/posegraph/pose_graph.h"

namespace subslam::posegraph {

struct SubmapRouteOptions {
  // Poses per local map (odometry steps per run): 1 joins every step as it comes (the
  // incremental EIF over the measurements in time order).
  int poses_per_map = 10;
  int max_local_iterations = 20;  // Gauss-Newton on each run, until the step is below 1e-9
  // The joiner; its association is forced to the graph's (known association).
  backend::EifJoinerOptions eif;
  // Join the local maps pairwise in a binary tree (TreeJoiner over EIF nodes) rather
  // than in order into one map. The tree's joins cost in proportion to their own size, so
  // the whole route costs O(n log n); in order, each relinearisation is of the whole map
  // joined so far. Both reach the same minimum after the polish.
  bool tree = true;

  absl::Status Validate() const;
};

struct SubmapRouteReport {
  int local_maps = 0;
  double local_map_seconds = 0.0;  // building the local maps
  double join_seconds = 0.0;       // joining them (the EIF's Join and Finish)
  backend::JoinerCounters counters;
  std::map<std::string, double> stage_times;  // the EIF's, per stage
};

// Sets every vertex estimate of `graph` (headings wrapped); `local_maps`, when given,
// receives the local maps as they were joined (features carry the graph's point index as
// truth_id, so `subslam join --known_association` joins them again). Errors: a graph the
// route does not apply to (see above), an invalid graph, a run whose Gauss-Newton fails.
absl::StatusOr<SubmapRouteReport> SolveBySubmaps(PoseGraph* graph, const SubmapRouteOptions& options,
                                                 std::vector<LocalSubmap>* local_maps = nullptr);

}  // namespace subslam::posegraph

#endif  // SUBSLAM_POSEGRAPH_SUBMAP_ROUTE_H_
