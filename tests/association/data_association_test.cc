#include "subslam/association/data_association.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>
#include <random>

#include "subslam/models/gating.h"

namespace subslam::association {
namespace {

AssociationCandidate C(int landmark, double nu0, double nu1) {
  // Unit innovation covariance: d² = ‖ν‖².
  return {landmark, nu0 * nu0 + nu1 * nu1, Eigen::Vector2d(nu0, nu1)};
}

TEST(NearestNeighbour, OneToOneInIncreasingDistance) {
  AssociationProblem p;
  p.candidates = {{C(0, 0.5, 0), C(1, 1.0, 0)}, {C(0, 0.1, 0)}};
  const AssociationResult r = NearestNeighbour(p);
  // Detection 1 is closer to landmark 0, so detection 0 falls back to landmark 1.
  EXPECT_EQ(r.landmark_of_detection, (std::vector<int>{1, 0}));
  EXPECT_EQ(r.pairings, 2);
}

TEST(JointCompatibility, RejectsJointlyIncompatiblePairings) {
  // Two landmarks whose predicted measurements are strongly correlated (a shared pose
  // error): individually both pairings pass, but their innovations point in opposite
  // directions, which the joint covariance makes implausible.
  AssociationProblem p;
  p.candidates = {{C(0, 2.0, 0)}, {C(1, -2.0, 0)}};
  p.covariance_block = [](int, int a, int, int b) -> Eigen::Matrix2d {
    return Eigen::Matrix2d::Identity() * (a == b ? 1.0 : 0.95);
  };
  const AssociationResult nn = NearestNeighbour(p);
  EXPECT_EQ(nn.pairings, 2);
  const AssociationResult jc = JointCompatibility(p, 0.99, 1000);
  EXPECT_EQ(jc.pairings, 1);
  EXPECT_FALSE(jc.truncated);
  // With independent landmarks, both pairings are jointly compatible.
  p.covariance_block = [](int, int a, int, int b) -> Eigen::Matrix2d {
    return Eigen::Matrix2d::Identity() * (a == b ? 1.0 : 0.0);
  };
  const AssociationResult both = JointCompatibility(p, 0.99, 1000);
  EXPECT_EQ(both.pairings, 2);
  EXPECT_NEAR(both.joint_d2, 8.0, 1e-12);
}

TEST(JointCompatibility, PrefersConsistentShiftedHypothesis) {
  // Detections shifted consistently by the same pose error: JCBB pairs them with the
  // landmarks that agree on the shift rather than the individually nearest ones.
  AssociationProblem p;
  p.candidates = {{C(1, 0.2, 0), C(0, 1.5, 0)}, {C(1, 1.5, 0), C(2, -2.8, 0)}};
  p.covariance_block = [](int, int a, int, int b) -> Eigen::Matrix2d {
    return Eigen::Matrix2d::Identity() * (a == b ? 1.0 : 0.9);
  };
  EXPECT_EQ(NearestNeighbour(p).landmark_of_detection, (std::vector<int>{1, 2}));
  const AssociationResult r = JointCompatibility(p, 0.99, 1000);
  EXPECT_EQ(r.pairings, 2);
  EXPECT_EQ(r.landmark_of_detection, (std::vector<int>{0, 1}));
}

// Required pairings are in every hypothesis, ungated, and the others are gated given
// them: d² − d²_required against χ²_{2k} for their k pairings. Detection 1's pairing
// (d² = 10, independent of detection 0's) fails χ²₂(0.99) = 9.21 given detection 0's;
// searched together with detection 0's instead, the pair passes χ²₄(0.99) = 13.28.
TEST(JointCompatibility, GatesTheOtherPairingsGivenTheRequiredOnes) {
  AssociationProblem p;
  p.candidates = {{C(0, 0.0, 0.0)}, {C(1, std::sqrt(10.0), 0.0)}};
  p.covariance_block = [](int, int a, int, int b) -> Eigen::Matrix2d {
    return Eigen::Matrix2d::Identity() * (a == b ? 1.0 : 0.0);
  };
  EXPECT_EQ(JointCompatibility(p, 0.99, 1000).pairings, 2);
  p.required = {1, 0};
  const AssociationResult given = JointCompatibility(p, 0.99, 1000);
  EXPECT_EQ(given.landmark_of_detection, (std::vector<int>{0, -1}));
  // A required pairing is kept whatever its d² (decided before), and counted.
  p.candidates = {{C(0, 4.0, 0.0)}, {C(1, 1.0, 0.0)}};
  const AssociationResult kept = JointCompatibility(p, 0.99, 1000);
  EXPECT_EQ(kept.landmark_of_detection, (std::vector<int>{0, 1}));
  EXPECT_NEAR(kept.joint_d2, 17.0, 1e-12);
  // Not required, the first pairing alone fails its gate (16 > 9.21).
  p.required.clear();
  EXPECT_EQ(JointCompatibility(p, 0.99, 1000).landmark_of_detection, (std::vector<int>{-1, 1}));
}

// The joint d² JCBB reports for its hypothesis (built one 2 × 2 block row of the
// Cholesky factor at a time) equals νᵀ S⁻¹ ν from the dense joint innovation covariance of
// the chosen pairings, on random problems with up to eight pairings, correlated landmarks
// and several candidates per detection.
TEST(JointCompatibility, JointD2EqualsTheDenseMahalanobisDistance) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal;
  std::uniform_int_distribution<int> landmark_of(0, 11);
  int checked_large = 0;
  for (int trial = 0; trial < 40; ++trial) {
    // Landmark prediction covariance: a random SPD 24 × 24 (12 landmarks, shared pose error).
    Eigen::MatrixXd G(24, 24);
    for (int r = 0; r < 24; ++r) {
      for (int c = 0; c < 24; ++c) G(r, c) = 0.3 * normal(rng);
    }
    const Eigen::MatrixXd P = G * G.transpose() / 24.0 + 0.05 * Eigen::MatrixXd::Identity(24, 24);
    AssociationProblem p;
    p.covariance_block = [P](int i, int a, int j, int b) -> Eigen::Matrix2d {
      Eigen::Matrix2d block = P.block<2, 2>(2 * a, 2 * b);
      if (i == j && a == b) block += 0.1 * Eigen::Matrix2d::Identity();  // measurement noise
      return block;
    };
    p.candidates.resize(8);
    for (int j = 0; j < 8; ++j) {
      const int count = 1 + trial % 3;
      std::vector<int> used;
      for (int c = 0; c < count; ++c) {
        int a = landmark_of(rng);
        while (std::find(used.begin(), used.end(), a) != used.end()) a = landmark_of(rng);
        used.push_back(a);
        const Eigen::Vector2d nu(0.3 * normal(rng), 0.3 * normal(rng));
        const Eigen::Matrix2d S = p.covariance_block(j, a, j, a);
        p.candidates[j].push_back({a, nu.dot(S.inverse() * nu), nu});
      }
      std::sort(p.candidates[j].begin(), p.candidates[j].end(),
                [](const AssociationCandidate& x, const AssociationCandidate& y) { return x.d2 < y.d2; });
    }
    const AssociationResult r = JointCompatibility(p, 0.99, 100000);
    ASSERT_FALSE(r.truncated);
    std::vector<int> detections;
    for (int j = 0; j < 8; ++j) {
      if (r.landmark_of_detection[j] >= 0) detections.push_back(j);
    }
    ASSERT_EQ(static_cast<int>(detections.size()), r.pairings);
    const int k = r.pairings;
    Eigen::MatrixXd S(2 * k, 2 * k);
    Eigen::VectorXd nu(2 * k);
    for (int x = 0; x < k; ++x) {
      const int i = detections[x], a = r.landmark_of_detection[i];
      for (const AssociationCandidate& c : p.candidates[i]) {
        if (c.landmark == a) nu.segment<2>(2 * x) = c.innovation;
      }
      for (int y = 0; y < k; ++y) {
        const int j = detections[y];
        S.block<2, 2>(2 * x, 2 * y) = p.covariance_block(i, a, j, r.landmark_of_detection[j]);
      }
    }
    const double dense = k == 0 ? 0.0 : nu.dot(S.ldlt().solve(nu));
    EXPECT_NEAR(r.joint_d2, dense, 1e-9 * std::max(1.0, dense)) << "trial " << trial << ", " << k << " pairings";
    EXPECT_LE(r.joint_d2, models::ChiSquareQuantile(0.99, std::max(1, 2 * k)));
    checked_large += k >= 5 ? 1 : 0;
  }
  EXPECT_GT(checked_large, 10);
}

// Detections without candidates do not spend the search budget: among 500 detections of
// which 3 have candidates, a 20-node budget still finds the full hypothesis (a search
// that branched on every detection would spend 500 nodes per hypothesis).
TEST(JointCompatibility, DetectionsWithoutCandidatesCostNothing) {
  AssociationProblem p;
  p.candidates.resize(500);
  p.candidates[10] = {C(0, 0.3, 0)};
  p.candidates[250] = {C(1, 0, 0.2), C(2, 0.5, 0.5)};
  p.candidates[499] = {C(3, 0.1, 0.1)};
  p.covariance_block = [](int, int a, int, int b) -> Eigen::Matrix2d {
    return Eigen::Matrix2d::Identity() * (a == b ? 1.0 : 0.0);
  };
  const AssociationResult r = JointCompatibility(p, 0.99, 20);
  EXPECT_FALSE(r.truncated);
  EXPECT_EQ(r.pairings, 3);
  EXPECT_EQ(r.landmark_of_detection[10], 0);
  EXPECT_EQ(r.landmark_of_detection[250], 1);
  EXPECT_EQ(r.landmark_of_detection[499], 3);
  EXPECT_EQ(r.landmark_of_detection[0], -1);
}

// JCBB's search, with its pruning bounds, finds the hypothesis an exhaustive search does:
// the most pairings, then the smallest joint d², among the one-to-one hypotheses whose
// every prefix (in the branching order: fewest candidates first, ties in detection
// order) passes the joint χ² gate. Random problems with a shared pose error (strongly
// correlated innovations), several candidates per detection and candidates shared
// between detections.
TEST(JointCompatibility, EqualsExhaustiveSearch) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  std::uniform_int_distribution<int> detections(1, 6), landmarks(1, 5);
  for (int trial = 0; trial < 300; ++trial) {
    const int m = detections(rng), n = landmarks(rng);
    // ν_ia = J_a p + l_a + q_i: covariance J_a P J_bᵀ + [a = b] L_a + [i = k] Q.
    std::vector<Eigen::Matrix<double, 2, 3>> J(n);
    for (auto& j : J) j = Eigen::Matrix<double, 2, 3>::NullaryExpr([&] { return normal(rng); });
    const Eigen::Matrix3d P = 0.5 * Eigen::Matrix3d::Identity();
    AssociationProblem p;
    p.covariance_block = [&](int i, int a, int k, int b) -> Eigen::Matrix2d {
      Eigen::Matrix2d c = J[a] * P * J[b].transpose();
      if (a == b) c += 0.3 * Eigen::Matrix2d::Identity();
      if (i == k) c += 0.2 * Eigen::Matrix2d::Identity();
      return c;
    };
    p.candidates.resize(m);
    std::bernoulli_distribution keep(0.6);
    for (int j = 0; j < m; ++j) {
      for (int a = 0; a < n; ++a) {
        if (!keep(rng)) continue;
        const Eigen::Vector2d nu(normal(rng), normal(rng));
        const Eigen::Matrix2d S = p.covariance_block(j, a, j, a);
        p.candidates[j].push_back({a, nu.dot(S.inverse() * nu), nu});
      }
      std::sort(p.candidates[j].begin(), p.candidates[j].end(),
                [](const auto& x, const auto& y) { return x.d2 < y.d2; });
    }
    // Exhaustive search, in the branching order.
    std::vector<int> order(m);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return p.candidates[a].size() < p.candidates[b].size(); });
    int best_pairings = 0;
    double best_d2 = 0.0;
    std::vector<int> current(m, -1);
    const auto joint_d2 = [&](int upto) {  // over the pairings of the first `upto` detections in order
      std::vector<std::pair<int, int>> pairs;
      for (int t = 0; t < upto; ++t) {
        if (current[order[t]] >= 0) pairs.push_back({order[t], current[order[t]]});
      }
      const int k = static_cast<int>(pairs.size());
      Eigen::MatrixXd S(2 * k, 2 * k);
      Eigen::VectorXd nu(2 * k);
      for (int x = 0; x < k; ++x) {
        for (const AssociationCandidate& c : p.candidates[pairs[x].first]) {
          if (c.landmark == pairs[x].second) nu.segment<2>(2 * x) = c.innovation;
        }
        for (int y = 0; y < k; ++y) {
          S.block<2, 2>(2 * x, 2 * y) =
              p.covariance_block(pairs[x].first, pairs[x].second, pairs[y].first, pairs[y].second);
        }
      }
      return k == 0 ? 0.0 : nu.dot(S.llt().solve(nu));
    };
    std::function<void(int, int)> search = [&](int t, int k) {
      if (t == m) {
        const double d2 = joint_d2(m);
        if (k > best_pairings || (k == best_pairings && d2 < best_d2)) {
          best_pairings = k;
          best_d2 = d2;
        }
        return;
      }
      const int j = order[t];
      search(t + 1, k);  // unpaired
      for (const AssociationCandidate& c : p.candidates[j]) {
        if (std::find(current.begin(), current.end(), c.landmark) != current.end()) continue;
        current[j] = c.landmark;
        if (joint_d2(t + 1) <= models::ChiSquareQuantile(0.99, 2 * (k + 1))) search(t + 1, k + 1);
        current[j] = -1;
      }
    };
    search(0, 0);
    const AssociationResult r = JointCompatibility(p, 0.99, 1000000);
    ASSERT_FALSE(r.truncated);
    ASSERT_EQ(r.pairings, best_pairings) << "trial " << trial;
    EXPECT_NEAR(r.joint_d2, best_d2, 1e-9 * std::max(1.0, best_d2)) << "trial " << trial;
  }
}

}  // namespace
}  // namespace subslam::association
