// The calibration's residuals as Ceres cost functions, whitened by the current noise
// (internal to the calibration module).
#ifndef SUBSLAM_CALIBRATION_INTERNAL_CALIBRATION_COSTS_H_
#define SUBSLAM_CALIBRATION_INTERNAL_CALIBRATION_COSTS_H_

#include <ceres/sized_cost_function.h>

#include <Eigen/Core>

#include "subslam/calibration/odometry_interval.h"
#include "subslam/models/range_bearing_model.h"

namespace subslam::calibration::internal {

// S·e for an interval between scan poses x_a, x_b (x, y, θ) under correction c
// (odometry_interval.h); S = L⁻¹ for the Cholesky factor L Lᵀ of its covariance.
class OdometryCost final : public ceres::SizedCostFunction<3, 3, 3, 3> {
 public:
  OdometryCost(const OdometryInterval* interval, const Eigen::Matrix3d& sqrt_information)
      : interval_(interval), S_(sqrt_information) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  const OdometryInterval* interval_;
  Eigen::Matrix3d S_;
};

// (h(x, l) − z) / σ per component, bearing wrapped, for one detection z = (range, bearing).
class DetectionCost final : public ceres::SizedCostFunction<2, 3, 2> {
 public:
  DetectionCost(const models::RangeBearingModel* sensor, const Eigen::Vector2d& z, const Eigen::Vector2d& sigma)
      : sensor_(sensor), z_(z), inverse_sigma_(sigma.cwiseInverse()) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  const models::RangeBearingModel* sensor_;
  Eigen::Vector2d z_;
  Eigen::Vector2d inverse_sigma_;
};

}  // namespace subslam::calibration::internal

#endif  // SUBSLAM_CALIBRATION_INTERNAL_CALIBRATION_COSTS_H_
