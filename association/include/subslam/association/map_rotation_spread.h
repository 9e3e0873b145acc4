// The spread of the local maps' own rotation: how much more their features turn against the
// graph, map to map, than their covariances admit.
//
// The association's rotation test (SubmapAssociationOptions::map_rotation_sigma_rad) fits,
// for each local map with two pairings or more with the landmarks the previous maps saw,
// the rotation δ̂ of its features about its start and its variance v (given the map's and
// the landmarks' covariances). If those covariances are right, δ̂ ~ N(0, v), and a fit lies
// beyond the test's bound (δ̂²/v above χ²₁ at `fit_probability`, the rotation test's own
// level) with probability 1 − fit_probability; the fits are taken as independent from map
// to map (consecutive maps' fits share some recent landmarks, which this ignores). The
// count k of fits beyond the bound among the n so far is tested against that binomial after
// every fit, at α/(k(k + 1)), α = 1 − probability (a new rejection can come only with a
// fit beyond the bound, and those levels sum to α), so that a run of consistent maps is
// rejected at some fit with probability at most α; one grossly rotated map (which the
// rotation test rotates back) does not reject it. While it is rejected, the
// maps' own rotation, ψ ~ N(0, τ²) with δ̂ ~ N(0, v + τ²), is estimated by maximum
// likelihood over every fit (Fisher scoring on τ², started from the last estimate), and
// each next local map is joined with its features' covariance widened by a rotation of τ̂
// about its start (WidenedFeaturesByRotation; the end pose is not widened: what the test
// measures is the features' rotation against the map's own start and end). Otherwise
// τ̂ = 0 and maps are joined as built.
//
// What the estimate carries. τ̂² is the second moment of the maps' rotation errors beyond
// their covariances, the tail included, carried as a Gaussian on every map: where those
// errors are heavy-tailed (a few maps far beyond the bound, the rest within their
// covariances) a Gaussian of that moment widens every map a little rather than the few
// a lot, which is what the joins can use (the measurements: docs/design/association.md).
// Fits of maps joined widened are recorded without their own
// widening: for the linear fit, widening the features by σ along the fitted rotation
// leaves δ̂ as it is and adds σ² to its variance, which Add takes off again. The recent
// landmarks a map is fitted against were built from widened maps too, which Add cannot take
// off: once maps are widened, v carries part of τ̂² and the estimate leans low (so a
// rejection can lapse and widening stop). Each joined map's fit counts once (it is kept
// with the joined map, LocalSubmap::rotation_fit_rad); a join the EIF's validation
// rejects, joined again without association, has none.
//
// Units: radians. Not thread-safe.
#ifndef SUBSLAM_ASSOCIATION_MAP_ROTATION_SPREAD_H_
#define SUBSLAM_ASSOCIATION_MAP_ROTATION_SPREAD_H_

#include <cmath>
#include <vector>

#include "subslam/core/local_submap.h"

namespace subslam::association {

class MapRotationSpread {
 public:
  // `probability` in [0, 1): the level at which the count of fits beyond the bound rejects
  // consistent maps (0: never; off); `fit_probability` in (0, 1): the rotation test's level,
  // P(χ²₁ ≤ bound) (SubmapAssociationOptions::map_rotation_probability).
  explicit MapRotationSpread(double probability = 0.999, double fit_probability = 0.99);

  // One map's fit: its rotation δ̂ [rad] and that estimate's variance [rad²] with the map as
  // it was associated, which had been widened by `widened_by_rad` (its rotation_spread_rad):
  // the fit's variance under the map's own covariance is variance_rad2 − widened_by_rad².
  // Ignored unless both are finite and that variance is positive.
  void Add(double delta_rad, double variance_rad2, double widened_by_rad = 0.0);
  // `s` with its features widened by sigma_rad() (WidenedFeaturesByRotation), or as it is.
  LocalSubmap Widened(const LocalSubmap& s) const;

  // τ̂ [rad] while the test rejects zero spread, else 0.
  double sigma_rad() const { return rejected_ ? std::sqrt(tau2_) : 0.0; }
  int fits() const { return static_cast<int>(delta_.size()); }
  int beyond() const { return beyond_; }       // fits with δ̂²/v beyond the bound
  bool rejected() const { return rejected_; }  // the count tested as above

 private:
  void Estimate();

  double probability_;
  double fit_probability_;
  double fit_bound_ = 0.0;  // χ²₁ at fit_probability_
  std::vector<double> delta_, variance_;
  int beyond_ = 0;
  bool rejected_ = false;
  double tau2_ = 0.0;  // the last maximum-likelihood estimate of τ² (kept as a warm start)
};

}  // namespace subslam::association

#endif  // SUBSLAM_ASSOCIATION_MAP_ROTATION_SPREAD_H_
