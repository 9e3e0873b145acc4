// A local map's rotation about its start pose: the error a particle-filter local map makes
// beyond its covariance when its particles collapse over a sharp turn (the heading after
// the turn, and every feature seen after it, sit off by more than the map's covariance
// admits; docs/limits.md). Association tests for it against the landmarks the previous
// local maps just saw (submap_association.h), and a map found rotated is joined with its
// covariance widened by a rotation nuisance, so that the graph estimates the rotation
// from the landmarks it shares with its neighbours instead of bending the trajectory.
//
// Conventions: the map's mean is [end pose (x, y, θ), landmark 1 (x, y), …] in the frame of
// its start pose (local_submap.h); a rotation by δ [rad] about that frame's origin moves a
// point p to R(δ)·p and adds δ to the end heading.
#ifndef SUBSLAM_ASSOCIATION_LOCAL_MAP_ROTATION_H_
#define SUBSLAM_ASSOCIATION_LOCAL_MAP_ROTATION_H_

#include <Eigen/Core>

#include "subslam/core/local_submap.h"

namespace subslam::association {

// ∂mean/∂δ at δ = 0 for the map rotated by δ about its start: (−y, x, 1) for the end pose,
// (−y, x) for each landmark (3 + 2n rows).
Eigen::VectorXd RotationAboutStart(const LocalSubmap& s);

// The map with covariance Σ + σ²·g·gᵀ, g = RotationAboutStart(s): its mean, and the
// relative geometry of its features, unchanged; a rotation of standard deviation
// `sigma_rad` about its start allowed for (rotation_widening_rad records it, in
// quadrature with any earlier widening). sigma_rad ≥ 0.
LocalSubmap WidenedByRotation(const LocalSubmap& s, double sigma_rad);

// The map with its features' covariance widened by a rotation of standard deviation
// `sigma_rad` about its start, the end pose left as it is: Σ + σ²·g·gᵀ with g =
// RotationAboutStart(s) but zero in the end pose's rows (rotation_spread_rad records it, in
// quadrature with any earlier one; map_rotation_spread.h). Its mean unchanged. sigma_rad ≥ 0.
LocalSubmap WidenedFeaturesByRotation(const LocalSubmap& s, double sigma_rad);

// The map rotated rigidly by `delta_rad` about its start: mean and covariance carried
// through the rotation exactly (A·Σ·Aᵀ, A rotating each position block, the end heading
// shifted by delta_rad and wrapped).
LocalSubmap RotatedAboutStart(const LocalSubmap& s, double delta_rad);

}  // namespace subslam::association

#endif  // SUBSLAM_ASSOCIATION_LOCAL_MAP_ROTATION_H_
