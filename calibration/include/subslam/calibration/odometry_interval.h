// The odometry between two consecutive scans as a calibration sees it: the recorded
// controls of the steps between them, corrected by c = (s₀, s₁, o₁) as
//   u' = (s₀·u₀ + o₀, s₁·u₁ + o₁)
// (a scale on both channels and an offset on the second: the turn rate of a unicycle, the
// steering angle of a car; o₀ is held as given), integrated by the data set's motion model from the identity.
//
// The relative pose of the scans, x_a⁻¹ ∘ x_b, differs from that prediction (in the frame
// of x_a: position [m], heading [rad]) by zero-mean Gaussian noise whose covariance is the
// steps' control noise propagated through the integration, exactly as the filters predict:
//   P ← J_x P J_xᵀ + J_u M(u') J_uᵀ,   M(u') = diag(σ₀² + (k₀u'₀)², σ₁² + (k₁u'₁)²).
// It is linear in the four variances θ = (σ₀², k₀², σ₁², k₁²): P = Σ_k θ_k T_k, and the
// T_k are what variance-component estimation needs.
#ifndef SUBSLAM_CALIBRATION_ODOMETRY_INTERVAL_H_
#define SUBSLAM_CALIBRATION_ODOMETRY_INTERVAL_H_

#include <Eigen/Core>
#include <array>
#include <vector>

#include "subslam/core/pose2.h"
#include "subslam/models/motion_model.h"

namespace subslam::calibration {

// The control correction c = (s₀, s₁, o₁).
using ControlCorrection = Eigen::Vector3d;

struct RecordedStep {
  Eigen::Vector2d control = Eigen::Vector2d::Zero();  // as recorded
  double dt = 0.0;                                    // s
};

class OdometryInterval {
 public:
  OdometryInterval(const models::MotionModel* model, std::vector<RecordedStep> steps, double offset0 = 0.0);

  // The predicted relative pose (x, y, θ) with θ unwrapped (the sum of the steps'
  // turns), and optionally its Jacobian with respect to c (3 × 3).
  Eigen::Vector3d Predict(const ControlCorrection& c, Eigen::Matrix3d* J_c = nullptr) const;

  // The four covariance components T_k at correction c (θ order above).
  std::array<Eigen::Matrix3d, 4> NoiseComponents(const ControlCorrection& c) const;

  const std::vector<RecordedStep>& steps() const { return steps_; }

 private:
  const models::MotionModel* model_;
  std::vector<RecordedStep> steps_;
  double offset0_;
};

// The residual of an interval: e = [R(θ_a)ᵀ(t_b − t_a) − p̂_xy; wrap(θ_b − θ_a − p̂_θ)],
// position in the frame of x_a, with its Jacobians with respect to x_a and x_b (3 × 3).
Eigen::Vector3d IntervalResidual(const Eigen::Vector3d& x_a, const Eigen::Vector3d& x_b,
                                 const Eigen::Vector3d& predicted, Eigen::Matrix3d* J_a = nullptr,
                                 Eigen::Matrix3d* J_b = nullptr);

}  // namespace subslam::calibration

#endif  // SUBSLAM_CALIBRATION_ODOMETRY_INTERVAL_H_
