// Ceres's solver options and robust loss from CeresSolveOptions, shared by the solvers
// that run Ceres (the submap graph's, backend/ceres_solver.h, and the pose graph's,
// posegraph/batch_solver.h) so that `lm`, `dogleg` and `gn` mean the same everywhere
// (also the pose-graph solvers' own, through this header).
#ifndef SUBSLAM_BACKEND_CERES_OPTIONS_H_
#define SUBSLAM_BACKEND_CERES_OPTIONS_H_

#include <ceres/loss_function.h>
#include <ceres/solver.h>

#include "subslam/backend/ceres_solver.h"

namespace subslam::backend {

// SPARSE_NORMAL_CHOLESKY on SuiteSparse, a trust region (Levenberg-Marquardt, Dogleg, or
// Gauss-Newton as Levenberg-Marquardt whose radius is so large, 10¹⁶, that the damping
// vanishes), the iteration limit, tolerances and threads of `options`, no logging.
ceres::Solver::Options CeresSolverOptions(const CeresSolveOptions& options);
// A new robust loss (the caller's problem takes ownership), or nullptr for none.
ceres::LossFunction* NewRobustLoss(const CeresSolveOptions& options);

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_CERES_OPTIONS_H_
