#include "subslam/posegraph/batch_solver.h"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <array>
#include <memory>
#include <vector>

#include "absl/strings/str_cat.h"
#include "subslam/posegraph/measurement_residuals.h"

namespace subslam::posegraph {
namespace {

using RowMajor23 = Eigen::Matrix<double, 2, 3, Eigen::RowMajor>;
using RowMajor33 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
using RowMajor22 = Eigen::Matrix<double, 2, 2, Eigen::RowMajor>;

// Lᵀ with Ω = L Lᵀ: the whitening of a residual of information Ω (rᵀΩr = ‖Lᵀr‖²).
template <int N>
Eigen::Matrix<double, N, N> Whitener(const Eigen::Matrix<double, N, N>& information) {
  return Eigen::LLT<Eigen::Matrix<double, N, N>>(information).matrixU();
}

Pose2 PoseOf(const double* p) { return {p[0], p[1], p[2]}; }

class OdometryCost final : public ceres::SizedCostFunction<3, 3, 3> {
 public:
  explicit OdometryCost(const OdometryMeasurement& m) : z_(m.z), W_(Whitener<3>(m.information)) {}
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Eigen::Matrix3d J_from, J_to;
    const bool want = jacobians != nullptr;
    const Eigen::Vector3d r = OdometryResidual(z_, PoseOf(x[0]), PoseOf(x[1]), want ? &J_from : nullptr,
                                               want ? &J_to : nullptr);
    Eigen::Map<Eigen::Vector3d>{residuals} = W_ * r;
    if (want && jacobians[0] != nullptr) Eigen::Map<RowMajor33>{jacobians[0]} = W_ * J_from;
    if (want && jacobians[1] != nullptr) Eigen::Map<RowMajor33>{jacobians[1]} = W_ * J_to;
    return true;
  }

 private:
  Pose2 z_;
  Eigen::Matrix3d W_;
};

class PointCost final : public ceres::SizedCostFunction<2, 3, 2> {
 public:
  explicit PointCost(const PointMeasurement& m) : z_(m.z), W_(Whitener<2>(m.information)) {}
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Matrix23d J_pose;
    Eigen::Matrix2d J_point;
    const bool want = jacobians != nullptr;
    const Eigen::Vector2d r = PointResidual(z_, PoseOf(x[0]), Eigen::Vector2d(x[1][0], x[1][1]),
                                            want ? &J_pose : nullptr, want ? &J_point : nullptr);
    Eigen::Map<Eigen::Vector2d>{residuals} = W_ * r;
    if (want && jacobians[0] != nullptr) Eigen::Map<RowMajor23>{jacobians[0]} = W_ * J_pose;
    if (want && jacobians[1] != nullptr) Eigen::Map<RowMajor22>{jacobians[1]} = W_ * J_point;
    return true;
  }

 private:
  Eigen::Vector2d z_;
  Eigen::Matrix2d W_;
};

class BearingRangeCost final : public ceres::SizedCostFunction<2, 3, 2> {
 public:
  explicit BearingRangeCost(const BearingRangeMeasurement& m)
      : bearing_(m.bearing), range_(m.range), W_(Whitener<2>(m.information)) {}
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Matrix23d J_pose;
    Eigen::Matrix2d J_point;
    const bool want = jacobians != nullptr;
    const Eigen::Vector2d r = BearingRangeResidual(bearing_, range_, PoseOf(x[0]), Eigen::Vector2d(x[1][0], x[1][1]),
                                                   want ? &J_pose : nullptr, want ? &J_point : nullptr);
    Eigen::Map<Eigen::Vector2d>{residuals} = W_ * r;
    if (want && jacobians[0] != nullptr) Eigen::Map<RowMajor23>{jacobians[0]} = W_ * J_pose;
    if (want && jacobians[1] != nullptr) Eigen::Map<RowMajor22>{jacobians[1]} = W_ * J_point;
    return true;
  }

 private:
  double bearing_, range_;
  Eigen::Matrix2d W_;
};

class BearingCost final : public ceres::SizedCostFunction<1, 3, 2> {
 public:
  explicit BearingCost(const BearingMeasurement& m) : bearing_(m.bearing), w_(std::sqrt(m.information)) {}
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Eigen::RowVector3d J_pose;
    Eigen::RowVector2d J_point;
    const bool want = jacobians != nullptr;
    residuals[0] = w_ * BearingResidual(bearing_, PoseOf(x[0]), Eigen::Vector2d(x[1][0], x[1][1]),
                                        want ? &J_pose : nullptr, want ? &J_point : nullptr);
    if (want && jacobians[0] != nullptr) Eigen::Map<Eigen::RowVector3d>{jacobians[0]} = w_ * J_pose;
    if (want && jacobians[1] != nullptr) Eigen::Map<Eigen::RowVector2d>{jacobians[1]} = w_ * J_point;
    return true;
  }

 private:
  double bearing_, w_;
};

}  // namespace

absl::StatusOr<BatchSolveReport> SolveGraphWithCeres(PoseGraph* graph, const backend::CeresSolveOptions& options) {
  if (absl::Status s = options.Validate(); !s.ok()) return s;
  if (absl::Status s = graph->Validate(); !s.ok()) return s;
  std::vector<std::array<double, 3>> poses(graph->poses.size());
  std::vector<std::array<double, 2>> points(graph->points.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    const Pose2& p = graph->poses[i].estimate;
    poses[i] = {p.x, p.y, p.theta};
  }
  for (size_t j = 0; j < points.size(); ++j) points[j] = {graph->points[j].estimate.x(), graph->points[j].estimate.y()};
  ceres::Problem problem;
  const auto loss = [&options]() -> ceres::LossFunction* {
    if (options.loss == backend::RobustLoss::kHuber) return new ceres::HuberLoss(options.loss_scale);
    if (options.loss == backend::RobustLoss::kCauchy) return new ceres::CauchyLoss(options.loss_scale);
    return nullptr;
  };
  for (const OdometryMeasurement& m : graph->odometry) {
    problem.AddResidualBlock(new OdometryCost(m), loss(), poses[m.from].data(), poses[m.to].data());
  }
  for (const PointMeasurement& m : graph->point_measurements) {
    problem.AddResidualBlock(new PointCost(m), loss(), poses[m.pose].data(), points[m.point].data());
  }
  for (const BearingRangeMeasurement& m : graph->bearing_range_measurements) {
    problem.AddResidualBlock(new BearingRangeCost(m), loss(), poses[m.pose].data(), points[m.point].data());
  }
  for (const BearingMeasurement& m : graph->bearing_measurements) {
    problem.AddResidualBlock(new BearingCost(m), loss(), poses[m.pose].data(), points[m.point].data());
  }
  for (int g : graph->GaugePoses()) {
    if (problem.HasParameterBlock(poses[g].data())) problem.SetParameterBlockConstant(poses[g].data());
  }
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  o.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  o.trust_region_strategy_type =
      options.method == backend::CeresMethod::kDogleg ? ceres::DOGLEG : ceres::LEVENBERG_MARQUARDT;
  if (options.method == backend::CeresMethod::kGaussNewton) {
    o.initial_trust_region_radius = 1e16;  // no damping: Gauss-Newton steps
    o.max_trust_region_radius = 1e16;
  }
  o.max_num_iterations = options.max_iterations;
  o.function_tolerance = options.function_tolerance;
  o.gradient_tolerance = options.gradient_tolerance;
  o.parameter_tolerance = options.parameter_tolerance;
  o.num_threads = options.num_threads;
  o.logging_type = ceres::SILENT;
  std::string why;
  if (!o.IsValid(&why)) return absl::InvalidArgumentError(absl::StrCat("Ceres options: ", why));
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem, &summary);
  if (!summary.IsSolutionUsable()) return absl::InternalError(absl::StrCat("Ceres: no usable solution: ", summary.message));
  for (size_t i = 0; i < poses.size(); ++i) {
    graph->poses[i].estimate = Pose2(poses[i][0], poses[i][1], WrapAngle(poses[i][2]));
    graph->poses[i].has_estimate = true;
  }
  for (size_t j = 0; j < points.size(); ++j) {
    graph->points[j].estimate = Eigen::Vector2d(points[j][0], points[j][1]);
    graph->points[j].has_estimate = true;
  }
  BatchSolveReport r;
  r.iterations = static_cast<int>(summary.iterations.size()) - 1;
  r.initial_error = summary.initial_cost;
  r.final_error = summary.final_cost;
  r.seconds = summary.total_time_in_seconds;
  r.termination = ceres::TerminationTypeToString(summary.termination_type);
  return r;
}

}  // namespace subslam::posegraph
