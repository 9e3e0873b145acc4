// SE(2) poses and point transforms with analytic Jacobians.
//
// Conventions (composition order, Jacobian layout, angle wrapping) are in
// <subslam/core/conventions.h>. Every function here is pure and thread-safe; the
// optional Jacobian out-parameters may be nullptr. Each Jacobian is checked against
// central differences in tests/graph/pose2_test.cc.
#ifndef SUBSLAM_CORE_POSE2_H_
#define SUBSLAM_CORE_POSE2_H_

#include <Eigen/Core>
#include <cmath>
#include <ostream>

#include "subslam/core/conventions.h"

namespace subslam {

using Matrix23d = Eigen::Matrix<double, 2, 3>;
using Matrix32d = Eigen::Matrix<double, 3, 2>;

// Wraps an angle to (−π, π]. d wrap(a) / d a = 1 away from the cut (see WrapAngle
// below), which is the Jacobian every caller uses.
// Inline: it sits in every inner loop.
inline double WrapAngle(double angle_rad, double* J_wrapped_angle = nullptr) {
  if (J_wrapped_angle != nullptr) *J_wrapped_angle = 1.0;
  if (angle_rad > -kPi && angle_rad <= kPi) return angle_rad;
  double wrapped = std::remainder(angle_rad, kTwoPi);  // in [−π, π]
  if (wrapped <= -kPi) wrapped += kTwoPi;
  return wrapped;
}

// A rigid 2-D transform (x [m], y [m], theta [rad]); see conventions.h.
struct Pose2 {
  double x = 0.0;
  double y = 0.0;
  double theta = 0.0;

  Pose2() = default;
  Pose2(double x_m, double y_m, double theta_rad) : x(x_m), y(y_m), theta(theta_rad) {}
  static Pose2 FromVector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

  Eigen::Vector3d vector() const { return {x, y, theta}; }
  Eigen::Vector2d translation() const { return {x, y}; }
  // Rotation matrix R(theta).
  Eigen::Matrix2d rotation() const;
};

std::ostream& operator<<(std::ostream& os, const Pose2& p);

// a ∘ b; the heading is wrapped.
Pose2 Compose(const Pose2& a, const Pose2& b, Eigen::Matrix3d* J_ab_a = nullptr, Eigen::Matrix3d* J_ab_b = nullptr);

// a ∘ b for independent uncertain a and b, with its covariance to first order:
//   *cov_ab = J_a cov_a J_aᵀ + J_b cov_b J_bᵀ   (J_a, J_b: Compose's Jacobians);
// cov_ab may be cov_a or cov_b.
Pose2 ComposeWithCovariance(const Pose2& a, const Eigen::Matrix3d& cov_a, const Pose2& b, const Eigen::Matrix3d& cov_b,
                            Eigen::Matrix3d* cov_ab);

// a⁻¹, so that Compose(Inverse(a), a) is the identity.
Pose2 Inverse(const Pose2& a, Eigen::Matrix3d* J_inv_a = nullptr);

// a⁻¹ ∘ b: b expressed in a's frame (the relative pose from a to b).
Pose2 Between(const Pose2& a, const Pose2& b, Eigen::Matrix3d* J_ab_a = nullptr, Eigen::Matrix3d* J_ab_b = nullptr);

// p given in `frame` → the same point in frame's parent: frame.xy + R(frame.θ)·p.
Eigen::Vector2d TransformFrom(const Pose2& frame, const Eigen::Vector2d& p_in_frame, Matrix23d* J_out_frame = nullptr,
                              Eigen::Matrix2d* J_out_point = nullptr);

// q given in frame's parent → the same point in `frame`: R(frame.θ)ᵀ (q − frame.xy).
Eigen::Vector2d TransformTo(const Pose2& frame, const Eigen::Vector2d& q_in_parent, Matrix23d* J_out_frame = nullptr,
                            Eigen::Matrix2d* J_out_point = nullptr);

// Difference a − b of two pose vectors with the heading difference wrapped: the
// error measure used by metrics and residuals.
Eigen::Vector3d PoseDifference(const Pose2& a, const Pose2& b);

}  // namespace subslam

#endif  // SUBSLAM_CORE_POSE2_H_
