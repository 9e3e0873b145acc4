// The EIF joiner's factorisation state (private to the back-end): the sparse LDLᵀ factor
// of Λ and what its next incremental update needs.
#ifndef SUBSLAM_BACKEND_SRC_EIF_SOLVER_H_
#define SUBSLAM_BACKEND_SRC_EIF_SOLVER_H_

#include <Eigen/Core>

#include "subslam/backend/internal/sparse_cholesky.h"

namespace subslam::backend {

struct EifSolver {
  SparseCholesky factor;
  Eigen::MatrixXd last_whitened_jacobian;  // of the newest factor, for the incremental update
  bool stale = false;                      // the factor no longer matches Λ (a rejected join was undone)
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_SRC_EIF_SOLVER_H_
