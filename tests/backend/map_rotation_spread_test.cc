#include "subslam/association/map_rotation_spread.h"

#include <gtest/gtest.h>

#include <boost/math/distributions/binomial.hpp>
#include <cmath>
#include <random>
#include <vector>

#include "subslam/association/local_map_rotation.h"
#include "subslam/models/gating.h"
#include "synthetic_run.h"

namespace subslam::backend {
namespace {

// `n` fits of maps whose own rotation spreads by `tau`: δ̂ ~ N(0, v + τ²), the fits' sigmas
// √v drawn between 2 and 10 mrad (as the rotation test's on Victoria Park's maps); whether
// the test rejected at some fit.
association::MapRotationSpread Fits(double tau, int n, std::mt19937_64* rng, std::vector<double>* variances = nullptr,
                                    bool* ever_rejected = nullptr) {
  std::uniform_real_distribution<double> sd(0.002, 0.010);
  std::normal_distribution<double> normal;
  association::MapRotationSpread spread(0.999);
  for (int k = 0; k < n; ++k) {
    const double v = std::pow(sd(*rng), 2);
    spread.Add(std::sqrt(v + tau * tau) * normal(*rng), v);
    if (variances != nullptr) variances->push_back(v);
    if (ever_rejected != nullptr) *ever_rejected = *ever_rejected || spread.rejected();
  }
  return spread;
}

// Over independent runs, (τ̂² − τ²)² times the Fisher information of τ² is χ²₁ per run
// for the maximum-likelihood estimate (asymptotically: 400 fits a run); the sum over the
// runs is bounded by χ²'s 0.001 and 0.999 quantiles.
TEST(MapRotationSpread, MaximumLikelihoodSpreadHoldsOverMonteCarloRuns) {
  constexpr int kRuns = 40, kFits = 400;
  constexpr double kTau = 0.005;
  std::mt19937_64 rng(17);
  double chi2 = 0.0;
  for (int run = 0; run < kRuns; ++run) {
    std::vector<double> v;
    const association::MapRotationSpread spread = Fits(kTau, kFits, &rng, &v);
    ASSERT_TRUE(spread.rejected());
    ASSERT_EQ(spread.fits(), kFits);
    double information = 0.0;
    for (double x : v) information += 0.5 / std::pow(x + kTau * kTau, 2);
    chi2 += std::pow(spread.sigma_rad() * spread.sigma_rad() - kTau * kTau, 2) * information;
  }
  EXPECT_LT(chi2, models::ChiSquareQuantile(0.999, kRuns));
  EXPECT_GT(chi2, models::ChiSquareQuantile(0.001, kRuns));
}

// Consistent fits: the test, run after every fit with the level spent over the fits,
// rejects a run at some fit with probability at most 0.001; over many runs the count is
// bounded by the binomial's 0.999 quantile, and a run not rejected at its end widens
// nothing.
TEST(MapRotationSpread, ConsistentFitsAreRarelyRejected) {
  constexpr int kRuns = 400;
  std::mt19937_64 rng(5);
  int rejected = 0;
  for (int run = 0; run < kRuns; ++run) {
    bool ever = false;
    const association::MapRotationSpread spread = Fits(0.0, 300, &rng, nullptr, &ever);
    if (ever) ++rejected;
    if (!spread.rejected()) EXPECT_EQ(spread.sigma_rad(), 0.0);
  }
  EXPECT_LE(rejected, boost::math::quantile(boost::math::binomial(kRuns, 0.001), 0.999));
}

TEST(MapRotationSpread, TakesTheWideningOffAndSkipsWhatIsNotAFit) {
  association::MapRotationSpread a(0.999), b(0.999);
  a.Add(0.01, 4e-6);                // δ̂²/v = 25: beyond χ²₁(0.99) = 6.63
  b.Add(0.01, 4e-6 + 9e-6, 0.003);  // a map widened by 3 mrad: its fit's variance grew by 9e-6
  a.Add(0.004, 4e-6);               // 4: within
  b.Add(0.004, 4e-6 + 9e-6, 0.003);
  EXPECT_EQ(a.beyond(), 1);
  EXPECT_EQ(b.beyond(), 1);
  EXPECT_EQ(b.fits(), 2);
  b.Add(NAN, 1e-6);          // not reached
  b.Add(0.01, 4e-6, 0.003);  // nothing left of its variance once the widening is off
  b.Add(0.01, INFINITY);
  EXPECT_EQ(b.fits(), 2);
  // One gross outlier among a few fits is what the rotation test is for, not a spread.
  EXPECT_FALSE(a.rejected());
  association::MapRotationSpread off(0.0);
  for (int k = 0; k < 50; ++k) off.Add(0.1, 1e-6);
  EXPECT_FALSE(off.rejected());
  EXPECT_EQ(off.sigma_rad(), 0.0);
}

// Widened, a map's features take the spread and its end pose does not; Widened() leaves a
// map as it is while there is no spread.
TEST(MapRotationSpread, WidensTheFeaturesOnlyOnceRejected) {
  const LocalSubmap s = MakeRun(3, 2).submaps[0];
  std::mt19937_64 rng(1);
  const association::MapRotationSpread none = Fits(0.0, 10, &rng);
  ASSERT_FALSE(none.rejected());
  EXPECT_EQ(none.Widened(s).covariance, s.covariance);
  const association::MapRotationSpread spread = Fits(0.01, 200, &rng);
  ASSERT_TRUE(spread.rejected());
  const double sigma = spread.sigma_rad();
  EXPECT_GT(sigma, 0.005);
  const LocalSubmap w = spread.Widened(s);
  Eigen::VectorXd g = association::RotationAboutStart(s);
  g.head<3>().setZero();
  EXPECT_TRUE(w.covariance.isApprox(s.covariance + sigma * sigma * g * g.transpose(), 1e-12));
  EXPECT_EQ(Eigen::Matrix3d(w.covariance.topLeftCorner(3, 3)), Eigen::Matrix3d(s.covariance.topLeftCorner(3, 3)));
  EXPECT_EQ(w.mean, s.mean);
  EXPECT_DOUBLE_EQ(w.rotation_spread_rad, sigma);
  EXPECT_EQ(w.rotation_widening_rad, 0.0);
  EXPECT_NEAR(association::WidenedFeaturesByRotation(w, 0.02).rotation_spread_rad, std::hypot(sigma, 0.02), 1e-12);
  EXPECT_TRUE(w.Validate().ok());
}

}  // namespace
}  // namespace subslam::backend
