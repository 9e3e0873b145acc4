// The rotation test of a local map against the landmarks the last local maps saw
// (SubmapAssociationOptions::map_rotation_sigma_rad): the recent landmarks, and the fit of
// the map's rotation about its start to its pairings with them.
#ifndef SUBSLAM_ASSOCIATION_SRC_RECENT_ROTATION_FIT_H_
#define SUBSLAM_ASSOCIATION_SRC_RECENT_ROTATION_FIT_H_

#include <cmath>
#include <vector>

#include "association_gating.h"

namespace subslam::association::submap_matching {

// The rotation test (map_rotation_sigma_rad) of a local map against the landmarks the last
// recent_maps (at least one) local maps saw. Those are known relative to the start anchor
// about as well as that map's own features were: a map whose features cannot be paired
// with them as they are, but can once rotated about its start, is wrong in itself, and a
// rotation is how a particle filter's map over a turn is wrong.
//  1. A first δ by a vote over rotations within ±3σ in steps of σ/10, the map widened by
//     one step at each: the rotation under which the most features find an individually
//     compatible recent landmark (the smaller sum of their best d² breaking a tie).
//  2. The features are paired with the recent landmarks by JCBB with the map rotated by δ
//     and widened by a rotation of σ about its start.
//  3. δ is fitted to those pairings: Gauss-Newton on d²(δ) = ν(δ)ᵀ S(δ)⁻¹ ν(δ), the joint
//     innovation of the pairings with the map rotated by δ (its covariance with it). Steps
//     2-3 repeat until the pairings stand. (Pairing is linearised at δ, not at 0: a
//     rotation of 0.1 rad moves a feature 15 m away by 0.08 m along its range through the
//     second-order term alone, more than a range error a map over one second admits.)
//  4. The statistic is the likelihood ratio d²(0) − d²(δ̂) of those pairings (at least two):
//     χ²₁ for a map that is not rotated.
// A hypothesis that pairs a feature the map's own association paired with a recent landmark
// otherwise (with another, or none) explains again what the map explains as it is: no fit.
struct RotationFit {
  double delta_rad = 0.0;
  double statistic = NAN;      // NaN: fewer than two pairings, or a re-pairing (see above)
  double variance_rad2 = NAN;  // of δ̂, given the pairings
};

// Flags, by landmark, those the last `maps` local maps of the graph saw.
std::vector<char> RecentLandmarks(const SubmapGraph& graph, int maps);

// Adds to the (ascending) candidates the recent landmarks near a feature of the map placed
// as `m` that are not among them yet.
void AddRecentCandidates(const SubmapGraph& graph, const PlacedMap& m, const std::vector<char>& recent,
                         std::vector<int>* candidates);

RotationFit FitRecentRotation(const SubmapAssociationOptions& o, const LocalSubmap& s, const PlacedMap& placed,
                              const Eigen::Matrix3d& Sigma_widened, int start_anchor,
                              const std::vector<int>& candidates, const SubmapGraph& graph,
                              const CandidateGeometry& geometry, const GateTest& gate,
                              const TimedCovariance& timed_covariance, const std::vector<char>& recent,
                              const std::vector<int>& own_pairing);

}  // namespace subslam::association::submap_matching

#endif  // SUBSLAM_ASSOCIATION_SRC_RECENT_ROTATION_FIT_H_
