#include "subslam/association/map_rotation_spread.h"

#include <algorithm>
#include <boost/math/distributions/binomial.hpp>
#include <cmath>

#include "subslam/association/local_map_rotation.h"
#include "subslam/core/check.h"
#include "subslam/models/gating.h"

namespace subslam::association {

MapRotationSpread::MapRotationSpread(double probability, double fit_probability)
    : probability_(probability), fit_probability_(fit_probability) {
  SUBSLAM_CHECK(probability >= 0.0 && probability < 1.0) << "map rotation spread probability " << probability;
  SUBSLAM_CHECK(fit_probability > 0.0 && fit_probability < 1.0) << "rotation test probability " << fit_probability;
  fit_bound_ = models::ChiSquareQuantile(fit_probability, 1);
}

void MapRotationSpread::Add(double delta_rad, double variance_rad2, double widened_by_rad) {
  variance_rad2 -= widened_by_rad * widened_by_rad;
  if (!(std::isfinite(delta_rad) && std::isfinite(variance_rad2) && variance_rad2 > 0.0)) return;
  delta_.push_back(delta_rad);
  variance_.push_back(variance_rad2);
  if (delta_rad * delta_rad / variance_rad2 > fit_bound_) ++beyond_;
  // P(at least k = `beyond_` of n consistent maps beyond the bound), tested after every fit
  // at α/(k(k + 1)), α = 1 − probability. For a given k that p-value grows with n, so a run
  // is rejected with the count at k only if it already is at the fit n* where the p-value
  // last lies below the level, with probability P(X_{n*} ≥ k) ≤ α/(k(k + 1)); over k the
  // levels sum to α: a run of consistent maps is rejected at some fit with probability at
  // most α, however long it is.
  const int n = fits();
  if (probability_ > 0.0 && beyond_ > 0) {
    const boost::math::binomial_distribution<double> consistent(n, 1.0 - fit_probability_);
    const double p_value = boost::math::cdf(boost::math::complement(consistent, beyond_ - 1));
    rejected_ = p_value < (1.0 - probability_) / (static_cast<double>(beyond_) * (beyond_ + 1));
  } else {
    rejected_ = false;
  }
  if (rejected_) Estimate();
}

LocalSubmap MapRotationSpread::Widened(const LocalSubmap& s) const {
  const double sigma = sigma_rad();
  return sigma > 0 ? WidenedFeaturesByRotation(s, sigma) : s;
}

void MapRotationSpread::Estimate() {
  // log L(t) = −½ Σ [log(v + t) + δ̂²/(v + t)], t = τ² ≥ 0; Fisher scoring:
  // t ← t + U/I with U = ½ Σ [δ̂²/(v + t)² − 1/(v + t)] and I = ½ Σ 1/(v + t)².
  const int n = fits();
  double t = tau2_;
  if (!(t > 0.0)) {  // the moment estimate to start from
    double excess = 0.0;
    for (int k = 0; k < n; ++k) excess += delta_[k] * delta_[k] - variance_[k];
    t = std::max(0.0, excess / n);
  }
  constexpr int kMaxIterations = 100;
  for (int it = 0; it < kMaxIterations; ++it) {
    double score = 0.0, information = 0.0;
    for (int k = 0; k < n; ++k) {
      const double s = variance_[k] + t;
      score += 0.5 * (delta_[k] * delta_[k] / (s * s) - 1.0 / s);
      information += 0.5 / (s * s);
    }
    const double next = std::max(0.0, t + score / information);
    const bool converged = std::abs(next - t) <= 1e-9 * std::max(next, 1e-12);
    t = next;
    if (converged) break;  // (from 0 with a positive score it moves on)
  }
  tau2_ = t;
}

}  // namespace subslam::association
