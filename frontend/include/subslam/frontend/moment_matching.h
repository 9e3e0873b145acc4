// Conversion of a weighted set of particle hypotheses (a Gaussian mixture) to one
// Gaussian by moment matching (HybridSLAM, Brooks & Bailey, §2.2-3.2, Eqs. 6-9):
//   x = Σ_p w_p x_p,   P = Σ_p w_p [P_p + (x_p − x)(x_p − x)ᵀ],
// with x_p = [pose_p, μ_{δ(1,p)}, …, μ_{δ(N,p)}] ordered by common feature id and P_p
// block-diagonal (the particle's pose covariance, then its landmark covariances).
//
// Headings are averaged as wrapped deviations from the heaviest particle's heading, so
// particles on both sides of ±π average correctly.
//
// Corner cases (documented options):
//  * A particle holding several landmarks voted to the same common feature: the one
//    with the highest existence is used (HybridSLAM picks one at random), or the
//    duplicates are fused (product of their Gaussians).
//  * A common feature missing from some particles: kIgnoreParticle (HybridSLAM) leaves
//    those particles out of that feature's moments — each mean and covariance block is
//    taken over the particles holding the feature(s) involved, with the weights
//    renormalised; kDiscardParticle (Combined SLAM) uses only the particles holding
//    every exported feature. Ignoring can in rare cases give an indefinite matrix: it
//    is then repaired by raising its eigenvalues to a floor, and the repair is counted.
//  * Existence of a common feature: Σ_p w_p e_p with e_p = 0 for a particle lacking it,
//    so features the particles disagree about get a low existence; only features with
//    existence ≥ min_existence are exported.
#ifndef SUBSLAM_FRONTEND_MOMENT_MATCHING_H_
#define SUBSLAM_FRONTEND_MOMENT_MATCHING_H_

#include <Eigen/Core>
#include <limits>
#include <span>
#include <vector>

#include "subslam/core/pose2.h"

namespace subslam::frontend {

struct FeatureHypothesis {
  int feature = 0;  // common feature id
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  double existence = 1.0;
  double signature = std::numeric_limits<double>::quiet_NaN();  // NaN when absent
};

struct ParticleHypothesis {
  double weight = 1.0;  // ≥ 0; normalised inside
  Pose2 pose;
  Eigen::Matrix3d pose_covariance = Eigen::Matrix3d::Zero();
  std::vector<FeatureHypothesis> features;  // any order; ids may repeat
};

enum class MissingFeaturePolicy { kIgnoreParticle, kDiscardParticle };
enum class DuplicateFeaturePolicy { kHighestExistence, kFuse };

struct MomentMatchingOptions {
  MissingFeaturePolicy missing = MissingFeaturePolicy::kIgnoreParticle;
  DuplicateFeaturePolicy duplicates = DuplicateFeaturePolicy::kHighestExistence;
  // Export only common features whose existence (see above) is at least this.
  double min_existence = 0.95;
  // Eigenvalue floor of the exported covariance (relative to its largest eigenvalue): an
  // indefinite or more ill-conditioned one is repaired (see RepairCovariance; counted).
  double repair_relative_floor = 1e-9;
};

struct MomentMatchedGaussian {
  Eigen::VectorXd mean;  // [pose (3), feature 1 (2), …], features by increasing id
  Eigen::MatrixXd covariance;
  std::vector<int> features;  // common ids, increasing
  std::vector<double> existence;
  std::vector<double> signature;  // weighted mean over particles holding it (NaN if none)
  // Known association only (else empty): each feature's true landmark id (−1: unknown).
  std::vector<int> truth_id;
  int covariance_repairs = 0;
  int particles_used = 0;            // with nonzero weight (kDiscardParticle: holding all)
  bool fell_back_to_ignore = false;  // kDiscardParticle found no particle holding all
};

// Makes a symmetric matrix positive definite and conditioned at most 1 / relative_floor,
// by raising every eigenvalue below relative_floor × the largest (at least 1e-15) to that
// floor. Returns whether it changed the matrix. An ill-conditioned covariance is
// repaired too: e.g. a local map closed one step after it opened has a rank-2 pose
// covariance (three pose variables, two control noises), which no joiner can whiten.
bool RepairCovariance(Eigen::MatrixXd* covariance, double relative_floor);

// Requires at least one particle with positive weight.
//
// `shared_ancestry` R ∈ [0, 1) accounts for particles that are not independent
// samples: with x_p = μ + e_p, Cov(e_p, e_q) = ρ_pq Σ (ρ_pp = 1) and R = Σ_pq w_p w_q ρ_pq,
//   E[Σ_p w_p (x_p − x)(x_p − x)ᵀ] = (1 − R) Σ   and   Cov(x − μ) = R Σ:
// the spread S = Σ_p w_p (x_p − x)(x_p − x)ᵀ under-states Σ, and the mean x, the
// Gaussian's centre, is itself off by a Monte Carlo error. The Gaussian's covariance
// must cover both the posterior's spread Σ and that error, so the spread term is
// S (1 + R) / (1 − R). For independent particles R = Σ_p w_p² (the unbiased weighted
// covariance, and the variance of a weighted mean); a particle filter's particles share
// their ancestors' noise, and R is larger (FastSlam::SharedAncestry). 0 (the default):
// the mixture's own moments, Eqs. 6-7. The particles' own covariances P_p are not
// scaled. One R serves every block — two approximations: where a block's weights are
// renormalised over the particles holding its features (it matters little for exported
// features, which hold min_existence (0.95) of the weight), and for landmarks, which
// depend only on the pose draws up to their observations, so that their share of
// common ancestry (their R) is larger than the end pose's: their blocks are
// under-corrected.
// The factor on the spread that shared_ancestry R stands for (see MomentMatch):
// (1 + R) / (1 − R).
double SharedAncestrySpreadScale(double shared_ancestry);

MomentMatchedGaussian MomentMatch(std::span<const ParticleHypothesis> particles,
                                  const MomentMatchingOptions& options = {}, double shared_ancestry = 0.0);

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_MOMENT_MATCHING_H_
