// Nonlinear least squares over a whole PoseGraph with Ceres: one residual block per
// measurement (measurement_residuals.h, whitened by the Cholesky factor of its
// information, analytic Jacobians), poses and points as parameter blocks, the gauge
// poses held constant (PoseGraph::GaugePoses). Ceres minimises ½ Σ ‖whitened residual‖²,
// the graph's `error`. Levenberg-Marquardt, Dogleg or Gauss-Newton and the tolerances
// come from backend::CeresSolveOptions (its robust loss applies to every measurement).
// Starts from the graph's vertex estimates: the file's, dead reckoning
// (InitializeByDeadReckoning) or another solver's.
#ifndef SUBSLAM_POSEGRAPH_BATCH_SOLVER_H_
#define SUBSLAM_POSEGRAPH_BATCH_SOLVER_H_

#include <string>

#include "absl/status/statusor.h"
#include "subslam/backend/ceres_solver.h"
#include "subslam/posegraph/pose_graph.h"

namespace subslam::posegraph {

struct BatchSolveReport {
  int iterations = 0;          // Ceres's, the start not counted
  double initial_error = 0.0;  // ½ Σ rᵀΩr
  double final_error = 0.0;
  double seconds = 0.0;     // Ceres's total time
  std::string termination;  // Ceres's termination type
};

// Optimises every vertex estimate of `graph` in place (headings wrapped after). Errors:
// invalid options, an invalid graph (PoseGraph::Validate), no usable solution.
absl::StatusOr<BatchSolveReport> SolveGraphWithCeres(PoseGraph* graph, const backend::CeresSolveOptions& options);

}  // namespace subslam::posegraph

#endif  // SUBSLAM_POSEGRAPH_BATCH_SOLVER_H_
