// subslam conventions — the single place where they are written down.
//
// Units: SI everywhere (metres, seconds, radians). Angles are wrapped to (−π, π].
//
// A 2-D pose is (x, y, θ): the position of a frame's origin and the heading of its
// x axis, both expressed in a parent frame. Names carry frames: `world_T_vehicle`
// is the vehicle frame expressed in the world frame.
//
// Composition a ∘ b expresses b (given in a's frame) in a's parent frame:
//   (a ∘ b).xy = a.xy + R(a.θ) · b.xy,   (a ∘ b).θ = wrap(a.θ + b.θ).
// Inverse: a⁻¹ ∘ a = identity. Between(a, b) = a⁻¹ ∘ b (b expressed in a's frame).
// A point p given in frame a is a ∘ p = a.xy + R(a.θ)·p in a's parent frame; the inverse
// transform is a⁻¹ · q = R(a.θ)ᵀ (q − a.xy).
//
// Jacobians are taken with respect to (x, y, θ) in that order, on the plain
// vector representation (not a tangent space): the derivative of the heading
// output ignores the wrap (its derivative is 1 except on the cut). Optional
// Jacobian out-parameters are named J_<output>_<input> and may be nullptr.
//
// State vectors of a map are ordered [pose (3), landmark 1 (2), landmark 2 (2), …].
//
// Vehicle frame: x forward, y left; a range-bearing detection (r, b) lies at
// (r cos b, r sin b) in the sensor frame, bearing counter-clockwise from x.
//
// Randomness: every random draw comes from an explicitly seeded std::mt19937_64;
// the same seed gives the same run, bit for bit, on the same build.
#ifndef SUBSLAM_CORE_CONVENTIONS_H_
#define SUBSLAM_CORE_CONVENTIONS_H_

#include <numbers>

namespace subslam {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kTwoPi = 2.0 * std::numbers::pi;

// Degrees to radians, for configuration tables written in degrees.
constexpr double DegToRad(double deg) { return deg * kPi / 180.0; }
constexpr double RadToDeg(double rad) { return rad * 180.0 / kPi; }

}  // namespace subslam

#endif  // SUBSLAM_CORE_CONVENTIONS_H_
