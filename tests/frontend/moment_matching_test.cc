#include "subslam/frontend/moment_matching.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <random>

#include "test_util.h"

namespace subslam::frontend {
namespace {

using testing::MatricesNear;

FeatureHypothesis Feature(int id, double x, double y, double var, double existence = 1.0) {
  return {id, Eigen::Vector2d(x, y), var * Eigen::Matrix2d::Identity(), existence, NAN};
}

// Two particles, hand-computed Eqs. 6-7.
TEST(MomentMatch, TwoParticlesMatchTheClosedForm) {
  ParticleHypothesis a, b;
  a.weight = 0.25;
  a.pose = Pose2(1.0, 0.0, 0.1);
  a.pose_covariance = 0.01 * Eigen::Matrix3d::Identity();
  a.features = {Feature(7, 10.0, 2.0, 0.04)};
  b.weight = 0.75;
  b.pose = Pose2(2.0, 1.0, -0.1);
  b.pose_covariance = 0.02 * Eigen::Matrix3d::Identity();
  b.features = {Feature(7, 11.0, 4.0, 0.08)};
  const std::vector<ParticleHypothesis> particles = {a, b};
  const MomentMatchedGaussian g = MomentMatch(particles);

  ASSERT_EQ(g.features, std::vector<int>{7});
  Eigen::VectorXd xa(5), xb(5);
  xa << 1.0, 0.0, 0.1, 10.0, 2.0;
  xb << 2.0, 1.0, -0.1, 11.0, 4.0;
  const Eigen::VectorXd mean = 0.25 * xa + 0.75 * xb;
  Eigen::MatrixXd Pa = Eigen::MatrixXd::Zero(5, 5), Pb = Eigen::MatrixXd::Zero(5, 5);
  Pa.topLeftCorner(3, 3) = 0.01 * Eigen::Matrix3d::Identity();
  Pa.bottomRightCorner(2, 2) = 0.04 * Eigen::Matrix2d::Identity();
  Pb.topLeftCorner(3, 3) = 0.02 * Eigen::Matrix3d::Identity();
  Pb.bottomRightCorner(2, 2) = 0.08 * Eigen::Matrix2d::Identity();
  const Eigen::MatrixXd cov =
      0.25 * (Pa + (xa - mean) * (xa - mean).transpose()) + 0.75 * (Pb + (xb - mean) * (xb - mean).transpose());
  EXPECT_TRUE(MatricesNear(mean, g.mean, 1e-12));
  EXPECT_TRUE(MatricesNear(cov, g.covariance, 1e-12));
  EXPECT_EQ(g.covariance_repairs, 0);
  EXPECT_EQ(g.particles_used, 2);
}

// The shared-ancestry correction scales the spread term, and only it, by (1 + R) / (1 − R): on the
// fast path (every particle holds every feature) and on the per-block one.
TEST(MomentMatch, SharedAncestryScalesTheSpreadOnly) {
  ParticleHypothesis a, b, c;
  a.weight = 0.2;
  a.pose = Pose2(1.0, 0.0, 0.1);
  a.pose_covariance = 0.5 * Eigen::Matrix3d::Identity();
  a.features = {Feature(3, 10.0, 2.0, 1.0), Feature(5, 0.0, 7.0, 1.1)};
  b.weight = 0.5;
  b.pose = Pose2(2.0, 1.0, -0.1);
  b.pose_covariance = 0.6 * Eigen::Matrix3d::Identity();
  b.features = {Feature(3, 11.0, 4.0, 1.2), Feature(5, 1.0, 6.0, 1.3)};
  c.weight = 0.3;
  c.pose = Pose2(1.5, -1.0, 0.05);
  c.pose_covariance = 0.7 * Eigen::Matrix3d::Identity();
  c.features = {Feature(3, 9.0, 3.0, 1.4), Feature(5, -1.0, 8.0, 1.5)};
  const double R = 0.3;
  for (const bool complete : {true, false}) {
    std::vector<ParticleHypothesis> particles = {a, b, c};
    if (!complete) particles[2].features.pop_back();  // feature 5 held by a and b only
    MomentMatchingOptions options;
    options.min_existence = 0.5;
    const MomentMatchedGaussian plain = MomentMatch(particles, options);
    const MomentMatchedGaussian corrected = MomentMatch(particles, options, R);
    // Each block's own part: the weighted mean of the holders' covariances.
    Eigen::MatrixXd own = Eigen::MatrixXd::Zero(7, 7);
    double w5 = 0.0;
    for (const ParticleHypothesis& p : particles) {
      own.topLeftCorner<3, 3>() += p.weight * p.pose_covariance;
      own.block<2, 2>(3, 3) += p.weight * p.features[0].covariance;
      if (p.features.size() > 1) {
        own.block<2, 2>(5, 5) += p.weight * p.features[1].covariance;
        w5 += p.weight;
      }
    }
    own.block<2, 2>(5, 5) /= w5;
    ASSERT_EQ(plain.covariance_repairs + corrected.covariance_repairs, 0) << (complete ? "complete" : "per block");
    EXPECT_TRUE(MatricesNear(plain.mean, corrected.mean, 0.0));
    const Eigen::MatrixXd expected = (plain.covariance - own) * (1.0 + R) / (1.0 - R) + own;
    EXPECT_TRUE(MatricesNear(expected, corrected.covariance, 1e-12)) << (complete ? "complete" : "per block");
  }
}

// Unnormalised weights give the same Gaussian; a single particle gives its own.
TEST(MomentMatch, NormalizesWeightsAndReducesToOneParticle) {
  ParticleHypothesis a;
  a.weight = 3.0;
  a.pose = Pose2(1.0, 2.0, 0.3);
  a.pose_covariance = Eigen::Vector3d(0.1, 0.2, 0.01).asDiagonal();
  a.features = {Feature(1, 5, 5, 0.5), Feature(0, -1, 2, 0.25)};
  const std::vector<ParticleHypothesis> one = {a};
  const MomentMatchedGaussian g = MomentMatch(one);
  ASSERT_EQ(g.features, (std::vector<int>{0, 1}));  // ordered by common id
  Eigen::VectorXd expected(7);
  expected << 1, 2, 0.3, -1, 2, 5, 5;
  EXPECT_TRUE(MatricesNear(expected, g.mean, 1e-12));
  Eigen::VectorXd diag(7);
  diag << 0.1, 0.2, 0.01, 0.25, 0.25, 0.5, 0.5;
  EXPECT_TRUE(MatricesNear(Eigen::MatrixXd(diag.asDiagonal()), g.covariance, 1e-12));
}

// Headings either side of ±π average to π, not 0.
TEST(MomentMatch, HeadingsAverageAcrossTheWrap) {
  ParticleHypothesis a, b;
  a.pose = Pose2(0, 0, kPi - 0.1);
  b.pose = Pose2(0, 0, -kPi + 0.1);
  a.pose_covariance = b.pose_covariance = 1e-6 * Eigen::Matrix3d::Identity();
  const std::vector<ParticleHypothesis> particles = {a, b};
  const MomentMatchedGaussian g = MomentMatch(particles);
  EXPECT_NEAR(std::abs(g.mean[2]), kPi, 1e-12);
  EXPECT_NEAR(g.covariance(2, 2), 0.01 + 1e-6, 1e-12);
}

// A feature held by only some particles: ignored by the others (HybridSLAM), or the
// others are discarded (Combined SLAM); existence counts a missing feature as 0.
TEST(MomentMatch, MissingFeaturePolicies) {
  ParticleHypothesis a, b;
  a.weight = b.weight = 0.5;
  a.pose = Pose2(0, 0, 0);
  b.pose = Pose2(1, 0, 0);
  a.pose_covariance = b.pose_covariance = 0.01 * Eigen::Matrix3d::Identity();
  a.features = {Feature(0, 5, 0, 0.1), Feature(1, 8, 8, 0.2)};
  b.features = {Feature(0, 6, 0, 0.1)};
  const std::vector<ParticleHypothesis> particles = {a, b};

  MomentMatchingOptions options;
  const MomentMatchedGaussian strict = MomentMatch(particles, options);
  EXPECT_EQ(strict.features, std::vector<int>{0});  // feature 1: existence 0.5 < 0.95

  options.min_existence = 0.4;
  const MomentMatchedGaussian ignore = MomentMatch(particles, options);
  ASSERT_EQ(ignore.features, (std::vector<int>{0, 1}));
  EXPECT_NEAR(ignore.existence[1], 0.5, 1e-12);
  EXPECT_NEAR(ignore.mean[0], 0.5, 1e-12);  // the pose over both particles
  EXPECT_TRUE(MatricesNear(Eigen::Vector2d(8, 8), ignore.mean.segment<2>(5), 1e-12));
  // Feature 1's block is particle a's own (the only holder), uncorrelated with the
  // pose and feature 0 (no spread within a single holder).
  EXPECT_TRUE(MatricesNear(0.2 * Eigen::Matrix2d::Identity(), ignore.covariance.block(5, 5, 2, 2), 1e-12));
  EXPECT_TRUE(MatricesNear(Eigen::MatrixXd::Zero(5, 2), ignore.covariance.block(0, 5, 5, 2), 1e-12));
  EXPECT_EQ(ignore.particles_used, 2);

  options.missing = MissingFeaturePolicy::kDiscardParticle;
  const MomentMatchedGaussian discard = MomentMatch(particles, options);
  EXPECT_EQ(discard.particles_used, 1);
  EXPECT_FALSE(discard.fell_back_to_ignore);
  EXPECT_NEAR(discard.mean[0], 0.0, 1e-12);  // particle a alone
  EXPECT_NEAR(discard.mean[3], 5.0, 1e-12);
}

TEST(MomentMatch, DuplicateFeaturesInOneParticle) {
  ParticleHypothesis a;
  a.pose_covariance = 0.01 * Eigen::Matrix3d::Identity();
  a.features = {Feature(3, 0, 0, 1.0, 0.96), Feature(3, 2, 0, 1.0, 0.99)};
  const std::vector<ParticleHypothesis> particles = {a};
  MomentMatchingOptions options;
  const MomentMatchedGaussian highest = MomentMatch(particles, options);
  EXPECT_NEAR(highest.mean[3], 2.0, 1e-12);  // the more likely duplicate
  options.duplicates = DuplicateFeaturePolicy::kFuse;
  const MomentMatchedGaussian fused = MomentMatch(particles, options);
  EXPECT_NEAR(fused.mean[3], 1.0, 1e-12);  // product of two equal-covariance Gaussians
  EXPECT_NEAR(fused.covariance(3, 3), 0.5, 1e-12);
}

// Random particle sets with features missing here and there: the result is always
// symmetric positive definite (repaired if ever needed, and then counted).
TEST(MomentMatch, RandomSetsGiveSymmetricPositiveDefiniteCovariances) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::bernoulli_distribution missing(0.2);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<ParticleHypothesis> particles(20);
    for (ParticleHypothesis& p : particles) {
      p.weight = 0.5 + 0.5 * u(rng);
      p.pose = Pose2(u(rng), u(rng), 0.1 * u(rng));
      p.pose_covariance = 1e-4 * Eigen::Matrix3d::Identity();
      for (int f = 0; f < 6; ++f) {
        if (missing(rng)) continue;
        p.features.push_back(Feature(f, 3 * f + u(rng), u(rng), 0.01));
      }
    }
    MomentMatchingOptions options;
    options.min_existence = 0.5;
    const MomentMatchedGaussian g = MomentMatch(particles, options);
    EXPECT_LT((g.covariance - g.covariance.transpose()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(g.covariance).info(), Eigen::Success);
    EXPECT_TRUE(std::is_sorted(g.features.begin(), g.features.end()));
  }
}

TEST(RepairCovariance, LeavesPositiveDefiniteAloneAndRepairsIndefinite) {
  Eigen::MatrixXd good = Eigen::Vector3d(1.0, 2.0, 3.0).asDiagonal();
  const Eigen::MatrixXd before = good;
  EXPECT_FALSE(RepairCovariance(&good, 1e-9));
  EXPECT_EQ(good, before);
  Eigen::MatrixXd bad(2, 2);
  bad << 1.0, 2.0, 2.0, 1.0;  // eigenvalues 3 and −1
  EXPECT_TRUE(RepairCovariance(&bad, 1e-6));
  EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(bad).info(), Eigen::Success);
  EXPECT_NEAR(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(bad).eigenvalues().maxCoeff(), 3.0, 1e-12);
}

// A local map closed one step after it opened: the pose covariance J M Jᵀ has rank 2
// (three pose variables, two control noises) and only rounding keeps its Cholesky factor
// alive. It is repaired to condition 1 / floor, its large eigenvalues kept.
TEST(RepairCovariance, RepairsANumericallySingularCovariance) {
  Eigen::Matrix<double, 3, 2> J;  // ∂(x, y, θ)/∂(v, ω) of a 0.1 s step at 1 m/s
  J << 0.1, 0.0, 0.0, 0.005, 0.0, 0.1;
  const Eigen::Matrix2d M = Eigen::Vector2d(0.26 * 0.26, 0.0093 * 0.0093).asDiagonal();
  Eigen::MatrixXd singular = J * M * J.transpose() + 1e-22 * Eigen::Matrix3d::Identity();
  ASSERT_EQ(Eigen::LLT<Eigen::MatrixXd>(singular).info(), Eigen::Success);
  const Eigen::Vector3d before = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(singular).eigenvalues();
  ASSERT_LT(before[0], 1e-13 * before[2]);
  EXPECT_TRUE(RepairCovariance(&singular, 1e-9));
  const Eigen::Vector3d after = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(singular).eigenvalues();
  EXPECT_NEAR(after[0], 1e-9 * before[2], 1e-12 * before[2]);
  EXPECT_NEAR(after[1], before[1], 1e-12 * before[2]);
  EXPECT_NEAR(after[2], before[2], 1e-12 * before[2]);
  // Conditioned just inside the floor: left alone.
  Eigen::MatrixXd conditioned = Eigen::Vector3d(1.0, 1e-3, 1e-8).asDiagonal();
  const Eigen::MatrixXd kept = conditioned;
  EXPECT_FALSE(RepairCovariance(&conditioned, 1e-9));
  EXPECT_EQ(conditioned, kept);
}

}  // namespace
}  // namespace subslam::frontend
