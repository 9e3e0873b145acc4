// The `subslam solve` job: a chosen set of solvers on one PoseGraph
// (posegraph/pose_graph.h), side by side, each from the same start.
//
// Methods (SolveMethodNames, in this order):
//   lm, dogleg, gn   Ceres batch (posegraph/batch_solver.h: Levenberg-Marquardt, Dogleg,
//                    Gauss-Newton) from the start estimate;
//   eif              the incremental EIF over the measurements in time order: the submap
//                    route with one odometry step per local map (posegraph/submap_route.h);
//   submaps          the submap route with SolveOptions::poses_per_map poses per local map,
//                    joined in a binary tree (SolveOptions::tree_joining);
//   submaps-lm       the submap route, then Levenberg-Marquardt from its estimate.
// The start estimate: dead reckoning (posegraph::InitializeByDeadReckoning), or the file's
// vertex estimates (`initial_from_file`); the submap routes start from dead reckoning
// within each local map either way.
//
// Outputs (SolveOptions::out_dir, when set): METHOD.g2o per method that ran (the graph
// with its solution; bearing-range measurements as Cartesian sightings, which g2o's
// format needs), METHOD_submaps.jsonl for the submap routes when asked, and report.json: the graph's counts and
// reading, the start's error, and under `methods` one entry per method — name, status ("ok" or why it did not run),
// error (½ Σ rᵀΩr), chi2 (Σ rᵀΩr), iterations, seconds, peak_rss_mb, and what the method
// reports beyond (Ceres's termination, the route's local maps and stage times).
#ifndef SUBSLAM_PIPELINE_SOLVE_PIPELINE_H_
#define SUBSLAM_PIPELINE_SOLVE_PIPELINE_H_

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "subslam/backend/ceres_solver.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/posegraph/pose_graph.h"

namespace subslam::pipeline {

const std::vector<std::string>& SolveMethodNames();

struct SolveOptions {
  std::vector<std::string> methods;  // empty: every method
  bool initial_from_file = false;    // start from the file's estimates (it must hold them all)
  // Poses per local map of the submap route (`submaps`, `submaps-lm`): runs short enough
  // that dead reckoning holds within them, long enough that a join's fixed cost is shared
  // (bench/RESULTS.md, "Graph solvers").
  int poses_per_map = 20;
  // The submap route joins its local maps in a binary tree (`submaps`, `submaps-lm`;
  // SubmapRouteOptions::tree); false: in order into one map. `eif` joins in order always:
  // it is the incremental EIF.
  bool tree_joining = true;
  backend::CeresSolveOptions ceres = [] {
    backend::CeresSolveOptions o;
    o.max_iterations = 200;
    return o;
  }();
  backend::EifJoinerOptions eif;
  std::string out_dir;  // empty: write nothing
  // How the job was invoked, recorded as report.json's "invocation" (the tool: its command
  // line and every flag's value).
  nlohmann::json invocation;
  // Also write the submap routes' local maps (METHOD_submaps.jsonl in out_dir), so that
  // other back-ends join the same maps (`subslam join --known_association`).
  bool write_local_maps = false;
  // What the report says the graph is (file, format, noise reading).
  nlohmann::json source;

  // Known methods, poses_per_map >= 1, valid Ceres and EIF options.
  absl::Status Validate() const;
};

struct SolveMethodResult {
  std::string name;
  std::string status = "ok";  // or why it did not run
  // Whether the method met its own convergence test; false when Ceres stopped at its
  // iteration limit (termination NO_CONVERGENCE: raise SolveOptions::ceres.max_iterations).
  bool converged = true;
  double error = 0.0, chi2 = 0.0;
  int iterations = 0;
  double seconds = 0.0;
  double peak_rss_mb = 0.0;  // the process's peak resident memory while the method ran
  nlohmann::json details;
};

struct SolveResult {
  double initial_error = 0.0, initial_chi2 = 0.0;  // of the start estimate
  std::vector<SolveMethodResult> methods;
  nlohmann::json report;
};

// Errors: an unknown method, an invalid graph, a start the graph cannot give (no
// estimates in the file, dead reckoning impossible), unwritable outputs. A method that
// does not apply to the graph (the submap route on a graph with loop-closing odometry)
// is listed with its reason.
absl::StatusOr<SolveResult> RunSolve(const posegraph::PoseGraph& graph, const SolveOptions& options);

// The printed table: one row per method.
std::string SolveTable(const SolveResult& result);

}  // namespace subslam::pipeline

#endif  // SUBSLAM_PIPELINE_SOLVE_PIPELINE_H_
