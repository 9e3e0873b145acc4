#include "subslam/calibration/internal/calibration_costs.h"

#include <Eigen/Core>

namespace subslam::calibration::internal {

using RowMatrix3d = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

bool OdometryCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const Eigen::Map<const Eigen::Vector3d> x_a(parameters[0]), x_b(parameters[1]), c(parameters[2]);
  const bool want = jacobians != nullptr;
  Eigen::Matrix3d J_c, J_a, J_b;
  const Eigen::Vector3d predicted = interval_->Predict(c, want ? &J_c : nullptr);
  const Eigen::Vector3d e = IntervalResidual(x_a, x_b, predicted, want ? &J_a : nullptr, want ? &J_b : nullptr);
  Eigen::Map<Eigen::Vector3d> r(residuals);
  r = S_ * e;
  if (!want) return true;
  const Eigen::Matrix3d J[3] = {S_ * J_a, S_ * J_b, -S_ * J_c};  // e = … − prediction(c)
  for (int b = 0; b < 3; ++b) {
    if (jacobians[b]) Eigen::Map<RowMatrix3d>(jacobians[b], 3, 3) = J[b];
  }
  return true;
}

bool DetectionCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const Eigen::Map<const Eigen::Vector3d> x(parameters[0]);
  const Eigen::Map<const Eigen::Vector2d> l(parameters[1]);
  if ((l - x.head<2>()).squaredNorm() < 1e-18) return false;  // the model needs range > 0
  Matrix23d J_x;
  Eigen::Matrix2d J_l;
  const Eigen::Vector2d h = sensor_->Observe(Pose2(x[0], x[1], x[2]), l, &J_x, &J_l);
  const Eigen::Vector2d e = models::RangeBearingModel::Difference(h, z_);
  Eigen::Map<Eigen::Vector2d> r(residuals);
  r = inverse_sigma_.cwiseProduct(e);
  if (jacobians == nullptr) return true;
  if (jacobians[0]) {
    Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> j(jacobians[0]);
    j = inverse_sigma_.asDiagonal() * J_x;
  }
  if (jacobians[1]) {
    Eigen::Map<Eigen::Matrix<double, 2, 2, Eigen::RowMajor>> j(jacobians[1]);
    j = inverse_sigma_.asDiagonal() * J_l;
  }
  return true;
}

}  // namespace subslam::calibration::internal
