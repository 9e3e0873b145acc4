// Revisable association: the information form keeps every local map's factor, so an
// association decided at join time need not be final. Two revisions, decided on the
// current estimate and its exact marginals, shared by every back-end:
//
//  - merge: two global landmarks a, b are one point when the χ² test of their difference
//    Δ = L_a − L_b against zero, with the difference's covariance from their joint
//    marginal (Σ_aa + Σ_bb − Σ_ab − Σ_ba), accepts at `merge_probability` (2 dof); no
//    local map holds both as distinct features (one sensor sweep saw two points); each is
//    the other's best partner (smallest d²); and the pair is unambiguous: neither has
//    another partner that a local map holds apart from the first (then it could be
//    either of two distinct points: a shifted loop closure on a lattice, say). Copies of
//    one point never held apart collapse pair by pair over passes. And the pair's
//    relative position is known: 3σ of Cov(Δ) below the association's loop-test radius
//    (SubmapAssociationOptions::loop_test_min_sigma_radius_m). Two landmarks known
//    relative to each other only to metres are a loop closure with one pairing, in the
//    regime where association asks for several (min_loop_pairings): not a merge.
//    (Also, with merge_unresolved, a pair closer than any one local map could resolve,
//    and with merge_by_density, a pair the χ² test holds apart that one point explains
//    better than two points of the map's local density.)
//    The joiner then solves for the merged landmark (the conditional mean given Δ = 0).
//  - loop merge (merge_loops): pairs that pass the χ² test but are known relative to
//    each other only to metres are merged together when there are at least the
//    association's min_loop_pairings of them whose differences are jointly compatible
//    (JCBB over the candidate pairs with their differences' joint covariance: one loop
//    offset explains them all) and no other jointly compatible choice of as many pairs
//    remains once theirs are struck out (the association's ambiguity test). Copies left
//    by loop closures too thin to make at join time — local maps with fewer features than
//    min_loop_pairings, as when few landmarks are detected — so close the loop once
//    enough of them have accumulated. Only pairs known to 3σ below the association's
//    loop_confirmation_min_sigma_radius_m take part: beyond it a match is relocalisation,
//    where association makes no closure without the confirmation of later maps, and a
//    merge has no later maps to ask.
//  - split: a feature i of a local map leaves its landmark j (for a landmark of its own)
//    when its residual r = P_s⁻¹·L_j − l_i fails the outlier test: rᵀ C⁻¹ r with
//    C = Q_ii − J Σ Jᵀ, the residual's covariance in the linear-Gaussian model (Q_ii the
//    feature's covariance in its local map, Σ the marginal of [P_s, L_j], J the
//    prediction's Jacobian), above the χ²₂ quantile at a family-wise level: with m
//    features tested, each at 1 − (1 − split_probability)/m (Bonferroni), so a consistent
//    map loses no feature by chance in a pass with probability split_probability. Only
//    landmarks with two or more features are tested. One gross error distorts the whole
//    estimate, so a pass splits only the worst feature; the next pass tests again on the
//    estimate solved without it.
//
// The split level (Bonferroni over a pass) is stricter than the merge level per test, so
// a feature split off is not merged back at once on the same evidence (hysteresis).
#ifndef SUBSLAM_ASSOCIATION_LANDMARK_REVISION_H_
#define SUBSLAM_ASSOCIATION_LANDMARK_REVISION_H_

#include <Eigen/Core>
#include <functional>
#include <vector>

#include "absl/status/status.h"
#include "subslam/association/relative_covariance_bounds.h"
#include "subslam/core/submap_graph.h"

namespace subslam::association {

struct LandmarkRevisionOptions {
  bool merge = true;
  double merge_probability = 0.99;  // χ²₂ acceptance of "the same point"
  // Also merge a pair that a single local map could not tell apart: Δᵀ (Q̃_a + Q̃_b)⁻¹ Δ
  // below the same gate, Q̃ each landmark's typical feature covariance (the median by
  // trace of its features', in the world frame). A landmark fixed by many local maps has
  // a marginal far tighter than any one map's feature, and the maps' small shared errors
  // then separate two estimates of one point statistically (pairs centimetres apart at
  // d² well beyond the gate) although no sensor sweep ever resolved two points there. The
  // other conditions of a merge hold as for the first test.
  bool merge_unresolved = true;
  // Also merge a pair that the χ² test holds apart but that lies inside the outer gate
  // χ²₂(density_gate_probability), when one point explains their difference better than
  // two distinct points at the map's local density: N(Δ; 0, Cov(Δ)) > ρ̂ [1/m²], with
  // ρ̂ = k / (π r²), k the landmarks within r = density_radius_m of the pair's midpoint
  // other than one of the pair (so at least 1). The likelihood ratio of "one point"
  // against "another landmark of the neighbourhood", at even prior odds. Local maps
  // over-confident by a few σ leave copies of one point 3–4σ apart; where landmarks stand that densely
  // (a lattice, a row of trees) or the difference is uncertain, two points are the
  // likelier explanation and the pair stays apart. The other conditions of a merge hold
  // as for the first test, and a pair this test accepts is a partner like one the first
  // accepts (for "best partner" and "unambiguous"). The outer gate bounds how far off a
  // copy may be: merged, a feature of a local map over-confident beyond it bends the
  // estimate to fit, and a loop closed by the next local maps can be missed
  // (docs/design/association.md).
  bool merge_by_density = true;
  double density_gate_probability = 0.999;  // in (0, 1); at or below merge_probability: no effect
  double density_radius_m = 10.0;           // as the association's candidate radius (TH2)
  // Off by default: the wrong merges it is for are mostly joint loop-closure decisions
  // that the estimate bends to fit, below a per-feature test, while a pass per split is
  // costly (docs/design/association.md).
  bool split = false;
  double split_probability = 0.99;  // family-wise, over the features tested in a pass
  // A revision pass runs after every relinearisation that follows a join, at the end,
  // after a whole-map (tree) join, and every `every_joins` joins (0: not on a schedule).
  // Passes during the run keep the online estimate tied where copies appear; each applied
  // merge is followed by a Gauss-Newton, which is what the passes cost
  // (docs/design/association.md).
  int every_joins = 10;
  bool merge_loops = true;

  bool enabled() const { return merge || split; }
  absl::Status Validate() const;
};

struct LandmarkMerge {
  int keep = 0;  // the lower index
  int drop = 0;  // the higher index (erased)
  double d2 = 0.0;
};

struct FeatureSplit {
  int factor = 0;   // index into the graph's factors
  int feature = 0;  // feature of that factor's local map
  double d2 = 0.0;
};

// Joint marginal covariance [L_a, L_b] (4 × 4).
using LandmarkPairCovarianceFn = std::function<Eigen::Matrix4d(int a, int b)>;
// Joint marginal covariance of the listed landmarks (2 rows each, in order).
using LandmarkJointCovarianceFn = std::function<Eigen::MatrixXd(const std::vector<int>& landmarks)>;
// For each landmark, the 5 × 5 marginal of [anchor, landmark] (a fixed anchor: zero rows).
using AnchorLandmarkCovarianceFn =
    std::function<std::vector<Eigen::Matrix<double, 5, 5>>(int anchor, const std::vector<int>& landmarks)>;

// The merges the test accepts on `graph`'s current estimate, disjoint, ordered by `drop`
// descending (so that applying them in order keeps the later indices valid).
// `loop_sigma_radius_m` is the association's loop-test radius (3σ, metres).
// `marginals` holds every landmark's marginal covariance, or an upper bound on it (for
// the pre-filter: a pair farther apart than √gate · (σ_a + σ_b), σ the largest standard
// deviation, cannot pass). With `touched` (one flag per landmark) only pairs with a
// touched landmark are tested: those whose own evidence changed since the last pass.
// Loop merges need `joint_covariance` and the association's loop tests (`loop_merges`).
// A pair is asked for its joint marginal only if it may pass: besides the scalar
// pre-filter, Cov(l_a − l_b) ⪯ 2(Σ_a + Σ_b) and the bounds kept in `relative_bounds`
// (relative_covariance_bounds.h; filled with every pair recovered) bound its d² from
// below, and a pair whose bound is beyond every gate is skipped; the merges found are
// those without the bounds.
struct LoopMergeTests {
  int min_pairings = 0;             // min_loop_pairings (< 1: no loop merges)
  double max_sigma_radius_m = 0.0;  // loop_confirmation_min_sigma_radius_m
  LandmarkJointCovarianceFn joint_covariance;
};
std::vector<LandmarkMerge> FindLandmarkMerges(const SubmapGraph& graph, const std::vector<Eigen::Matrix2d>& marginals,
                                              const LandmarkPairCovarianceFn& pair_covariance,
                                              const LandmarkRevisionOptions& options, double loop_sigma_radius_m,
                                              const std::vector<char>& touched = {},
                                              const LoopMergeTests& loop_merges = {},
                                              RelativeCovarianceBounds* relative_bounds = nullptr);

// The worst feature whose residual fails the outlier test (empty: none fails), of a
// landmark that keeps at least one other feature.
std::vector<FeatureSplit> FindFeatureSplits(const SubmapGraph& graph,
                                            const AnchorLandmarkCovarianceFn& anchor_landmark_covariance,
                                            const LandmarkRevisionOptions& options);

}  // namespace subslam::association

#endif  // SUBSLAM_ASSOCIATION_LANDMARK_REVISION_H_
