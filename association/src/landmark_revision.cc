#include "subslam/association/landmark_revision.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numeric>

#include "subslam/association/data_association.h"
#include "subslam/models/gating.h"

namespace subslam::association {

absl::Status LandmarkRevisionOptions::Validate() const {
  if (!(merge_probability > 0 && merge_probability < 1)) {
    return absl::InvalidArgumentError("merge_probability must be in (0, 1)");
  }
  if (!(split_probability > 0 && split_probability < 1)) {
    return absl::InvalidArgumentError("split_probability must be in (0, 1)");
  }
  if (every_joins < 0) return absl::InvalidArgumentError("every_joins must be >= 0");
  if (!(density_gate_probability > 0 && density_gate_probability < 1)) {
    return absl::InvalidArgumentError("density_gate_probability must be in (0, 1)");
  }
  if (!(density_radius_m > 0 && std::isfinite(density_radius_m))) {
    return absl::InvalidArgumentError("density_radius_m must be positive and finite");
  }
  return absl::OkStatus();
}

namespace {

// For each landmark, the factors holding it as a feature, ascending.
std::vector<std::vector<int>> FactorsOfLandmarks(const SubmapGraph& graph) {
  std::vector<std::vector<int>> out(graph.num_landmarks());
  for (int f = 0; f < static_cast<int>(graph.factors().size()); ++f) {
    for (int j : graph.factors()[f].landmark_of_feature) {
      if (out[j].empty() || out[j].back() != f) out[j].push_back(f);
    }
  }
  return out;
}

bool Intersect(const std::vector<int>& a, const std::vector<int>& b) {
  size_t i = 0, k = 0;
  while (i < a.size() && k < b.size()) {
    if (a[i] == b[k]) return true;
    if (a[i] < b[k])
      ++i;
    else
      ++k;
  }
  return false;
}

double LargestSigma(const Eigen::Matrix2d& m) {
  const double largest = 0.5 * (m(0, 0) + m(1, 1)) + std::hypot(0.5 * (m(0, 0) - m(1, 1)), m(0, 1));
  return std::sqrt(std::max(0.0, largest));
}

// Loop merges: among the candidate pairs (each passing the χ² test, each known only to
// metres), the largest set whose differences are jointly compatible (JCBB: the newer
// landmark of each pair a detection, its older partners the candidates), kept when it has
// at least `min_pairings` pairs and no other jointly compatible set of as many remains
// with its pairs struck out. Disjoint pairs only.
std::vector<LandmarkMerge> LoopMerges(const SubmapGraph& graph, const std::vector<LandmarkMerge>& pairs,
                                      const LandmarkJointCovarianceFn& joint_covariance, double probability,
                                      int min_pairings) {
  std::vector<LandmarkMerge> out;
  const int n = graph.num_landmarks();
  std::vector<int> newer;                // the detections
  std::vector<int> detection_of(n, -1);  // by landmark
  std::vector<int> involved;             // every landmark of a pair: the joint marginal's order
  std::vector<int> row_of(n, -1);        // its first row there
  for (const LandmarkMerge& m : pairs) {
    if (detection_of[m.drop] < 0) {
      detection_of[m.drop] = static_cast<int>(newer.size());
      newer.push_back(m.drop);
    }
    for (int j : {m.keep, m.drop}) {
      if (row_of[j] >= 0) continue;
      row_of[j] = 2 * static_cast<int>(involved.size());
      involved.push_back(j);
    }
  }
  if (static_cast<int>(newer.size()) < min_pairings) return out;
  const Eigen::MatrixXd Sigma = joint_covariance(involved);
  const auto& L = graph.landmarks();
  association::AssociationProblem problem;
  problem.candidates.resize(newer.size());
  for (const LandmarkMerge& m : pairs) {
    problem.candidates[detection_of[m.drop]].push_back({m.keep, m.d2, L[m.drop] - L[m.keep]});
  }
  for (auto& list : problem.candidates) {
    std::sort(list.begin(), list.end(),
              [](const association::AssociationCandidate& x, const association::AssociationCandidate& y) {
                return x.d2 < y.d2 || (x.d2 == y.d2 && x.landmark < y.landmark);
              });
  }
  // Cov(L_d − L_a, L_e − L_b).
  problem.covariance_block = [&](int i, int a, int k, int b) -> Eigen::Matrix2d {
    const int d = row_of[newer[i]], e = row_of[newer[k]], ra = row_of[a], rb = row_of[b];
    return Sigma.block<2, 2>(d, e) - Sigma.block<2, 2>(d, rb) - Sigma.block<2, 2>(ra, e) + Sigma.block<2, 2>(ra, rb);
  };
  constexpr long kMaxNodes = 20000;
  const association::AssociationResult best = association::JointCompatibility(problem, probability, kMaxNodes);
  if (best.pairings < min_pairings) return out;
  association::AssociationProblem alternative = problem;
  for (size_t d = 0; d < newer.size(); ++d) {
    const int a = best.landmark_of_detection[d];
    std::erase_if(alternative.candidates[d],
                  [a](const association::AssociationCandidate& c) { return c.landmark == a; });
  }
  if (association::JointCompatibility(alternative, probability, kMaxNodes).pairings >= min_pairings) return out;
  std::vector<char> used(graph.num_landmarks(), 0);
  for (size_t d = 0; d < newer.size(); ++d) {
    const int a = best.landmark_of_detection[d];
    if (a < 0) continue;
    if (used[a] || used[newer[d]]) return {};  // a chain of copies: left to the pairwise test
    used[a] = used[newer[d]] = 1;
    double d2 = NAN;
    for (const association::AssociationCandidate& c : problem.candidates[d]) d2 = c.landmark == a ? c.d2 : d2;
    out.push_back({a, newer[d], d2});
  }
  return out;
}

// Each landmark's typical single feature, in the world frame: the one of median precision
// (trace) among its features (infinite for a landmark without one).
std::vector<Eigen::Matrix2d> TypicalFeatureCovariances(const SubmapGraph& graph) {
  const int n = graph.num_landmarks();
  std::vector<std::vector<Eigen::Matrix2d>> features_of(n);
  for (const SubmapFactor& f : graph.factors()) {
    const Eigen::Matrix2d R = graph.anchors()[f.start_anchor].rotation();
    for (int i = 0; i < static_cast<int>(f.landmark_of_feature.size()); ++i) {
      features_of[f.landmark_of_feature[i]].push_back(R * f.submap.covariance.block<2, 2>(3 + 2 * i, 3 + 2 * i) *
                                                      R.transpose());
    }
  }
  std::vector<Eigen::Matrix2d> typical(n, Eigen::Matrix2d::Constant(INFINITY));
  for (int j = 0; j < n; ++j) {
    std::vector<Eigen::Matrix2d>& q = features_of[j];
    if (q.empty()) continue;
    std::nth_element(q.begin(), q.begin() + q.size() / 2, q.end(),
                     [](const Eigen::Matrix2d& x, const Eigen::Matrix2d& y) { return x.trace() < y.trace(); });
    typical[j] = q[q.size() / 2];
  }
  return typical;
}

// The pairs merged among those that pass: each landmark's compatible partners; a pair is
// merged when each is the other's best (smallest d²) and neither has another partner that
// one local map holds apart from the first: then the landmark could be either of two
// distinct points (ambiguous). A cluster of copies of one point (never held apart)
// collapses pair by pair over passes.
std::vector<LandmarkMerge> MutualBestPairs(const std::vector<LandmarkMerge>& passing,
                                           const std::vector<std::vector<int>>& factors_of, int n) {
  std::vector<LandmarkMerge> out;
  std::vector<std::vector<int>> partners_of(n);
  std::vector<int> best(n, -1);
  for (int p = 0; p < static_cast<int>(passing.size()); ++p) {
    for (int j : {passing[p].keep, passing[p].drop}) {
      partners_of[j].push_back(j == passing[p].keep ? passing[p].drop : passing[p].keep);
      if (best[j] < 0 || passing[p].d2 < passing[best[j]].d2) best[j] = p;
    }
  }
  const auto ambiguous = [&](int j, int other) {
    for (int c : partners_of[j]) {
      if (c != other && Intersect(factors_of[c], factors_of[other])) return true;
    }
    return false;
  };
  for (int p = 0; p < static_cast<int>(passing.size()); ++p) {
    const LandmarkMerge& m = passing[p];
    if (best[m.keep] != p || best[m.drop] != p) continue;
    if (ambiguous(m.keep, m.drop) || ambiguous(m.drop, m.keep)) continue;
    out.push_back(m);
  }
  return out;
}

}  // namespace

namespace {

// Whether a lower bound on Δᵀ Cov(l_a − l_b)⁻¹ Δ is beyond `skip_d2`: from
// Cov(l_a − l_b) ⪯ 2(Σ_a + Σ_b) (Cov(l_a + l_b) ⪰ 0), Σ the marginals or upper bounds
// on them, and from a bound kept since an earlier pass. A relative slack keeps a pair
// that the bound and the exact test would put on either side of the gate through
// rounding alone.
bool OutsideGateByBound(const Eigen::Vector2d& delta, const Eigen::Matrix2d& marginal_a,
                        const Eigen::Matrix2d& marginal_b, const RelativeCovarianceBounds* kept, int a, int b,
                        double skip_d2) {
  const double limit = skip_d2 * (1.0 + 1e-9);
  if (marginal_a.allFinite() && marginal_b.allFinite()) {
    const Eigen::LLT<Eigen::Matrix2d> sum(2.0 * (marginal_a + marginal_b));
    if (sum.info() == Eigen::Success && delta.dot(sum.solve(delta)) > limit) return true;
  }
  const Eigen::Matrix2d* bound = kept == nullptr ? nullptr : kept->Find(a, b);
  if (bound == nullptr) return false;
  const Eigen::LLT<Eigen::Matrix2d> llt(*bound);
  return llt.info() == Eigen::Success && delta.dot(llt.solve(delta)) > limit;
}

}  // namespace

std::vector<LandmarkMerge> FindLandmarkMerges(const SubmapGraph& graph, const std::vector<Eigen::Matrix2d>& marginals,
                                              const LandmarkPairCovarianceFn& pair_covariance,
                                              const LandmarkRevisionOptions& options, double loop_sigma_radius_m,
                                              const std::vector<char>& touched, const LoopMergeTests& loop_merges,
                                              RelativeCovarianceBounds* relative_bounds) {
  const int n = graph.num_landmarks();
  std::vector<LandmarkMerge> out;
  if (!options.merge || n < 2) return out;
  const double gate = models::ChiSquareQuantile(options.merge_probability, 2);
  const bool density = options.merge_by_density;
  const double outer_gate = density ? models::ChiSquareQuantile(options.density_gate_probability, 2) : gate;
  const double root_gate = std::sqrt(std::max(gate, outer_gate));
  // A pair whose d² is at least this passes neither test (nor the loop merges' gate).
  const double skip_d2 = std::max(gate, outer_gate);
  const std::vector<std::vector<int>> factors_of = FactorsOfLandmarks(graph);
  const std::vector<Eigen::Matrix2d> typical = TypicalFeatureCovariances(graph);
  const bool resolution = options.merge_unresolved;
  // Per landmark, the largest standard deviation that either test can use (the
  // marginal's, and the typical feature's for the resolution test).
  std::vector<double> sigma(n);
  double sigma_max = 0.0;
  for (int j = 0; j < n; ++j) {
    sigma[j] = marginals[j].allFinite() ? LargestSigma(marginals[j]) : INFINITY;
    if (resolution && typical[j].allFinite()) sigma[j] = std::max(sigma[j], LargestSigma(typical[j]));
    sigma_max = std::max(sigma_max, sigma[j]);
  }
  std::vector<int> by_x(n);
  std::iota(by_x.begin(), by_x.end(), 0);
  const auto& L = graph.landmarks();
  std::sort(by_x.begin(), by_x.end(),
            [&](int a, int b) { return L[a].x() < L[b].x() || (L[a].x() == L[b].x() && a < b); });
  // The density of landmarks around `p` [1/m²]: those within density_radius_m, less one
  // (the pair's reference point), at least one (the pair's other point).
  const double r = options.density_radius_m;
  const auto local_density = [&](const Eigen::Vector2d& p) {
    auto it = std::lower_bound(by_x.begin(), by_x.end(), p.x() - r, [&](int j, double x) { return L[j].x() < x; });
    int k = 0;
    for (; it != by_x.end() && L[*it].x() <= p.x() + r; ++it) k += (L[*it] - p).squaredNorm() <= r * r ? 1 : 0;
    return std::max(1, k - 1) / (M_PI * r * r);
  };
  // Pairs that pass a test: along any direction u, uᵀ Cov(Δ) u ≤ (σ_a + σ_b)² (and
  // uᵀ (Q̃_a + Q̃_b) u ≤ σ̃_a² + σ̃_b²), so |Δ|² / (σ_a + σ_b)² bounds d² from below and
  // the pre-filter loses no such pair.
  std::vector<LandmarkMerge> passing, uncertain;
  for (int p = 0; p < n; ++p) {
    const int a = by_x[p];
    for (int q = p + 1; q < n; ++q) {
      const int b = by_x[q];
      if (L[b].x() - L[a].x() > root_gate * (sigma[a] + sigma_max)) break;
      const Eigen::Vector2d delta = L[a] - L[b];
      if (delta.norm() > root_gate * (sigma[a] + sigma[b])) continue;
      if (!touched.empty() && !touched[a] && !touched[b]) continue;
      if (Intersect(factors_of[a], factors_of[b])) continue;
      double d2_res = INFINITY;
      if (resolution) {
        const Eigen::LLT<Eigen::Matrix2d> single(typical[a] + typical[b]);
        if (single.info() == Eigen::Success) d2_res = delta.dot(single.solve(delta));
      }
      if (!(d2_res < gate) && OutsideGateByBound(delta, marginals[a], marginals[b], relative_bounds, a, b, skip_d2)) {
        continue;
      }
      const Eigen::Matrix4d S = pair_covariance(a, b);
      const Eigen::Matrix2d C =
          S.topLeftCorner<2, 2>() + S.bottomRightCorner<2, 2>() - S.topRightCorner<2, 2>() - S.bottomLeftCorner<2, 2>();
      if (relative_bounds != nullptr) relative_bounds->Insert(a, b, C);
      const Eigen::LLT<Eigen::Matrix2d> llt(C);
      if (llt.info() != Eigen::Success) continue;
      const double d2 = delta.dot(llt.solve(delta));
      if (!(d2 < gate) && !(d2_res < gate)) {
        // Held apart by the χ² test: merged only where one point is the likelier explanation.
        if (!density || !(d2 < outer_gate)) continue;
        // √det C from the factor (positive where the factorisation succeeded).
        const double root_det = llt.matrixLLT()(0, 0) * llt.matrixLLT()(1, 1);
        const double one_point = std::exp(-0.5 * d2) / (2.0 * M_PI * root_det);
        if (!(one_point > local_density(0.5 * (L[a] + L[b])))) continue;
      }
      // A pair whose relative position is uncertain to 3σ ≥ loop_sigma_radius_m is a loop
      // closure with one pairing, in the regime where association asks for several.
      if (3.0 * LargestSigma(C) >= loop_sigma_radius_m) {
        if (d2 < gate && 3.0 * LargestSigma(C) < loop_merges.max_sigma_radius_m) {
          uncertain.push_back({std::min(a, b), std::max(a, b), d2});
        }
        continue;
      }
      passing.push_back({std::min(a, b), std::max(a, b), d2});
    }
  }
  out = MutualBestPairs(passing, factors_of, n);
  if (options.merge_loops && loop_merges.joint_covariance && loop_merges.min_pairings >= 1) {
    std::vector<char> merged(n, 0);
    for (const LandmarkMerge& m : out) merged[m.keep] = merged[m.drop] = 1;
    std::erase_if(uncertain, [&](const LandmarkMerge& m) { return merged[m.keep] || merged[m.drop]; });
    for (const LandmarkMerge& m : LoopMerges(graph, uncertain, loop_merges.joint_covariance, options.merge_probability,
                                             loop_merges.min_pairings)) {
      out.push_back(m);
    }
  }
  std::sort(out.begin(), out.end(), [](const LandmarkMerge& x, const LandmarkMerge& y) { return x.drop > y.drop; });
  return out;
}

std::vector<FeatureSplit> FindFeatureSplits(const SubmapGraph& graph,
                                            const AnchorLandmarkCovarianceFn& anchor_landmark_covariance,
                                            const LandmarkRevisionOptions& options) {
  std::vector<FeatureSplit> out;
  if (!options.split) return out;
  const std::vector<int> counts = graph.FeatureCounts();
  std::vector<FeatureSplit> tested;
  for (int f = 0; f < static_cast<int>(graph.factors().size()); ++f) {
    const SubmapFactor& factor = graph.factors()[f];
    std::vector<int> features, landmarks;
    for (int i = 0; i < static_cast<int>(factor.landmark_of_feature.size()); ++i) {
      const int j = factor.landmark_of_feature[i];
      if (counts[j] < 2) continue;
      features.push_back(i);
      landmarks.push_back(j);
    }
    if (features.empty()) continue;
    const std::vector<Eigen::Matrix<double, 5, 5>> sigma = anchor_landmark_covariance(factor.start_anchor, landmarks);
    const Pose2& P_s = graph.anchors()[factor.start_anchor];
    for (size_t c = 0; c < features.size(); ++c) {
      const int i = features[c];
      Matrix23d J_frame;
      Eigen::Matrix2d J_point;
      const Eigen::Vector2d r =
          TransformTo(P_s, graph.landmarks()[landmarks[c]], &J_frame, &J_point) - factor.submap.landmark(i);
      Eigen::Matrix<double, 2, 5> J;
      J << J_frame, J_point;
      const Eigen::Matrix2d C =
          factor.submap.covariance.block<2, 2>(3 + 2 * i, 3 + 2 * i) - J * sigma[c] * J.transpose();
      const Eigen::LLT<Eigen::Matrix2d> llt(C);
      // A residual covariance that is not positive definite: the feature alone fixes its
      // landmark (nothing to test it against).
      const double d2 = llt.info() == Eigen::Success ? r.dot(llt.solve(r)) : 0.0;
      tested.push_back({f, i, d2});
    }
  }
  if (tested.empty()) return out;
  const double level = 1.0 - (1.0 - options.split_probability) / static_cast<double>(tested.size());
  const double bound = models::ChiSquareQuantile(level, 2);
  // One gross error pulls the whole estimate and the residuals around it: only the worst
  // feature is split off in a pass, and the rest tested again after the estimate is
  // solved without it (iterated outlier removal).
  int worst = -1;
  for (int t = 0; t < static_cast<int>(tested.size()); ++t) {
    if (tested[t].d2 > bound && (worst < 0 || tested[t].d2 > tested[worst].d2)) worst = t;
  }
  if (worst >= 0) out.push_back(tested[worst]);
  return out;
}

}  // namespace subslam::association
