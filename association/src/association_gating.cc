#include "association_gating.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace subslam::association::submap_matching {

PlacedMap Place(const LocalSubmap& s, const Pose2& P_s, const Eigen::Matrix3d& Sigma_s, double landmark_radius) {
  PlacedMap m;
  m.P_s = P_s;
  m.sigma_xy = std::sqrt(std::max(0.0, Sigma_s.topLeftCorner<2, 2>().eigenvalues().real().maxCoeff()));
  const double sigma_theta = std::sqrt(std::max(0.0, Sigma_s(2, 2)));
  const int n = s.num_landmarks();
  m.world.resize(n);
  m.r2.resize(n);
  for (int i = 0; i < n; ++i) {
    m.world[i] = TransformFrom(P_s, s.landmark(i));
    m.r2[i] = landmark_radius + 3.0 * (m.sigma_xy + sigma_theta * s.landmark(i).norm());
  }
  return m;
}

std::vector<int> NearbyLandmarks(const SubmapGraph& graph, const PlacedMap& m, bool anchor_prefilter,
                                 double anchor_radius) {
  std::vector<char> is_candidate(graph.num_landmarks(), anchor_prefilter ? 0 : 1);
  const double r1 = anchor_radius + 3.0 * m.sigma_xy;
  for (const SubmapFactor& f : graph.factors()) {
    if (!anchor_prefilter) break;
    const bool near = (graph.anchors()[f.start_anchor].translation() - m.P_s.translation()).norm() <= r1 ||
                      (graph.anchors()[f.end_anchor].translation() - m.P_s.translation()).norm() <= r1;
    if (!near) continue;
    for (int j : f.landmark_of_feature) is_candidate[j] = 1;
  }
  std::vector<int> candidates;
  for (int j = 0; j < graph.num_landmarks(); ++j) {
    if (!is_candidate[j]) continue;
    for (size_t i = 0; i < m.world.size(); ++i) {
      if ((graph.landmarks()[j] - m.world[i]).norm() <= m.r2[i]) {
        candidates.push_back(j);
        break;
      }
    }
  }
  return candidates;
}

std::vector<int> PossiblyCompatible(const std::vector<int>& candidates,
                                    const std::vector<std::optional<Matrix5d>>& bounds, const PlacedMap& m,
                                    const SubmapGraph& graph, const LocalSubmap& s, const GateTest& gate,
                                    const PlacedMap* wide, const std::vector<char>* keep_if_near) {
  std::vector<int> kept;
  for (size_t c = 0; c < candidates.size(); ++c) {
    const int j = candidates[c];
    bool may_pass = !bounds[c].has_value();
    Eigen::Matrix<double, 2, 5> J;
    Matrix23d J_frame;
    Eigen::Matrix2d J_point;
    const Eigen::Vector2d predicted = TransformTo(m.P_s, graph.landmarks()[j], &J_frame, &J_point);
    J << J_frame, J_point;
    for (int i = 0; i < s.num_landmarks() && !may_pass; ++i) {
      if (wide != nullptr && (*keep_if_near)[j] && wide->Near(graph.landmarks()[j], i)) {
        may_pass = true;
        break;
      }
      if (!m.Near(graph.landmarks()[j], i)) continue;
      const Eigen::Matrix2d S_upper = J * *bounds[c] * J.transpose() + s.covariance.block<2, 2>(3 + 2 * i, 3 + 2 * i);
      // The relative slack keeps a pairing that the bound and the exact test would put
      // on either side of the gate through rounding alone.
      may_pass = gate(i, j, predicted - s.landmark(i), S_upper, 1.0 + 1e-9).has_value();
    }
    if (may_pass) kept.push_back(j);
  }
  return kept;
}

double MedianNearestNeighbourDistance(const SubmapGraph& graph, const std::vector<int>& landmarks) {
  const int n = static_cast<int>(landmarks.size());
  if (n < 2) return std::numeric_limits<double>::infinity();
  std::vector<double> nearest(n, std::numeric_limits<double>::infinity());
  for (int a = 0; a < n; ++a) {
    for (int b = a + 1; b < n; ++b) {
      const double d = (graph.landmarks()[landmarks[a]] - graph.landmarks()[landmarks[b]]).norm();
      nearest[a] = std::min(nearest[a], d);
      nearest[b] = std::min(nearest[b], d);
    }
  }
  std::nth_element(nearest.begin(), nearest.begin() + n / 2, nearest.end());
  return nearest[n / 2];
}

LoopFlags FlagLoopLandmarks(const SubmapAssociationOptions& o, const SubmapGraph& graph, double sigma_xy,
                            const std::vector<int>& candidates, const CandidateGeometry& geometry) {
  LoopFlags flags;
  flags.sigma_xy = sigma_xy;
  flags.radius = o.loop_test_min_sigma_radius_m;
  if (o.loop_test_scaled_by_spacing && o.min_loop_pairings > 1 && 3.0 * sigma_xy < flags.radius) {
    flags.radius = std::min(flags.radius, MedianNearestNeighbourDistance(graph, candidates));
  }
  flags.regime = o.min_loop_pairings > 1 && 3.0 * sigma_xy >= flags.radius;
  if (!flags.regime) return flags;
  flags.recent.assign(graph.num_landmarks(), 0);
  flags.certain.assign(graph.num_landmarks(), 0);
  const int first_recent = static_cast<int>(graph.factors().size()) - o.recent_maps;
  for (int f = std::max(0, first_recent); f < static_cast<int>(graph.factors().size()); ++f) {
    for (int j : graph.factors()[f].landmark_of_feature) flags.recent[j] = 1;
  }
  const double radius = flags.radius / 3.0;
  for (int c = 0; c < static_cast<int>(candidates.size()) && o.keep_certain_loop_pairings; ++c) {
    const Eigen::Matrix2d r = geometry.Relative(c);
    // The larger eigenvalue of the symmetric 2 × 2 block.
    const double largest = 0.5 * (r(0, 0) + r(1, 1)) + std::hypot(0.5 * (r(0, 0) - r(1, 1)), r(0, 1));
    flags.certain[candidates[c]] = largest < radius * radius ? 1 : 0;
  }
  return flags;
}

CandidateGeometry Geometry(int start_anchor, const std::vector<int>& candidates, const Pose2& P_s,
                           const SubmapGraph& graph, const SubmapAssociator::PairCovarianceFn& pair_covariance,
                           const TimedCovariance& timed_covariance, double* covariance_seconds) {
  const int c_count = static_cast<int>(candidates.size());
  CandidateGeometry g;
  g.pair.resize(c_count);
  if (pair_covariance) {
    const absl::Time t0 = absl::Now();
    g.pair = pair_covariance(start_anchor, candidates);
    *covariance_seconds += absl::ToDoubleSeconds(absl::Now() - t0);
  } else {
    g.full_joint = timed_covariance({start_anchor}, candidates);
    for (int c = 0; c < c_count; ++c) {
      g.pair[c].topLeftCorner<3, 3>() = g.full_joint.topLeftCorner<3, 3>();
      g.pair[c].topRightCorner<3, 2>() = g.full_joint.block<3, 2>(0, 3 + 2 * c);
      g.pair[c].bottomLeftCorner<2, 3>() = g.full_joint.block<2, 3>(3 + 2 * c, 0);
      g.pair[c].bottomRightCorner<2, 2>() = g.full_joint.block<2, 2>(3 + 2 * c, 3 + 2 * c);
    }
  }
  g.J_frame.resize(c_count);
  g.J_point.resize(c_count);
  g.predicted.resize(c_count);
  for (int c = 0; c < c_count; ++c) {
    g.predicted[c] = TransformTo(P_s, graph.landmarks()[candidates[c]], &g.J_frame[c], &g.J_point[c]);
  }
  return g;
}

association::AssociationProblem IndividualCompatibility(const LocalSubmap& s, const std::vector<int>& candidates,
                                                        const PlacedMap& m, const SubmapGraph& graph,
                                                        const CandidateGeometry& geometry, const GateTest& gate) {
  const int n = s.num_landmarks();
  association::AssociationProblem problem;
  problem.candidates.resize(n);
  for (int c = 0; c < static_cast<int>(candidates.size()); ++c) {
    const int j = candidates[c];
    for (int i = 0; i < n; ++i) {
      if (!m.Near(graph.landmarks()[j], i)) continue;
      const Eigen::Vector2d nu = geometry.predicted[c] - s.landmark(i);
      const Eigen::Matrix2d S = geometry.Relative(c) + s.covariance.block<2, 2>(3 + 2 * i, 3 + 2 * i);
      const std::optional<double> score = gate(i, j, nu, S, 1.0);
      if (score.has_value()) problem.candidates[i].push_back({c, *score, nu});
    }
  }
  for (auto& list : problem.candidates) {
    std::sort(list.begin(), list.end(),
              [](const auto& a, const auto& b) { return a.d2 < b.d2 || (a.d2 == b.d2 && a.landmark < b.landmark); });
  }
  return problem;
}

}  // namespace subslam::association::submap_matching
