#include "subslam/backend/submap_association.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "subslam/association/data_association.h"
#include "subslam/backend/local_map_rotation.h"
#include "subslam/models/gating.h"

namespace subslam::backend {

absl::Status SubmapAssociationOptions::Validate() const {
  if (!(anchor_search_radius_m >= 0 && landmark_search_radius_m >= 0)) {
    return absl::InvalidArgumentError("search radii must be >= 0");
  }
  if (!(gate_probability > 0 && gate_probability < 1)) {
    return absl::InvalidArgumentError("gate_probability must be in (0, 1)");
  }
  if (!(sigma_signature >= 0 && std::isfinite(sigma_signature))) {
    return absl::InvalidArgumentError("sigma_signature must be finite and >= 0");
  }
  if (jcbb_max_nodes < 1) return absl::InvalidArgumentError("jcbb_max_nodes must be >= 1");
  if (recent_maps < 0 || !(loop_test_min_sigma_radius_m >= 0)) {
    return absl::InvalidArgumentError("recent_maps and loop_test_min_sigma_radius_m must be >= 0");
  }
  if (loop_confirmation_maps < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("loop_confirmation_maps must be >= 0, got ", loop_confirmation_maps));
  }
  if (!(loop_confirmation_min_sigma_radius_m >= 0 && std::isfinite(loop_confirmation_min_sigma_radius_m))) {
    return absl::InvalidArgumentError(
        absl::StrCat("loop_confirmation_min_sigma_radius_m must be finite and >= 0 [m], got ",
                     loop_confirmation_min_sigma_radius_m));
  }
  if (!(map_rotation_probability > 0 && map_rotation_probability < 1)) {
    return absl::InvalidArgumentError(
        absl::StrCat("map_rotation_probability must be in (0, 1), got ", map_rotation_probability));
  }
  if (!(map_rotation_spread_probability >= 0 && map_rotation_spread_probability < 1)) {
    return absl::InvalidArgumentError(
        absl::StrCat("map_rotation_spread_probability must be in [0, 1), got ", map_rotation_spread_probability));
  }
  if (!(map_rotation_sigma_rad >= 0 && std::isfinite(map_rotation_sigma_rad))) {
    return absl::InvalidArgumentError(
        absl::StrCat("map_rotation_sigma_rad must be finite and >= 0 [rad], got ", map_rotation_sigma_rad));
  }
  return absl::OkStatus();
}

std::vector<std::vector<int>> WholeMapGroups(const SubmapGraph& graph) {
  std::vector<std::vector<int>> groups;
  groups.reserve(graph.factors().size());
  for (const SubmapFactor& f : graph.factors()) groups.push_back(f.landmark_of_feature);
  return groups;
}

std::optional<LocalSubmap> RotatedBack(const LocalSubmap& s, const SubmapAssociation& a) {
  if (!a.map_rotated || s.rotation_widening_rad > 0) return std::nullopt;
  return WidenedByRotation(RotatedAboutStart(s, a.map_rotation_rad), a.map_widening_rad);
}

SubmapAssociator::SubmapAssociator(const SubmapAssociationOptions& options)
    : options_(options),
      rotation_spread_(options.map_rotation_sigma_rad > 0 && options.map_rotation_spread_probability > 0 &&
                               options.map_rotation_spread_probability < 1
                           ? options.map_rotation_spread_probability
                           : 0.0,
                       options.map_rotation_probability > 0 && options.map_rotation_probability < 1
                           ? options.map_rotation_probability
                           : 0.99) {}

LocalSubmap SubmapAssociator::WithRotationSpread(const LocalSubmap& s) const { return rotation_spread_.Widened(s); }

void SubmapAssociator::RecordRotationFit(const LocalSubmap& joined) {
  rotation_spread_.Add(joined.rotation_fit_rad, joined.rotation_fit_variance_rad2, joined.rotation_spread_rad);
}

void StampRotationFit(const SubmapAssociation& a, LocalSubmap* s) {
  if (std::isfinite(s->rotation_fit_rad)) return;
  s->rotation_fit_rad = a.map_rotation_fit_rad;
  s->rotation_fit_variance_rad2 = a.map_rotation_fit_variance_rad2;
}

double SubmapAssociator::MeanSignature(int landmark) const {
  if (landmark >= static_cast<int>(signature_count_.size()) || signature_count_[landmark] == 0) return NAN;
  return signature_sum_[landmark] / signature_count_[landmark];
}

std::vector<int> SubmapAssociator::TruthIds(int num_landmarks) const {
  std::vector<int> out(num_landmarks, -1);
  for (const auto& [truth, landmark] : landmark_of_truth_) {
    if (landmark < num_landmarks) out[landmark] = truth;
  }
  return out;
}

void SubmapAssociator::Record(const LocalSubmap& s, const std::vector<int>& landmark_of_feature, int first_new_landmark,
                              bool define_truth) {
  int needed = 0;
  for (int j : landmark_of_feature) needed = std::max(needed, j + 1);
  if (needed > static_cast<int>(signature_sum_.size())) {
    signature_sum_.resize(needed, 0.0);
    signature_count_.resize(needed, 0);
  }
  for (int i = 0; i < s.num_landmarks(); ++i) {
    const int j = landmark_of_feature[i];
    if (std::isfinite(s.landmarks[i].signature)) {
      signature_sum_[j] += s.landmarks[i].signature;
      ++signature_count_[j];
    }
    const std::optional<int>& t = s.landmarks[i].truth_id;
    if (define_truth && j >= first_new_landmark && t.has_value() && *t >= 0) landmark_of_truth_[*t] = j;
  }
}

void SubmapAssociator::MergeLandmarks(int keep, int drop) {
  if (drop < static_cast<int>(signature_sum_.size())) {
    if (keep >= static_cast<int>(signature_sum_.size())) {
      signature_sum_.resize(keep + 1, 0.0);
      signature_count_.resize(keep + 1, 0);
    }
    signature_sum_[keep] += signature_sum_[drop];
    signature_count_[keep] += signature_count_[drop];
    signature_sum_.erase(signature_sum_.begin() + drop);
    signature_count_.erase(signature_count_.begin() + drop);
  }
  for (auto& [truth, landmark] : landmark_of_truth_) landmark = SubmapGraph::RenumberAfterMerge(landmark, keep, drop);
}

void SubmapAssociator::SplitFeature(int from, int to, double signature) {
  const int needed = std::max(from, to) + 1;
  if (needed > static_cast<int>(signature_sum_.size())) {
    signature_sum_.resize(needed, 0.0);
    signature_count_.resize(needed, 0);
  }
  if (std::isfinite(signature)) {
    signature_sum_[from] -= signature;
    --signature_count_[from];
    signature_sum_[to] += signature;
    ++signature_count_[to];
  }
}

namespace {

// A local map placed in the world by its start anchor P_s: where each feature lands, and
// how far from it a landmark may lie and still be a candidate (the landmark search radius
// grown by 3σ of the anchor's position and heading at the feature's distance).
struct PlacedMap {
  Pose2 P_s;
  double sigma_xy = 0.0;
  std::vector<Eigen::Vector2d> world;
  std::vector<double> r2;

  bool Near(const Eigen::Vector2d& landmark, int i) const { return !((landmark - world[i]).norm() > r2[i]); }
};

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

// Step 1: the landmarks near some feature, among those of local maps with an anchor
// within `anchor_radius` (+ 3σ) of the start anchor (all of them without the prefilter).
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

// Step 3's test of feature i against landmark j with innovation ν and covariance S: the
// score (d², plus the signature term when both have one) if it passes the gate (widened
// by `gate_scale`).
class GateTest {
 public:
  GateTest(const LocalSubmap& s, const SubmapAssociator& associator)
      : s_(s),
        associator_(associator),
        gate2_(models::ChiSquareQuantile(associator.options().gate_probability, 2)),
        gate3_(models::ChiSquareQuantile(associator.options().gate_probability, 3)) {}

  std::optional<double> operator()(int i, int j, const Eigen::Vector2d& nu, const Eigen::Matrix2d& S,
                                   double gate_scale) const {
    const std::optional<double> d2 = models::MahalanobisSquared2(nu, S);
    if (!d2.has_value()) return std::nullopt;
    double score = *d2, gate = gate2_;
    const double sig_l = associator_.MeanSignature(j);
    const double sigma_signature = associator_.options().sigma_signature;
    if (sigma_signature > 0 && std::isfinite(s_.landmarks[i].signature) && std::isfinite(sig_l)) {
      const double ds = (s_.landmarks[i].signature - sig_l) / sigma_signature;
      score += ds * ds;
      gate = gate3_;
    }
    if (score >= gate * gate_scale) return std::nullopt;
    return score;
  }

 private:
  const LocalSubmap& s_;
  const SubmapAssociator& associator_;
  double gate2_, gate3_;
};

// Step 2: the candidates that could pass the gate with some feature under the joiner's
// upper bound on their marginal (a candidate without a bound is kept); and those that
// `keep_if_near` flags near a feature of the map placed as `wide` (the rotation test's
// recent landmarks: few, and no linearised gate holds for a map rotated by tenths of a
// radian).
std::vector<int> PossiblyCompatible(const std::vector<int>& candidates,
                                    const std::vector<std::optional<Matrix5d>>& bounds, const PlacedMap& m,
                                    const SubmapGraph& graph, const LocalSubmap& s, const GateTest& gate,
                                    const PlacedMap* wide = nullptr, const std::vector<char>* keep_if_near = nullptr) {
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

// The candidates seen from the start anchor: each one's predicted position in its frame,
// the Jacobians of that prediction, and the marginal of [P_s, L_c] it is taken through.
struct CandidateGeometry {
  std::vector<Matrix5d> pair;
  Eigen::MatrixXd full_joint;  // [P_s, every candidate], when no pairwise blocks were given
  std::vector<Matrix23d> J_frame;
  std::vector<Eigen::Matrix2d> J_point;
  std::vector<Eigen::Vector2d> predicted;

  // Candidate c's covariance in the start anchor's frame.
  Eigen::Matrix2d Relative(int c) const {
    Eigen::Matrix<double, 2, 5> J;
    J << J_frame[c], J_point[c];
    return J * pair[c] * J.transpose();
  }
};

// Landmarks a recent local map saw (pairings with any other close a loop) and, with
// keep_certain_loop_pairings, the candidates whose position relative to the start anchor
// is known to 3σ below the loop test's radius (kept when the tests drop a closure). The
// loop tests apply while the start anchor is uncertain (`regime`).
struct LoopFlags {
  bool regime = false;
  double sigma_xy = 0.0;  // of the start anchor's position [m]
  std::vector<char> recent, certain;
};

LoopFlags FlagLoopLandmarks(const SubmapAssociationOptions& o, const SubmapGraph& graph, double sigma_xy,
                            const std::vector<int>& candidates, const CandidateGeometry& geometry) {
  LoopFlags flags;
  flags.sigma_xy = sigma_xy;
  flags.regime = o.min_loop_pairings > 1 && 3.0 * sigma_xy >= o.loop_test_min_sigma_radius_m;
  if (!flags.regime) return flags;
  flags.recent.assign(graph.num_landmarks(), 0);
  flags.certain.assign(graph.num_landmarks(), 0);
  const int first_recent = static_cast<int>(graph.factors().size()) - o.recent_maps;
  for (int f = std::max(0, first_recent); f < static_cast<int>(graph.factors().size()); ++f) {
    for (int j : graph.factors()[f].landmark_of_feature) flags.recent[j] = 1;
  }
  const double radius = o.loop_test_min_sigma_radius_m / 3.0;
  for (int c = 0; c < static_cast<int>(candidates.size()) && o.keep_certain_loop_pairings; ++c) {
    const Eigen::Matrix2d r = geometry.Relative(c);
    // The larger eigenvalue of the symmetric 2 × 2 block.
    const double largest = 0.5 * (r(0, 0) + r(1, 1)) + std::hypot(0.5 * (r(0, 0) - r(1, 1)), r(0, 1));
    flags.certain[candidates[c]] = largest < radius * radius ? 1 : 0;
  }
  return flags;
}

// The joiner's joint covariance, its time added to the association's record.
class TimedCovariance {
 public:
  TimedCovariance(const SubmapAssociator::JointCovarianceFn& joint_covariance, double* seconds)
      : joint_covariance_(joint_covariance), seconds_(seconds) {}
  Eigen::MatrixXd operator()(const std::vector<int>& anchors, const std::vector<int>& landmarks) const {
    const absl::Time t0 = absl::Now();
    Eigen::MatrixXd m = joint_covariance_(anchors, landmarks);
    *seconds_ += absl::ToDoubleSeconds(absl::Now() - t0);
    return m;
  }

 private:
  const SubmapAssociator::JointCovarianceFn& joint_covariance_;
  double* seconds_;
};

// The marginal of [P_s, L_c] for each candidate — from the joiner's pairwise blocks when
// it has them (no cross-covariances between candidates are formed), else from the joint
// covariance of all candidates — and each candidate's prediction from P_s.
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

// Step 3: individual compatibility of each (feature, candidate) pair; each feature's
// compatible candidates by increasing score.
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

// The joint innovation covariance JCBB asks for: Cov(ν_ia, ν_kb) = J_a Σ J_bᵀ + Q_ik, with
// Σ the joint marginal of P_s and the candidates compatible with some feature (asked of the
// joiner once, for those only), J over [P_s, candidate], and Q the local map's covariance.
// J_a Σ J_bᵀ is computed once per pair of candidates (JCBB asks for it at every node).
class InnovationCovariance {
 public:
  InnovationCovariance(const association::AssociationProblem& problem, int start_anchor,
                       const std::vector<int>& candidates, const CandidateGeometry& geometry,
                       const TimedCovariance& timed_covariance)
      : geometry_(geometry), slot_(candidates.size(), -1) {
    std::vector<int> compatible;
    for (const auto& list : problem.candidates) {
      for (const association::AssociationCandidate& cand : list) {
        if (slot_[cand.landmark] < 0) {
          slot_[cand.landmark] = static_cast<int>(compatible.size());
          compatible.push_back(candidates[cand.landmark]);
        }
      }
    }
    if (geometry.full_joint.size() > 0) {
      std::vector<int> rows(3 + 2 * compatible.size());  // of full_joint, per slot
      rows[0] = 0, rows[1] = 1, rows[2] = 2;
      for (size_t c = 0; c < slot_.size(); ++c) {
        if (slot_[c] < 0) continue;
        rows[3 + 2 * slot_[c]] = 3 + 2 * static_cast<int>(c);
        rows[4 + 2 * slot_[c]] = 4 + 2 * static_cast<int>(c);
      }
      Sigma_ = geometry.full_joint(rows, rows);
    } else if (!compatible.empty()) {
      Sigma_ = timed_covariance({start_anchor}, compatible);
    }
    c_n_ = compatible.size();
    projected_.resize(c_n_ * c_n_);
    projected_known_.assign(c_n_ * c_n_, 0);
  }

  // The block of pairings (feature i, candidate a) and (feature k, candidate b), for a local
  // map of covariance Q.
  Eigen::Matrix2d operator()(const Eigen::MatrixXd& Q, int i, int a, int k, int b) const {
    const size_t key = static_cast<size_t>(slot_[a]) * c_n_ + slot_[b];
    if (!projected_known_[key]) {
      const int oa = 3 + 2 * slot_[a], ob = 3 + 2 * slot_[b];
      const std::vector<Matrix23d>& J_frame = geometry_.J_frame;
      const std::vector<Eigen::Matrix2d>& J_point = geometry_.J_point;
      projected_[key] = J_frame[a] * Sigma_.topLeftCorner<3, 3>() * J_frame[b].transpose() +
                        J_frame[a] * Sigma_.block<3, 2>(0, ob) * J_point[b].transpose() +
                        J_point[a] * Sigma_.block<2, 3>(oa, 0) * J_frame[b].transpose() +
                        J_point[a] * Sigma_.block<2, 2>(oa, ob) * J_point[b].transpose();
      projected_known_[key] = 1;
    }
    return projected_[key] + Q.block<2, 2>(3 + 2 * i, 3 + 2 * k);
  }

 private:
  const CandidateGeometry& geometry_;
  std::vector<int> slot_;  // per candidate: its place in Σ (−1: compatible with no feature)
  size_t c_n_ = 0;
  Eigen::MatrixXd Sigma_;
  mutable std::vector<Eigen::Matrix2d> projected_;
  mutable std::vector<char> projected_known_;
};

// A whole map's association problem linearised about another start-anchor pose. The
// prediction of each candidate from a start anchor P ~ N(P̄, Σ) is linearised about P_lin:
// its mean h(P_lin) + J (P̄ − P_lin), its covariance through J at P_lin (the iterated
// Kalman filter's form, exact where h is linear between P_lin and the true pose). A whole
// map hundreds of metres long, joined under a lost start anchor whose heading is off by
// tenths of a radian, moves a far feature by metres through the second-order term: the
// pairings that close the loop fit, but every later group's, gated conditionally on them
// about the prior's P̄, fails, and the closure goes unconfirmed. Once a group closes a
// loop, the grouped association gates the later groups about the start anchor the
// decided pairings imply, as a sequential joiner gates its next map after fusing and
// relinearising.
class Relinearization {
 public:
  Relinearization(const LocalSubmap& s, int start_anchor, const std::vector<int>& candidates, const SubmapGraph& graph,
                  const CandidateGeometry& prior, const Pose2& P_prior, const Eigen::Matrix3d& Sigma_s,
                  double landmark_radius, const GateTest& gate, const TimedCovariance& timed_covariance)
      : s_(s),
        start_anchor_(start_anchor),
        candidates_(candidates),
        graph_(graph),
        prior_(prior),
        P_prior_(P_prior),
        Sigma_s_(Sigma_s),
        landmark_radius_(landmark_radius),
        gate_(gate),
        timed_covariance_(timed_covariance) {}

  // The start anchor's mean given the pairings (feature, candidate), by the iterated
  // Kalman update about each iterate: the gain Cov(P_s, ν) S⁻¹, S the pairings' joint
  // innovation covariance and Cov(P_s, ν_k) = Σ_ss J_frameᵀ + Σ_sc J_pointᵀ, so that a
  // pairing with a landmark known relative to the anchor (a recent one) moves it little.
  Pose2 Fit(const std::vector<std::pair<int, int>>& pairs) const {
    const int m = static_cast<int>(pairs.size());
    Pose2 x = P_prior_;
    if (m == 0) return x;
    Eigen::MatrixXd S(2 * m, 2 * m), C(3, 2 * m);
    Eigen::VectorXd y(2 * m);
    for (int iteration = 0; iteration < 10; ++iteration) {
      const std::unique_ptr<Linearized> l = Build(x, pairs);
      for (int k = 0; k < m; ++k) {
        const auto [i, c] = pairs[k];
        const CandidateGeometry& g = l->geometry;
        C.middleCols<2>(2 * k) =
            Sigma_s_ * g.J_frame[c].transpose() + g.pair[c].topRightCorner<3, 2>() * g.J_point[c].transpose();
        y.segment<2>(2 * k) = s_.landmark(i) - g.predicted[c];
        for (int q = 0; q < m; ++q) {
          S.block<2, 2>(2 * k, 2 * q) = l->problem.covariance_block(i, c, pairs[q].first, pairs[q].second);
        }
      }
      const Eigen::LDLT<Eigen::MatrixXd> ldlt(0.5 * (S + S.transpose()));
      if (ldlt.info() != Eigen::Success) return x;
      const Eigen::Vector3d step = C * ldlt.solve(y);
      const Pose2 next(P_prior_.x + step.x(), P_prior_.y + step.y(), WrapAngle(P_prior_.theta + step.z()));
      const double moved = PoseDifference(next, x).norm();
      x = next;
      if (moved < 1e-9) break;
    }
    return x;
  }

  // The problem about P_lin, with each (feature, candidate) of `keep` among its feature's
  // candidates even where it fails the gate (the decided pairings it is conditioned on).
  const association::AssociationProblem& At(const Pose2& P_lin, const std::vector<std::pair<int, int>>& keep) {
    built_.push_back(Build(P_lin, keep));
    return built_.back()->problem;
  }

 private:
  struct Linearized {
    CandidateGeometry geometry;  // the prior's [P_s, candidate] marginals, Jacobians at P_lin
    std::unique_ptr<InnovationCovariance> covariance;
    association::AssociationProblem problem;
  };

  std::unique_ptr<Linearized> Build(const Pose2& P_lin, const std::vector<std::pair<int, int>>& keep) const {
    auto l = std::make_unique<Linearized>();
    CandidateGeometry& g = l->geometry;
    g.pair = prior_.pair;  // not the full joint: the innovation covariance asks for its candidates' only
    const int count = static_cast<int>(candidates_.size());
    g.J_frame.resize(count);
    g.J_point.resize(count);
    g.predicted.resize(count);
    const Eigen::Vector3d offset = PoseDifference(P_prior_, P_lin);
    for (int c = 0; c < count; ++c) {
      g.predicted[c] =
          TransformTo(P_lin, graph_.landmarks()[candidates_[c]], &g.J_frame[c], &g.J_point[c]) + g.J_frame[c] * offset;
    }
    const PlacedMap placed = Place(s_, P_lin, Sigma_s_, landmark_radius_);
    l->problem = IndividualCompatibility(s_, candidates_, placed, graph_, g, gate_);
    for (const auto& [i, c] : keep) {
      auto& list = l->problem.candidates[i];
      if (std::any_of(list.begin(), list.end(),
                      [c](const association::AssociationCandidate& x) { return x.landmark == c; })) {
        continue;
      }
      const Eigen::Vector2d nu = g.predicted[c] - s_.landmark(i);
      const Eigen::Matrix2d S = g.Relative(c) + s_.covariance.block<2, 2>(3 + 2 * i, 3 + 2 * i);
      list.insert(list.begin(), {c, models::MahalanobisSquared2(nu, S).value_or(INFINITY), nu});
    }
    l->covariance =
        std::make_unique<InnovationCovariance>(l->problem, start_anchor_, candidates_, g, timed_covariance_);
    const InnovationCovariance* covariance = l->covariance.get();
    const LocalSubmap* s = &s_;
    l->problem.covariance_block = [covariance, s](int i, int a, int k, int b) {
      return (*covariance)(s->covariance, i, a, k, b);
    };
    return l;
  }

  const LocalSubmap& s_;
  int start_anchor_;
  const std::vector<int>& candidates_;
  const SubmapGraph& graph_;
  const CandidateGeometry& prior_;
  Pose2 P_prior_;
  Eigen::Matrix3d Sigma_s_;
  double landmark_radius_;
  const GateTest& gate_;
  const TimedCovariance& timed_covariance_;
  std::vector<std::unique_ptr<Linearized>> built_;  // the problems' covariance blocks point into them
};

// Step 4 for a whole map, group by group (the features of each of its local maps, in
// order): each group's JCBB given the pairings the groups before it kept (required, their
// innovations gated conditionally on them, as if fused), then the loop tests on that
// group's pairings alone, as sequential joining applies them to each local map. A feature
// left unpaired is decided again by a later group that holds it. Once a group has closed a
// loop (min_loop_pairings kept), the later groups are gated given that closure and the
// loop tests no longer apply, as after a sequential join has fused it; under a lost
// anchor the closure must be confirmed by one of the next loop_confirmation_maps groups,
// or the decisions from its group on are made again without its loop pairings.
class GroupedAssociation {
 public:
  // `relinearization`: rebuilds the problem about the start anchor the decided pairings imply (null:
  // the prior's linearisation throughout).
  GroupedAssociation(const SubmapAssociationOptions& o, const LocalSubmap& s, const std::vector<int>& candidates,
                     const LoopFlags& loop, const association::AssociationProblem& problem,
                     Relinearization* relinearization, SubmapAssociation* out)
      : o_(o),
        s_(s),
        candidates_(candidates),
        loop_(loop),
        problem_(&problem),
        relinearization_(relinearization),
        out_(out) {}

  association::AssociationResult Solve(const std::vector<std::vector<int>>& groups) {
    State state;
    state.landmark_of_feature.assign(s_.num_landmarks(), -1);
    state.paired_landmark.assign(candidates_.size(), 0);
    state.loop_open = loop_.regime;
    state.problem = problem_;
    const bool confirm = loop_.regime && o_.loop_confirmation_maps > 0 &&
                         3.0 * loop_.sigma_xy >= o_.loop_confirmation_min_sigma_radius_m;
    std::optional<State> before_closure;  // the state before a closure waiting for confirmation
    int closing_group = -1, suppressed_group = -1;
    const int num_groups = static_cast<int>(groups.size());
    for (int g = 0; g <= num_groups; ++g) {
      // Unconfirmed by the next loop_confirmation_maps groups, or still waiting after the
      // last one (the maps that would confirm it come in a later join, which can close the
      // loop with them): the decisions from the closing group on are made again, without
      // its loop pairings. Closing groups only move on, so this ends.
      const bool waiting_at_end = g == num_groups && before_closure.has_value();
      if (waiting_at_end || (before_closure.has_value() && g - closing_group > o_.loop_confirmation_maps)) {
        ++out_->loop_closures_unconfirmed;
        state = std::move(*before_closure);
        before_closure.reset();
        problem_ = state.problem;
        suppressed_group = closing_group;
        g = closing_group;
      }
      if (g == num_groups) break;
      State before = confirm && !before_closure.has_value() ? state : State();
      const GroupOutcome outcome = AssociateGroup(groups[g], /*suppress_loop=*/g == suppressed_group, &state);
      if (outcome.closed_loop && relinearization_ != nullptr) {
        std::vector<std::pair<int, int>> pairs;
        for (int i : state.decided) pairs.push_back({i, state.landmark_of_feature[i]});
        problem_ = &relinearization_->At(relinearization_->Fit(pairs), pairs);
        state.problem = problem_;
      }
      if (before_closure.has_value()) {
        if (outcome.found_old_landmark) {
          ++out_->loop_closures_confirmed;
          before_closure.reset();
        }
      } else if (outcome.closed_loop && confirm) {
        before_closure = std::move(before);
        closing_group = g;
      }
    }
    association::AssociationResult result;
    result.landmark_of_detection = std::move(state.landmark_of_feature);
    result.pairings = static_cast<int>(state.decided.size());
    out_->uncertain_loop_features = std::move(state.uncertain_loop_features);
    return result;
  }

 private:
  struct State {
    std::vector<int> landmark_of_feature;  // candidate index per feature (−1: none yet)
    std::vector<int> decided;              // features paired so far, in order
    std::vector<char> paired_landmark;     // by candidate index
    std::vector<int> uncertain_loop_features;
    bool loop_open = false;
    const association::AssociationProblem* problem = nullptr;  // the linearisation in use
  };
  struct GroupOutcome {
    bool closed_loop = false;         // kept at least min_loop_pairings loop pairings
    bool found_old_landmark = false;  // paired an old landmark no earlier group had paired
  };

  // Associates the group's undecided features given the decided ones.
  GroupOutcome AssociateGroup(const std::vector<int>& group, bool suppress_loop, State* state) {
    const int n = s_.num_landmarks();
    std::vector<int> detections = state->decided;
    for (int i : group) {
      if (i < 0 || i >= n || state->landmark_of_feature[i] >= 0 || problem_->candidates[i].empty()) continue;
      if (std::find(detections.begin() + state->decided.size(), detections.end(), i) == detections.end()) {
        detections.push_back(i);
      }
    }
    const int num_decided = static_cast<int>(state->decided.size()), count = static_cast<int>(detections.size());
    GroupOutcome outcome;
    if (count == num_decided) return outcome;
    association::AssociationProblem sub;
    sub.candidates.resize(count);
    sub.required.assign(count, 0);
    for (int d = 0; d < count; ++d) {
      const int i = detections[d];
      if (d < num_decided) {
        for (const association::AssociationCandidate& cand : problem_->candidates[i]) {
          if (cand.landmark == state->landmark_of_feature[i]) sub.candidates[d].push_back(cand);
        }
        sub.required[d] = 1;
      } else {
        sub.candidates[d] = problem_->candidates[i];
      }
    }
    sub.covariance_block = [&](int d1, int a, int d2, int b) {
      return problem_->covariance_block(detections[d1], a, detections[d2], b);
    };
    // An old landmark: one no recent map saw and no earlier group paired (outside the
    // loop regime no landmark is flagged recent, and none is needed).
    const auto old = [&](int c) {
      return c >= 0 && (loop_.recent.empty() || !loop_.recent[candidates_[c]]) && !state->paired_landmark[c];
    };
    const auto loop_pairings_of = [&](const association::AssociationResult& r) {
      int k = 0;
      for (int d = num_decided; d < count; ++d) k += old(r.landmark_of_detection[d]) ? 1 : 0;
      return k;
    };
    association::AssociationResult r = association::JointCompatibility(sub, o_.gate_probability, o_.jcbb_max_nodes);
    out_->jcbb_truncated = out_->jcbb_truncated || r.truncated;
    for (int d = 0; d < num_decided; ++d) {
      if (r.landmark_of_detection[d] < 0) return outcome;  // could not condition on them: unpaired
    }
    const int loop_pairings = loop_pairings_of(r);
    outcome.found_old_landmark = loop_pairings > 0;
    if (state->loop_open && loop_pairings > 0) {
      bool drop = suppress_loop || loop_pairings < o_.min_loop_pairings;
      if (!suppress_loop && loop_pairings < o_.min_loop_pairings) out_->loop_pairings_dropped += loop_pairings;
      if (!drop && o_.loop_ambiguity_test) {
        association::AssociationProblem alternative = sub;
        for (int d = num_decided; d < count; ++d) {
          const int c = r.landmark_of_detection[d];
          if (!old(c)) continue;
          std::erase_if(alternative.candidates[d],
                        [c](const association::AssociationCandidate& x) { return x.landmark == c; });
        }
        const association::AssociationResult other =
            association::JointCompatibility(alternative, o_.gate_probability, o_.jcbb_max_nodes);
        if (loop_pairings_of(other) >= o_.min_loop_pairings) {
          drop = true;
          out_->loop_ambiguous = true;
        }
      }
      if (drop) {
        for (int d = num_decided; d < count; ++d) {
          int& c = r.landmark_of_detection[d];
          if (old(c) && !loop_.certain[candidates_[c]]) c = -1;
        }
      } else {
        for (int d = num_decided; d < count; ++d) {
          if (old(r.landmark_of_detection[d])) state->uncertain_loop_features.push_back(detections[d]);
        }
        state->loop_open = false;
        outcome.closed_loop = true;
      }
    }
    for (int d = num_decided; d < count; ++d) {
      const int i = detections[d], c = r.landmark_of_detection[d];
      if (c < 0) continue;
      state->landmark_of_feature[i] = c;
      state->paired_landmark[c] = 1;
      state->decided.push_back(i);
    }
    return outcome;
  }

  const SubmapAssociationOptions& o_;
  const LocalSubmap& s_;
  const std::vector<int>& candidates_;
  const LoopFlags& loop_;
  const association::AssociationProblem* problem_;
  Relinearization* relinearization_;
  SubmapAssociation* out_;
};

// Step 4: JCBB over the individually compatible pairings, with the joint covariance of P_s
// and those candidates only; then the loop-closure ambiguity test: with the hypothesis'
// loop pairings struck out, does another jointly compatible hypothesis still pair as many
// features with old landmarks? Then the corridor offers two explanations and the loop
// closure waits (its uncertain pairings are dropped).
association::AssociationResult JointlyCompatible(const SubmapAssociationOptions& o, const LocalSubmap& s,
                                                 int start_anchor, const std::vector<int>& candidates,
                                                 const CandidateGeometry& geometry, const LoopFlags& loop,
                                                 const TimedCovariance& timed_covariance,
                                                 const std::vector<std::vector<int>>* groups,
                                                 Relinearization* relinearization,
                                                 association::AssociationProblem* problem, SubmapAssociation* out) {
  const InnovationCovariance covariance(*problem, start_anchor, candidates, geometry, timed_covariance);
  problem->covariance_block = [&](int i, int a, int k, int b) { return covariance(s.covariance, i, a, k, b); };
  if (groups != nullptr) {
    return GroupedAssociation(o, s, candidates, loop, *problem, relinearization, out).Solve(*groups);
  }
  association::AssociationResult result =
      association::JointCompatibility(*problem, o.gate_probability, o.jcbb_max_nodes);
  out->jcbb_truncated = result.truncated;
  out->pairings_d2 = result.pairings > 0 ? result.joint_d2 : 0.0;
  out->pairings_dof = 2 * result.pairings;
  const auto closes_loop = [&](int c) { return c >= 0 && !loop.recent[candidates[c]]; };
  const auto loop_pairings_of = [&](const association::AssociationResult& r) {
    return static_cast<int>(std::count_if(r.landmark_of_detection.begin(), r.landmark_of_detection.end(), closes_loop));
  };
  // With the hypothesis' loop pairings struck out: how many features does the best other
  // jointly compatible hypothesis pair with old landmarks?
  const auto other_loop_pairings = [&]() {
    association::AssociationProblem alternative = *problem;
    for (int i = 0; i < s.num_landmarks(); ++i) {
      const int c = result.landmark_of_detection[i];
      if (!closes_loop(c)) continue;
      std::erase_if(alternative.candidates[i],
                    [c](const association::AssociationCandidate& x) { return x.landmark == c; });
    }
    return loop_pairings_of(association::JointCompatibility(alternative, o.gate_probability, o.jcbb_max_nodes));
  };
  const int loop_pairings = loop.regime ? loop_pairings_of(result) : 0;  // (flags only in the regime)
  if (o.confirm_thin_loops && o.loop_ambiguity_test && loop.regime && loop_pairings > 0 &&
      loop_pairings < o.min_loop_pairings) {
    // A thin closure: offered for confirmation (SubmapAssociation::thin_loop_pairings)
    // only if no other hypothesis pairs as many features with old landmarks.
    out->thin_loop_unambiguous = other_loop_pairings() < loop_pairings;
  }
  if (o.loop_ambiguity_test && loop.regime && loop_pairings >= o.min_loop_pairings &&
      other_loop_pairings() >= o.min_loop_pairings) {
    for (int& c : result.landmark_of_detection) {
      if (closes_loop(c) && !loop.certain[candidates[c]]) c = -1;
    }
    out->loop_ambiguous = true;
  }
  return result;
}

// A loop closure — pairings with landmarks no recent local map saw — is accepted only
// with at least min_loop_pairings of them, when the start anchor is uncertain (3σ at
// least loop_test_min_sigma_radius_m): after a long drift the gates are wide and a
// hypothesis with one or two old landmarks is easily compatible by chance.
void ApplyLoopPairingTest(const SubmapAssociationOptions& o, const LoopFlags& flags, SubmapAssociation* out) {
  if (!flags.regime) return;
  int loop_pairings = 0;
  for (int j : out->landmark_of_feature) loop_pairings += (j >= 0 && !flags.recent[j]) ? 1 : 0;
  if (loop_pairings > 0 && loop_pairings < o.min_loop_pairings) {
    for (size_t i = 0; i < out->landmark_of_feature.size(); ++i) {
      int& j = out->landmark_of_feature[i];
      if (j < 0 || flags.recent[j] || flags.certain[j]) continue;
      if (out->thin_loop_unambiguous) out->thin_loop_pairings.push_back({static_cast<int>(i), j});
      j = -1;
    }
    if (!out->thin_loop_unambiguous) out->thin_loop_pairings.clear();
    out->loop_pairings_dropped = loop_pairings;
  } else {
    for (size_t i = 0; i < out->landmark_of_feature.size(); ++i) {
      const int j = out->landmark_of_feature[i];
      if (j >= 0 && !flags.recent[j]) out->uncertain_loop_features.push_back(static_cast<int>(i));
    }
  }
}

// Flags, by landmark, those the last `maps` local maps of the graph saw.
std::vector<char> RecentLandmarks(const SubmapGraph& graph, int maps) {
  std::vector<char> recent(graph.num_landmarks(), 0);
  const int num_factors = static_cast<int>(graph.factors().size());
  for (int f = std::max(0, num_factors - maps); f < num_factors; ++f) {
    for (int j : graph.factors()[f].landmark_of_feature) recent[j] = 1;
  }
  return recent;
}

// Adds to the (ascending) candidates the recent landmarks near a feature of the map placed
// as `m` that are not among them yet.
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

// The rotation test (map_rotation_sigma_rad) of a local map against the landmarks the last
// recent_maps (at least one) local maps saw. Those are known relative to the start anchor
// about as well as that map's own features were: a map whose features cannot be paired
// with them as they are, but can once rotated about its start, is wrong in itself, and a
// rotation is how a particle filter's map over a turn is wrong.
//  1. A first δ by a vote over rotations within ±3σ in steps of σ/10, the map widened by
//     one step at each: the rotation under which the most features find an individually
//     compatible recent landmark (the smaller sum of their best d² breaking a tie).
//  2. The features are paired with the recent landmarks by JCBB with the map rotated by δ
//     and widened by a rotation of σ about its start.
//  3. δ is fitted to those pairings: Gauss-Newton on d²(δ) = ν(δ)ᵀ S(δ)⁻¹ ν(δ), the joint
//     innovation of the pairings with the map rotated by δ (its covariance with it). Steps
//     2-3 repeat until the pairings stand. (Pairing is linearised at δ, not at 0: a
//     rotation of 0.1 rad moves a feature 15 m away by 0.08 m along its range through the
//     second-order term alone, more than a range error a map over one second admits.)
//  4. The statistic is the likelihood ratio d²(0) − d²(δ̂) of those pairings (at least two):
//     χ²₁ for a map that is not rotated.
// A hypothesis that pairs a feature the map's own association paired with a recent landmark
// otherwise (with another, or none) explains again what the map explains as it is: no fit.
struct RotationFit {
  double delta_rad = 0.0;
  double statistic = NAN;      // NaN: fewer than two pairings, or a re-pairing (see above)
  double variance_rad2 = NAN;  // of δ̂, given the pairings
};

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
  std::vector<int> recent_candidates;  // indices into candidates
  std::vector<Eigen::Matrix2d> relative;
  for (int c = 0; c < static_cast<int>(candidates.size()); ++c) {
    if (!recent[candidates[c]]) continue;
    recent_candidates.push_back(c);
    relative.push_back(geometry.Relative(c));
  }
  if (recent_candidates.size() < 2) return fit;
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
  if (best_count < 2) return fit;
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

}  // namespace

SubmapAssociation SubmapAssociator::AssociateByTruth(const LocalSubmap& s) const {
  SubmapAssociation out;
  out.landmark_of_feature.assign(s.num_landmarks(), -1);
  for (int i = 0; i < s.num_landmarks(); ++i) {
    const std::optional<int>& t = s.landmarks[i].truth_id;
    if (!t.has_value() || *t < 0) continue;  // unknown or false alarm: a new landmark
    auto it = landmark_of_truth_.find(*t);
    if (it != landmark_of_truth_.end()) out.landmark_of_feature[i] = it->second;
  }
  return out;
}

SubmapAssociation SubmapAssociator::Associate(const LocalSubmap& s, int start_anchor, const SubmapGraph& graph,
                                              const JointCovarianceFn& joint_covariance, bool anchor_prefilter,
                                              const PairCovarianceFn& pair_covariance, const PairBoundFn& pair_bound,
                                              const std::vector<std::vector<int>>* groups) const {
  if (options_.known_association) return AssociateByTruth(s);
  const int n = s.num_landmarks();
  SubmapAssociation out;
  out.landmark_of_feature.assign(n, -1);
  const TimedCovariance timed_covariance(joint_covariance, &out.covariance_seconds);
  const Eigen::Matrix3d Sigma_s = timed_covariance({start_anchor}, {});
  out.start_anchor_covariance = Sigma_s;
  const PlacedMap placed = Place(s, graph.anchors()[start_anchor], Sigma_s, options_.landmark_search_radius_m);
  out.start_position_sigma_m = placed.sigma_xy;
  std::vector<int> candidates = NearbyLandmarks(graph, placed, anchor_prefilter, options_.anchor_search_radius_m);
  // The rotation test (map_rotation_sigma_rad) looks for the recent landmarks as far as the
  // widened map's features reach. (A map joined widened once, and associated again after an
  // undone loop closure, is not tested again.)
  const double sigma_rotation = options_.map_rotation_sigma_rad;
  const bool test_rotation =
      sigma_rotation > 0 && options_.joint_compatibility && groups == nullptr && !(s.rotation_widening_rad > 0);
  std::optional<PlacedMap> placed_widened;
  Eigen::Matrix3d Sigma_widened = Sigma_s;
  Sigma_widened(2, 2) += sigma_rotation * sigma_rotation;  // the search radii grow as for the start heading
  std::vector<char> recent;
  if (test_rotation) {
    placed_widened = Place(s, placed.P_s, Sigma_widened, options_.landmark_search_radius_m);
    recent = RecentLandmarks(graph, std::max(1, options_.recent_maps));
    AddRecentCandidates(graph, *placed_widened, recent, &candidates);
  }
  out.candidates = static_cast<int>(candidates.size());
  const GateTest gate(s, *this);
  if (pair_bound && pair_covariance) {
    const absl::Time t0 = absl::Now();
    const std::vector<std::optional<Matrix5d>> bounds = pair_bound(start_anchor, candidates);
    out.covariance_seconds += absl::ToDoubleSeconds(absl::Now() - t0);
    std::vector<int> kept =
        test_rotation ? PossiblyCompatible(candidates, bounds, placed, graph, s, gate, &*placed_widened, &recent)
                      : PossiblyCompatible(candidates, bounds, placed, graph, s, gate);
    out.candidates_bounded_out = static_cast<int>(candidates.size() - kept.size());
    candidates.swap(kept);
  }
  if (candidates.empty()) return out;
  const CandidateGeometry geometry =
      Geometry(start_anchor, candidates, placed.P_s, graph, pair_covariance, timed_covariance, &out.covariance_seconds);
  const LoopFlags loop = FlagLoopLandmarks(options_, graph, placed.sigma_xy, candidates, geometry);
  const bool by_group = groups != nullptr && options_.joint_compatibility;
  // Steps 3-5 for the map `m` (the local map, or it widened by a rotation) placed as `placed_m`.
  const auto associate_features = [&](const LocalSubmap& m, const PlacedMap& placed_m, SubmapAssociation* a) {
    association::AssociationProblem problem = IndividualCompatibility(m, candidates, placed_m, graph, geometry, gate);
    std::optional<Relinearization> relinearization;
    if (by_group) {
      relinearization.emplace(m, start_anchor, candidates, graph, geometry, placed_m.P_s, Sigma_s,
                              options_.landmark_search_radius_m, gate, timed_covariance);
    }
    association::AssociationResult result =
        options_.joint_compatibility
            ? JointlyCompatible(options_, m, start_anchor, candidates, geometry, loop, timed_covariance,
                                by_group ? groups : nullptr, relinearization ? &*relinearization : nullptr, &problem, a)
            : association::NearestNeighbour(problem);
    for (int i = 0; i < n; ++i) {
      if (result.landmark_of_detection[i] >= 0) a->landmark_of_feature[i] = candidates[result.landmark_of_detection[i]];
    }
    if (!by_group) ApplyLoopPairingTest(options_, loop, a);  // the grouped search applied it per group
  };
  associate_features(s, placed, &out);
  if (!test_rotation) return out;
  const RotationFit fit = FitRecentRotation(options_, s, placed, Sigma_widened, start_anchor, candidates, graph,
                                            geometry, gate, timed_covariance, recent, out.landmark_of_feature);
  out.map_rotation_statistic = fit.statistic;
  if (std::isfinite(fit.statistic)) {
    out.map_rotation_fit_rad = fit.delta_rad;
    out.map_rotation_fit_variance_rad2 = fit.variance_rad2;
  }
  if (!(fit.statistic >= models::ChiSquareQuantile(options_.map_rotation_probability, 1))) return out;
  // The map is rotated beyond its covariance: associated, and joined, widened.
  SubmapAssociation again;
  again.landmark_of_feature.assign(n, -1);
  again.map_rotated = true;
  again.map_rotation_rad = fit.delta_rad;
  // The rotation's spread, as the data show it: δ̂ ~ N(0, σ² + var δ̂) for a map rotated by
  // N(0, σ²) gives σ̂² = δ̂² − var δ̂ (positive: the test passed).
  again.map_widening_rad = std::sqrt(std::max(0.0, fit.delta_rad * fit.delta_rad - fit.variance_rad2));
  again.map_rotation_statistic = fit.statistic;
  again.map_rotation_fit_rad = out.map_rotation_fit_rad;
  again.map_rotation_fit_variance_rad2 = out.map_rotation_fit_variance_rad2;
  const LocalSubmap joined = *RotatedBack(s, again);
  associate_features(joined, Place(joined, placed.P_s, Sigma_widened, options_.landmark_search_radius_m), &again);
  again.jcbb_truncated = again.jcbb_truncated || out.jcbb_truncated;
  again.covariance_seconds = out.covariance_seconds;
  again.candidates = out.candidates;
  again.candidates_bounded_out = out.candidates_bounded_out;
  again.start_anchor_covariance = out.start_anchor_covariance;
  again.start_position_sigma_m = out.start_position_sigma_m;
  return again;
}

}  // namespace subslam::backend
