// Unicycle (velocity) motion model with exact arc integration (FMJ §II, Eq. 1).
//
// Control u = (v [m/s], ω [rad/s]) held for dt. With φ = ω·dt the body-frame
// displacement is v·dt·(sin φ / φ, (1 − cos φ) / φ) and the heading change φ, so
//   x_{k+1} = x_k ∘ (v·dt·A(φ), v·dt·B(φ), φ),  A(φ) = sin φ/φ,  B(φ) = (1 − cos φ)/φ.
// A, B and their derivatives switch to Taylor series for |φ| < 1e-4, so the ω → 0
// limit (straight line) is exact and smooth.
#ifndef SUBSLAM_MODELS_UNICYCLE_MODEL_H_
#define SUBSLAM_MODELS_UNICYCLE_MODEL_H_

#include "subslam/models/motion_model.h"

namespace subslam::models {

class UnicycleModel final : public MotionModel {
 public:
  explicit UnicycleModel(const ControlNoise& noise = {}) : MotionModel(noise) {}

  Pose2 Predict(const Pose2& x, const Eigen::Vector2d& u, double dt, Eigen::Matrix3d* J_next_x = nullptr,
                Matrix32d* J_next_u = nullptr) const override;
  std::string Name() const override { return "unicycle"; }
};

}  // namespace subslam::models

#endif  // SUBSLAM_MODELS_UNICYCLE_MODEL_H_
