#include "recent_rotation_fit.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "grouped_association.h"
#include "subslam/association/local_map_rotation.h"

namespace subslam::association::submap_matching {

std::vector<char> RecentLandmarks(const SubmapGraph& graph, int maps) {
  std::vector<char> recent(graph.num_landmarks(), 0);
  const int num_factors = static_cast<int>(graph.factors().size());
  for (int f = std::max(0, num_factors - maps); f < num_factors; ++f) {
    for (int j : graph.factors()[f].landmark_of_feature) recent[j] = 1;
  }
  return recent;
}

void AddRecentCandidates(const SubmapGraph& graph, const PlacedMap& m, const std::vector<char>& recent,
                         std::vector<int>* candidates) {
  const auto before = static_cast<std::ptrdiff_t>(candidates->size());
  for (int j = 0; j < graph.num_landmarks(); ++j) {
    if (!recent[j] || std::binary_search(candidates->begin(), candidates->begin() + before, j)) continue;
    for (size_t i = 0; i < m.world.size(); ++i) {
      if (m.Near(graph.landmarks()[j], static_cast<int>(i))) {
        candidates->push_back(j);
        break;
      }
    }
  }
  std::inplace_merge(candidates->begin(), candidates->begin() + before, candidates->end());
}

namespace {

// Step 1 of the rotation test: the rotation within ±3σ, in steps of σ/10, under which the
// most features find an individually compatible recent landmark (the smaller sum of their
// best d² breaking a tie), the map widened by one step at each; none when fewer than two
// recent candidates or features would vote.
std::optional<double> VoteRotation(const LocalSubmap& s, const std::vector<int>& candidates,
                                   const CandidateGeometry& geometry, const GateTest& gate,
                                   const std::vector<char>& recent, double sigma) {
  std::vector<int> recent_candidates;  // indices into candidates
  std::vector<Eigen::Matrix2d> relative;
  for (int c = 0; c < static_cast<int>(candidates.size()); ++c) {
    if (!recent[candidates[c]]) continue;
    recent_candidates.push_back(c);
    relative.push_back(geometry.Relative(c));
  }
  if (recent_candidates.size() < 2) return std::nullopt;
  constexpr int kVoteSteps = 30;
  const double step = sigma / 10.0;
  int best_count = 0;
  double best_sum = INFINITY, delta = 0.0;
  for (int k = -kVoteSteps; k <= kVoteSteps; ++k) {
    const LocalSubmap w = WidenedByRotation(RotatedAboutStart(s, k * step), step);
    int count = 0;
    double sum = 0.0;
    for (int i = 0; i < s.num_landmarks(); ++i) {
      double best = INFINITY;
      for (size_t r = 0; r < recent_candidates.size(); ++r) {
        const int c = recent_candidates[r];
        const std::optional<double> score = gate(i, candidates[c], geometry.predicted[c] - w.landmark(i),
                                                 relative[r] + w.covariance.block<2, 2>(3 + 2 * i, 3 + 2 * i), 1.0);
        if (score.has_value()) best = std::min(best, *score);
      }
      if (std::isfinite(best)) {
        ++count;
        sum += best;
      }
    }
    if (count > best_count || (count == best_count && sum < best_sum)) {
      best_count = count;
      best_sum = sum;
      delta = k * step;
    }
  }
  if (best_count < 2) return std::nullopt;
  return delta;
}

}  // namespace

RotationFit FitRecentRotation(const SubmapAssociationOptions& o, const LocalSubmap& s, const PlacedMap& placed,
                              const Eigen::Matrix3d& Sigma_widened, int start_anchor,
                              const std::vector<int>& candidates, const SubmapGraph& graph,
                              const CandidateGeometry& geometry, const GateTest& gate,
                              const TimedCovariance& timed_covariance, const std::vector<char>& recent,
                              const std::vector<int>& own_pairing) {
  constexpr int kRounds = 3, kGaussNewtonIterations = 8;
  const double sigma = o.map_rotation_sigma_rad;
  RotationFit fit;
  // The recent landmarks individually compatible with each feature of the map rotated by
  // `d` and widened.
  const auto compatible_recent = [&](double d, LocalSubmap* widened) {
    *widened = WidenedByRotation(RotatedAboutStart(s, d), sigma);
    const PlacedMap placed_widened = Place(*widened, placed.P_s, Sigma_widened, o.landmark_search_radius_m);
    association::AssociationProblem problem =
        IndividualCompatibility(*widened, candidates, placed_widened, graph, geometry, gate);
    for (auto& list : problem.candidates) {
      std::erase_if(list, [&](const association::AssociationCandidate& x) { return !recent[candidates[x.landmark]]; });
    }
    return problem;
  };
  // Step 1.
  const std::optional<double> voted = VoteRotation(s, candidates, geometry, gate, recent, sigma);
  if (!voted.has_value()) return fit;
  double delta = *voted;
  // Steps 2-3.
  LocalSubmap widened;
  std::vector<int> hypothesis;  // candidate per feature of the last round's pairings
  for (int round = 0; round < kRounds; ++round) {
    association::AssociationProblem problem = compatible_recent(delta, &widened);
    const InnovationCovariance covariance(problem, start_anchor, candidates, geometry, timed_covariance);
    problem.covariance_block = [&](int i, int a, int k, int b) { return covariance(widened.covariance, i, a, k, b); };
    const association::AssociationResult r =
        association::JointCompatibility(problem, o.gate_probability, o.jcbb_max_nodes);
    if (r.pairings < 2) return RotationFit{};
    for (int i = 0; i < s.num_landmarks(); ++i) {
      const int j = own_pairing[i];
      if (j >= 0 && recent[j] && (r.landmark_of_detection[i] < 0 || candidates[r.landmark_of_detection[i]] != j)) {
        return RotationFit{};
      }
    }
    if (r.landmark_of_detection == hypothesis) break;
    hypothesis = r.landmark_of_detection;
    std::vector<std::pair<int, int>> pairs;  // (feature, candidate)
    for (int i = 0; i < s.num_landmarks(); ++i) {
      if (hypothesis[i] >= 0) pairs.push_back({i, hypothesis[i]});
    }
    const int k = static_cast<int>(pairs.size());
    // d²(δ), and with `g` its innovation's derivative ∂ν/∂δ: ν = prediction − feature, so
    // minus the rotated feature's own.
    const auto joint = [&](double d, Eigen::VectorXd* nu, Eigen::MatrixXd* S, Eigen::VectorXd* g) {
      const LocalSubmap rotated = RotatedAboutStart(s, d);
      const Eigen::VectorXd feature_rate = RotationAboutStart(rotated);
      nu->resize(2 * k);
      g->resize(2 * k);
      S->resize(2 * k, 2 * k);
      for (int p = 0; p < k; ++p) {
        nu->segment<2>(2 * p) = geometry.predicted[pairs[p].second] - rotated.landmark(pairs[p].first);
        g->segment<2>(2 * p) = -feature_rate.segment<2>(3 + 2 * pairs[p].first);
        for (int q = 0; q < k; ++q) {
          S->block<2, 2>(2 * p, 2 * q) =
              covariance(rotated.covariance, pairs[p].first, pairs[p].second, pairs[q].first, pairs[q].second);
        }
      }
    };
    Eigen::VectorXd nu, g;
    Eigen::MatrixXd S;
    const auto d2_at = [&](double d) {
      joint(d, &nu, &S, &g);
      const Eigen::LLT<Eigen::MatrixXd> llt(S);
      return llt.info() == Eigen::Success ? nu.dot(llt.solve(nu)) : NAN;
    };
    const double d2_zero = d2_at(0.0);
    double d2 = d2_at(delta);
    for (int it = 0; it < kGaussNewtonIterations && std::isfinite(d2); ++it) {
      const Eigen::LLT<Eigen::MatrixXd> llt(S);
      const Eigen::VectorXd w = llt.solve(g);
      const double information = g.dot(w);
      if (!(information > 0)) break;
      const double increment = -w.dot(nu) / information;
      const double next = delta + increment, d2_next = d2_at(next);
      if (!(d2_next < d2)) {
        d2_at(delta);  // back to the iterate's linearisation
        break;
      }
      delta = next;
      d2 = d2_next;
      if (std::abs(increment) < 1e-9) break;
    }
    fit.delta_rad = delta;
    fit.statistic = d2_zero - d2;
    const Eigen::LLT<Eigen::MatrixXd> llt(S);  // S, g at δ̂
    fit.variance_rad2 = 1.0 / g.dot(llt.solve(g));
  }
  return fit;
}

}  // namespace subslam::association::submap_matching
