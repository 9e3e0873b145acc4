// Motion models: discrete-time prediction of a 2-D pose from a control held over dt,
// with Jacobians and control-noise propagation.
//
//   x_{k+1} = f(x_k, u, dt),   Q_k = J_x_u · M(u) · J_x_uᵀ
//
// where M(u) is the control covariance. A control is the pair (u0, u1) whose meaning
// depends on the model: (v [m/s], ω [rad/s]) for UnicycleModel, (v [m/s], steer [rad])
// for AckermannModel. Noise on each control channel is σ² = σ_abs² + (scale·|u|)², which
// covers both absolute (Victoria Park, ISEIF) and proportional (HybridSLAM §5: 0.25·v,
// 0.35·ω) specifications. Models are immutable after construction and thread-safe.
#ifndef SUBSLAM_MODELS_MOTION_MODEL_H_
#define SUBSLAM_MODELS_MOTION_MODEL_H_

#include <Eigen/Core>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "subslam/core/pose2.h"

namespace subslam::models {

// Per-channel control noise: σ² = sigma² + (scale·|u|)².
struct ControlNoise {
  double sigma_u0 = 0.0;  // absolute σ of channel 0 (speed, m/s)
  double sigma_u1 = 0.0;  // absolute σ of channel 1 (rad/s or rad)
  double scale_u0 = 0.0;  // proportional σ of channel 0 (fraction of |u0|)
  double scale_u1 = 0.0;  // proportional σ of channel 1 (fraction of |u1|)

  absl::Status Validate() const;
  // Diagonal control covariance M(u).
  Eigen::Matrix2d Covariance(const Eigen::Vector2d& u) const;
};

class MotionModel {
 public:
  virtual ~MotionModel() = default;

  // Pose after holding control u for dt seconds. dt ≥ 0.
  virtual Pose2 Predict(const Pose2& x, const Eigen::Vector2d& u, double dt, Eigen::Matrix3d* J_next_x = nullptr,
                        Matrix32d* J_next_u = nullptr) const = 0;

  // Process covariance J_next_u · M(u) · J_next_uᵀ for this step.
  Eigen::Matrix3d ProcessCovariance(const Pose2& x, const Eigen::Vector2d& u, double dt) const;

  const ControlNoise& noise() const { return noise_; }
  virtual std::string Name() const = 0;

 protected:
  explicit MotionModel(const ControlNoise& noise) : noise_(noise) {}

 private:
  ControlNoise noise_;
};

}  // namespace subslam::models

#endif  // SUBSLAM_MODELS_MOTION_MODEL_H_
