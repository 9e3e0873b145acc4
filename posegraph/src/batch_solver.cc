#include "subslam/posegraph/batch_solver.h"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <array>
#include <memory>
#include <type_traits>
#include <vector>

#include "absl/strings/str_cat.h"
#include "subslam/backend/ceres_options.h"
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
    const Eigen::Vector3d r =
        OdometryResidual(z_, PoseOf(x[0]), PoseOf(x[1]), want ? &J_from : nullptr, want ? &J_to : nullptr);
    Eigen::Map<Eigen::Vector3d>{residuals} = W_ * r;
    if (want && jacobians[0] != nullptr) Eigen::Map<RowMajor33>{jacobians[0]} = W_ * J_from;
    if (want && jacobians[1] != nullptr) Eigen::Map<RowMajor33>{jacobians[1]} = W_ * J_to;
    return true;
  }

 private:
  Pose2 z_;
  Eigen::Matrix3d W_;
};

// A 2-D sighting (a Cartesian point or a bearing-range measurement) of a point from a
// pose: `Residual` gives r and its Jacobians for the measurement held.
template <typename Measurement>
class SightingCost final : public ceres::SizedCostFunction<2, 3, 2> {
 public:
  explicit SightingCost(const Measurement& m) : m_(m), W_(Whitener<2>(m.information)) {}
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Matrix23d J_pose;
    Eigen::Matrix2d J_point;
    const bool want = jacobians != nullptr;
    const Eigen::Vector2d r =
        Residual(PoseOf(x[0]), Eigen::Vector2d(x[1][0], x[1][1]), want ? &J_pose : nullptr, want ? &J_point : nullptr);
    Eigen::Map<Eigen::Vector2d>{residuals} = W_ * r;
    if (want && jacobians[0] != nullptr) Eigen::Map<RowMajor23>{jacobians[0]} = W_ * J_pose;
    if (want && jacobians[1] != nullptr) Eigen::Map<RowMajor22>{jacobians[1]} = W_ * J_point;
    return true;
  }

 private:
  Eigen::Vector2d Residual(const Pose2& pose, const Eigen::Vector2d& point, Matrix23d* J_pose,
                           Eigen::Matrix2d* J_point) const {
    if constexpr (std::is_same_v<Measurement, PointMeasurement>) {
      return PointResidual(m_.z, pose, point, J_pose, J_point);
    } else {
      return BearingRangeResidual(m_.bearing, m_.range, pose, point, J_pose, J_point);
    }
  }
  Measurement m_;
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
  const auto loss = [&options] { return backend::NewRobustLoss(options); };
  for (const OdometryMeasurement& m : graph->odometry) {
    problem.AddResidualBlock(new OdometryCost(m), loss(), poses[m.from].data(), poses[m.to].data());
  }
  for (const PointMeasurement& m : graph->point_measurements) {
    problem.AddResidualBlock(new SightingCost<PointMeasurement>(m), loss(), poses[m.pose].data(),
                             points[m.point].data());
  }
  for (const BearingRangeMeasurement& m : graph->bearing_range_measurements) {
    problem.AddResidualBlock(new SightingCost<BearingRangeMeasurement>(m), loss(), poses[m.pose].data(),
                             points[m.point].data());
  }
  for (const BearingMeasurement& m : graph->bearing_measurements) {
    problem.AddResidualBlock(new BearingCost(m), loss(), poses[m.pose].data(), points[m.point].data());
  }
  for (int g : graph->GaugePoses()) {
    if (problem.HasParameterBlock(poses[g].data())) problem.SetParameterBlockConstant(poses[g].data());
  }
  const ceres::Solver::Options o = backend::CeresSolverOptions(options);
  std::string why;
  if (!o.IsValid(&why)) return absl::InvalidArgumentError(absl::StrCat("Ceres options: ", why));
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem, &summary);
  if (!summary.IsSolutionUsable())
    return absl::InternalError(absl::StrCat("Ceres: no usable solution: ", summary.message));
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
