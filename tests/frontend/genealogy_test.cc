#include "subslam/frontend/genealogy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace subslam::frontend {
namespace {

std::vector<double> RandomWeights(int n, std::mt19937_64& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<double> w(n);
  double total = 0.0;
  for (double& v : w) total += v = std::exp(normal(rng));
  for (double& v : w) v /= total;
  return w;
}

// Systematic resampling of `weights`: the parent slot of each new slot.
std::vector<int> Systematic(const std::vector<double>& weights, std::mt19937_64& rng) {
  const int n = static_cast<int>(weights.size());
  const double u0 = std::uniform_real_distribution<double>(0.0, 1.0 / n)(rng);
  std::vector<int> parent(n);
  double cumulative = weights[0];
  int source = 0;
  for (int i = 0; i < n; ++i) {
    while (u0 + static_cast<double>(i) / n > cumulative && source + 1 < n) cumulative += weights[++source];
    parent[i] = source;
  }
  return parent;
}

// Against the definition: each particle's slot at every scan, kept in full; ρ_pq the
// share of scans at which p and q had one slot. Random genealogies, with resamplings to
// a single ancestor now and then (the class then drops what came before).
TEST(Genealogy, SharedAncestryEqualsThePairwiseDefinition) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  int checked = 0, pruned = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const int n = 2 + trial % 9;
    Genealogy genealogy;
    genealogy.Reset();
    std::vector<std::vector<int>> history(n);  // history[p][t]: p's slot at scan t
    EXPECT_EQ(genealogy.SharedAncestry(RandomWeights(n, rng)), 0.0);
    const int scans = 1 + trial % 23;
    for (int t = 0; t < scans; ++t) {
      genealogy.AddScan();
      for (int p = 0; p < n; ++p) history[p].push_back(p);
      const double u = uniform(rng);
      if (u < 0.5) {
        std::vector<int> parent = Systematic(RandomWeights(n, rng), rng);
        if (u < 0.05) parent.assign(n, static_cast<int>(uniform(rng) * n));  // one ancestor
        genealogy.AddResampling(parent);
        std::vector<std::vector<int>> next(n);
        for (int p = 0; p < n; ++p) next[p] = history[parent[p]];
        history.swap(next);
      }
      const std::vector<double> w = RandomWeights(n, rng);
      double expected = 0.0;
      for (int p = 0; p < n; ++p) {
        for (int q = 0; q < n; ++q) {
          int shared = 0;
          for (int s = 0; s <= t; ++s) shared += history[p][s] == history[q][s];
          expected += w[p] * w[q] * shared / (t + 1.0);
        }
      }
      ASSERT_NEAR(genealogy.SharedAncestry(w), expected, 1e-12) << "trial " << trial << " scan " << t;
      ++checked;
      pruned += genealogy.resamplings_kept() == 0 && t > 0;
    }
  }
  EXPECT_GT(checked, 2000);
  EXPECT_GT(pruned, 10);
}

// The claims behind the correction: particles that each add an independent N(0, 1) draw
// per scan, resampled now and then with weights independent of their values, have a
// weighted spread S = Σ w_p (x_p − x̄)² with E[S] = (1 − R) T, and a weighted mean with
// E[x̄²] = R T (the centre is 0). Over 20,000 runs the means of S / ((1 − R) T) and of
// x̄² / (R T) lie within 4 standard errors of 1; the uncorrected S / T does not.
TEST(Genealogy, CorrectedSpreadAndTheMeansErrorMatchIndependentDraws) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const int n = 10, scans = 12, runs = 20000;
  double sum_corrected = 0.0, sum_sq_corrected = 0.0, sum_plain = 0.0, sum_sq_plain = 0.0;
  double sum_mean = 0.0, sum_sq_mean = 0.0;
  for (int run = 0; run < runs; ++run) {
    Genealogy genealogy;
    genealogy.Reset();
    std::vector<double> x(n, 0.0);
    for (int t = 0; t < scans; ++t) {
      genealogy.AddScan();
      for (double& v : x) v += normal(rng);
      if (uniform(rng) < 0.6) {
        const std::vector<int> parent = Systematic(RandomWeights(n, rng), rng);
        genealogy.AddResampling(parent);
        std::vector<double> next(n);
        for (int p = 0; p < n; ++p) next[p] = x[parent[p]];
        x.swap(next);
      }
    }
    const std::vector<double> w = RandomWeights(n, rng);
    double mean = 0.0, spread = 0.0;
    for (int p = 0; p < n; ++p) mean += w[p] * x[p];
    for (int p = 0; p < n; ++p) spread += w[p] * (x[p] - mean) * (x[p] - mean);
    const double R = genealogy.SharedAncestry(w);
    ASSERT_LT(R, 1.0);
    const double corrected = spread / ((1.0 - R) * scans), plain = spread / scans;
    sum_corrected += corrected;
    sum_sq_corrected += corrected * corrected;
    sum_plain += plain;
    sum_sq_plain += plain * plain;
    const double mean_error = mean * mean / (R * scans);
    sum_mean += mean_error;
    sum_sq_mean += mean_error * mean_error;
  }
  const auto z = [runs](double sum, double sum_sq) {
    const double mean = sum / runs;
    const double se = std::sqrt((sum_sq / runs - mean * mean) / runs);
    return (mean - 1.0) / se;
  };
  EXPECT_LT(std::abs(z(sum_corrected, sum_sq_corrected)), 4.0) << "mean " << sum_corrected / runs;
  EXPECT_LT(z(sum_plain, sum_sq_plain), -4.0) << "mean " << sum_plain / runs;
  EXPECT_LT(std::abs(z(sum_mean, sum_sq_mean)), 4.0) << "mean " << sum_mean / runs;
}

}  // namespace
}  // namespace subslam::frontend
