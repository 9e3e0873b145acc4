// Ackermann (car-like) motion model of the Victoria Park vehicle (Guivant & Nebot 2001;
// ../shared/data/victoria_park/README.md). The state is the pose of the sensor mounted
// a [m] forward and b [m] left of the rear-axle centre; the speed v is measured by an
// encoder H [m] to the side of the axle centre, so the axle-centre speed is
//   vc = v / (1 − tan(steer)·H/L),
// and with φ̇ = (vc/L)·tan(steer):
//   ẋ = vc·cos φ − φ̇·(a·sin φ + b·cos φ),   ẏ = vc·sin φ + φ̇·(a·cos φ − b·sin φ).
// The step integrates this with the forward-Euler rule over dt (Victoria Park's
// controls arrive at ≈40 Hz). With H = a = b = 0 it is the plain kinematic bicycle
// (φ̇ = v·tan(steer)/L), used by the simulated car-like scenarios.
//
// Control u = (v [m/s], steer [rad]). Steering angles with |tan(steer)·H/L| ≥ 0.99
// are outside the model and are clamped there (the data never come close).
#ifndef SUBSLAM_MODELS_ACKERMANN_MODEL_H_
#define SUBSLAM_MODELS_ACKERMANN_MODEL_H_

#include "subslam/models/motion_model.h"

namespace subslam::models {

struct AckermannGeometry {
  double wheelbase_m = 2.83;       // L
  double encoder_offset_m = 0.76;  // H
  double sensor_forward_m = 3.78;  // a
  double sensor_left_m = 0.50;     // b

  absl::Status Validate() const;
};

class AckermannModel final : public MotionModel {
 public:
  AckermannModel(const AckermannGeometry& geometry, const ControlNoise& noise)
      : MotionModel(noise), geometry_(geometry) {}

  Pose2 Predict(const Pose2& x, const Eigen::Vector2d& u, double dt, Eigen::Matrix3d* J_next_x = nullptr,
                Matrix32d* J_next_u = nullptr) const override;
  std::string Name() const override { return "ackermann"; }
  const AckermannGeometry& geometry() const { return geometry_; }

 private:
  AckermannGeometry geometry_;
};

}  // namespace subslam::models

#endif  // SUBSLAM_MODELS_ACKERMANN_MODEL_H_
