// Nonlinear least squares over the submap graph with Ceres: every local map is one
// residual block (SubmapCostFunction), anchor 0 is held constant, and the anchors and
// landmarks of the graph are the parameter blocks. Solved with SPARSE_NORMAL_CHOLESKY on
// SuiteSparse; Levenberg-Marquardt (default) or Dogleg from Ceres, or Gauss-Newton,
// obtained as Levenberg-Marquardt with a trust region so large (10¹⁶) that the damping
// vanishes. An optional robust loss (Huber or Cauchy, scale in whitened units) per
// submap block bounds the pull of a local map that disagrees with the rest.
// The graph's association is taken as given (e.g. from the EIF joiner), so every
// back-end solves the same problem.
#ifndef SUBSLAM_BACKEND_CERES_SOLVER_H_
#define SUBSLAM_BACKEND_CERES_SOLVER_H_

#include <Eigen/Core>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "subslam/core/submap_graph.h"

namespace subslam::backend {

enum class CeresMethod { kLevenbergMarquardt, kDogleg, kGaussNewton };
const char* ToString(CeresMethod method);  // lm, dogleg, gn
absl::StatusOr<CeresMethod> CeresMethodFromString(const std::string& name);
enum class RobustLoss { kNone, kHuber, kCauchy };
const char* ToString(RobustLoss loss);  // none, huber, cauchy
absl::StatusOr<RobustLoss> RobustLossFromString(const std::string& name);

struct CeresSolveOptions {
  CeresMethod method = CeresMethod::kLevenbergMarquardt;
  RobustLoss loss = RobustLoss::kNone;
  double loss_scale = 3.0;  // in whitened residual units (σ)
  int max_iterations = 100;
  double function_tolerance = 1e-12;
  double gradient_tolerance = 1e-14;
  double parameter_tolerance = 1e-12;
  int num_threads = 1;

  absl::Status Validate() const;
};

// The figures of Ceres's summary that the reports carry.
struct CeresSolveReport {
  int iterations = 0;
  double initial_cost = 0.0;  // ½ Σ ‖whitened residual‖²
  double final_cost = 0.0;
  double seconds = 0.0;
  std::string termination;          // Ceres's termination type
  std::string brief;                // Ceres's one-line report
  double covariance_seconds = 0.0;  // ceres::Covariance, when asked for
};

// Optimises the graph's anchors 1 … k and landmarks in place (headings wrapped after).
// When `anchor_covariances` is given, it receives, through ceres::Covariance at the
// solution, the marginal covariance of each listed anchor (anchor 0: zero).
absl::StatusOr<CeresSolveReport> SolveWithCeres(SubmapGraph* graph, const CeresSolveOptions& options,
                                                const std::vector<int>& covariance_anchors = {},
                                                std::vector<Eigen::Matrix3d>* anchor_covariances = nullptr);

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_CERES_SOLVER_H_
