// Grouped joint compatibility: the pairings of a local map with the map decided by JCBB
// over groups of features, each group gated about the start anchor the decisions so far
// imply (Relinearization), and the loop test on the pairings (association/submap_association.h).
#ifndef SUBSLAM_ASSOCIATION_SRC_GROUPED_ASSOCIATION_H_
#define SUBSLAM_ASSOCIATION_SRC_GROUPED_ASSOCIATION_H_

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <vector>

#include "association_gating.h"

namespace subslam::association::submap_matching {

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
                                                 association::AssociationProblem* problem, SubmapAssociation* out);

// A loop closure — pairings with landmarks no recent local map saw — is accepted only
// with at least min_loop_pairings of them, when the start anchor is uncertain (3σ at
// least loop_test_min_sigma_radius_m): after a long drift the gates are wide and a
// hypothesis with one or two old landmarks is easily compatible by chance.
void ApplyLoopPairingTest(const SubmapAssociationOptions& o, const LoopFlags& flags, SubmapAssociation* out);

}  // namespace subslam::association::submap_matching

#endif  // SUBSLAM_ASSOCIATION_SRC_GROUPED_ASSOCIATION_H_
