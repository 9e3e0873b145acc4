#include "subslam/backend/ceres_solver.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "subslam/backend/ceres_options.h"
#include "subslam/backend/ceres_submap_cost.h"
#include "subslam/core/enum_names.h"

namespace subslam::backend {

namespace {
constexpr EnumName<CeresMethod> kCeresMethodNames[] = {
    {CeresMethod::kLevenbergMarquardt, "lm"}, {CeresMethod::kDogleg, "dogleg"}, {CeresMethod::kGaussNewton, "gn"}};
constexpr EnumName<RobustLoss> kRobustLossNames[] = {
    {RobustLoss::kNone, "none"}, {RobustLoss::kHuber, "huber"}, {RobustLoss::kCauchy, "cauchy"}};
}  // namespace

const char* ToString(CeresMethod method) { return NameOf(kCeresMethodNames, method); }
absl::StatusOr<CeresMethod> CeresMethodFromString(const std::string& name) {
  return ParseEnum(kCeresMethodNames, name, "Ceres method");
}
const char* ToString(RobustLoss loss) { return NameOf(kRobustLossNames, loss); }
absl::StatusOr<RobustLoss> RobustLossFromString(const std::string& name) {
  return ParseEnum(kRobustLossNames, name, "robust loss");
}

absl::Status CeresSolveOptions::Validate() const {
  if (!(loss_scale > 0 && std::isfinite(loss_scale))) {
    return absl::InvalidArgumentError("loss_scale must be finite and > 0");
  }
  if (max_iterations < 1 || num_threads < 1) {
    return absl::InvalidArgumentError("max_iterations and num_threads must be >= 1");
  }
  if (!(function_tolerance >= 0 && gradient_tolerance >= 0 && parameter_tolerance >= 0)) {
    return absl::InvalidArgumentError("tolerances must be >= 0");
  }
  return absl::OkStatus();
}

ceres::Solver::Options CeresSolverOptions(const CeresSolveOptions& options) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  o.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  o.minimizer_type = ceres::TRUST_REGION;
  o.trust_region_strategy_type = options.method == CeresMethod::kDogleg ? ceres::DOGLEG : ceres::LEVENBERG_MARQUARDT;
  if (options.method == CeresMethod::kGaussNewton) {
    o.initial_trust_region_radius = 1e16;
    o.max_trust_region_radius = 1e16;
  }
  o.max_num_iterations = options.max_iterations;
  o.function_tolerance = options.function_tolerance;
  o.gradient_tolerance = options.gradient_tolerance;
  o.parameter_tolerance = options.parameter_tolerance;
  o.num_threads = options.num_threads;
  o.logging_type = ceres::SILENT;
  return o;
}

ceres::LossFunction* NewRobustLoss(const CeresSolveOptions& options) {
  if (options.loss == RobustLoss::kHuber) return new ceres::HuberLoss(options.loss_scale);
  if (options.loss == RobustLoss::kCauchy) return new ceres::CauchyLoss(options.loss_scale);
  return nullptr;
}

absl::StatusOr<CeresSolveReport> SolveWithCeres(SubmapGraph* graph, const CeresSolveOptions& options,
                                                const std::vector<int>& covariance_anchors,
                                                std::vector<Eigen::Matrix3d>* anchor_covariances) {
  if (absl::Status s = options.Validate(); !s.ok()) return s;
  // Parameter storage: anchors (x, y, θ) and landmarks (x, y).
  std::vector<std::array<double, 3>> anchors(graph->num_anchors());
  std::vector<std::array<double, 2>> landmarks(graph->num_landmarks());
  for (int k = 0; k < graph->num_anchors(); ++k) {
    const Pose2& p = graph->anchors()[k];
    anchors[k] = {p.x, p.y, p.theta};
  }
  for (int j = 0; j < graph->num_landmarks(); ++j) {
    landmarks[j] = {graph->landmarks()[j].x(), graph->landmarks()[j].y()};
  }
  ceres::Problem problem;
  for (const SubmapFactor& f : graph->factors()) {
    std::vector<double*> blocks = {anchors[f.start_anchor].data(), anchors[f.end_anchor].data()};
    // Distinct landmarks only: two features on one landmark share its block.
    std::vector<int> distinct, block_of_feature;
    for (int j : f.landmark_of_feature) {
      auto it = std::find(distinct.begin(), distinct.end(), j);
      block_of_feature.push_back(static_cast<int>(it - distinct.begin()));
      if (it == distinct.end()) distinct.push_back(j);
    }
    for (int j : distinct) blocks.push_back(landmarks[j].data());
    problem.AddResidualBlock(new SubmapCostFunction(f.submap, block_of_feature), NewRobustLoss(options), blocks);
  }
  if (problem.HasParameterBlock(anchors[0].data())) problem.SetParameterBlockConstant(anchors[0].data());

  ceres::Solver::Options o = CeresSolverOptions(options);
  std::string why;
  if (!o.IsValid(&why)) return absl::InvalidArgumentError(absl::StrCat("Ceres options: ", why));
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem, &summary);
  if (!summary.IsSolutionUsable()) {
    return absl::InternalError(absl::StrCat("Ceres: no usable solution: ", summary.message));
  }
  CeresSolveReport r;
  if (anchor_covariances != nullptr) {
    const absl::Time start = absl::Now();
    ceres::Covariance::Options co;
    co.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
    co.algorithm_type = ceres::SPARSE_QR;
    co.num_threads = options.num_threads;
    ceres::Covariance covariance(co);
    std::vector<std::pair<const double*, const double*>> blocks;
    for (int k : covariance_anchors) {
      if (k > 0) blocks.push_back({anchors[k].data(), anchors[k].data()});
    }
    if (!covariance.Compute(blocks, &problem)) {
      return absl::InternalError("Ceres: covariance computation failed (rank deficient?)");
    }
    anchor_covariances->clear();
    for (int k : covariance_anchors) {
      Eigen::Matrix<double, 3, 3, Eigen::RowMajor> c = Eigen::Matrix3d::Zero();
      if (k > 0) covariance.GetCovarianceBlock(anchors[k].data(), anchors[k].data(), c.data());
      anchor_covariances->push_back(c);
    }
    r.covariance_seconds = absl::ToDoubleSeconds(absl::Now() - start);
  }
  for (int k = 1; k < graph->num_anchors(); ++k) {
    graph->anchor(k) = Pose2(anchors[k][0], anchors[k][1], WrapAngle(anchors[k][2]));
  }
  for (int j = 0; j < graph->num_landmarks(); ++j) {
    graph->landmark(j) = Eigen::Vector2d(landmarks[j][0], landmarks[j][1]);
  }
  r.iterations = static_cast<int>(summary.iterations.size()) - 1;  // iteration 0 is the start
  r.initial_cost = summary.initial_cost;
  r.final_cost = summary.final_cost;
  r.seconds = summary.total_time_in_seconds;
  r.termination = ceres::TerminationTypeToString(summary.termination_type);
  r.brief = summary.BriefReport();
  return r;
}

}  // namespace subslam::backend
