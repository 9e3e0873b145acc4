#include "subslam/models/unicycle_model.h"

#include <cmath>

namespace subslam::models {
namespace {

constexpr double kSeriesThreshold = 1e-4;

// A(φ) = sin φ / φ and B(φ) = (1 − cos φ) / φ with their derivatives.
struct ArcCoefficients {
  double a, b, da, db;
};

ArcCoefficients Arc(double phi) {
  if (std::abs(phi) < kSeriesThreshold) {
    const double p2 = phi * phi;
    return {1.0 - p2 / 6.0, phi / 2.0 - phi * p2 / 24.0, -phi / 3.0 + phi * p2 / 30.0, 0.5 - p2 / 8.0};
  }
  const double s = std::sin(phi), c = std::cos(phi);
  return {s / phi, (1.0 - c) / phi, (phi * c - s) / (phi * phi), (phi * s - (1.0 - c)) / (phi * phi)};
}

}  // namespace

Pose2 UnicycleModel::Predict(const Pose2& x, const Eigen::Vector2d& u, double dt, Eigen::Matrix3d* J_next_x,
                             Matrix32d* J_next_u) const {
  const double v = u[0], omega = u[1];
  const double phi = omega * dt;
  const ArcCoefficients arc = Arc(phi);
  const Pose2 delta(v * dt * arc.a, v * dt * arc.b, phi);
  Eigen::Matrix3d J_next_delta;
  const Pose2 next = Compose(x, delta, J_next_x, J_next_u ? &J_next_delta : nullptr);
  if (J_next_u != nullptr) {
    Matrix32d J_delta_u;
    J_delta_u << dt * arc.a, v * dt * arc.da * dt,  //
        dt * arc.b, v * dt * arc.db * dt,           //
        0.0, dt;
    *J_next_u = J_next_delta * J_delta_u;
  }
  return next;
}

}  // namespace subslam::models
