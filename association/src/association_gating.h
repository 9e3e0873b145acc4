// The steps of a local map's association against the map that decide which pairings are
// possible (association/submap_association.h, SubmapAssociator::Associate): the map placed by its
// start anchor, the candidate landmarks near its features, their geometry seen from the
// start anchor, the gate of each (feature, candidate) pairing, and the joint innovation
// covariance JCBB asks for.
#ifndef SUBSLAM_ASSOCIATION_SRC_ASSOCIATION_GATING_H_
#define SUBSLAM_ASSOCIATION_SRC_ASSOCIATION_GATING_H_

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "absl/time/clock.h"
#include "subslam/association/data_association.h"
#include "subslam/association/submap_association.h"
#include "subslam/core/local_submap.h"
#include "subslam/core/submap_graph.h"
#include "subslam/models/gating.h"

namespace subslam::association::submap_matching {

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
  // The loop tests' radius [m]: loop_test_min_sigma_radius_m, or the candidates' spacing
  // when smaller (loop_test_scaled_by_spacing); the regime is 3σ_xy at least this.
  double radius = 0.0;
  std::vector<char> recent, certain;
};

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

PlacedMap Place(const LocalSubmap& s, const Pose2& P_s, const Eigen::Matrix3d& Sigma_s, double landmark_radius);

// Step 1: the landmarks near some feature, among those of local maps with an anchor
// within `anchor_radius` (+ 3σ) of the start anchor (all of them without the prefilter).
std::vector<int> NearbyLandmarks(const SubmapGraph& graph, const PlacedMap& m, bool anchor_prefilter,
                                 double anchor_radius);

// Step 2: the candidates that could pass the gate with some feature under the joiner's
// upper bound on their marginal (a candidate without a bound is kept); and those that
// `keep_if_near` flags near a feature of the map placed as `wide` (the rotation test's
// recent landmarks: few, and no linearised gate holds for a map rotated by tenths of a
// radian).
std::vector<int> PossiblyCompatible(const std::vector<int>& candidates,
                                    const std::vector<std::optional<Matrix5d>>& bounds, const PlacedMap& m,
                                    const SubmapGraph& graph, const LocalSubmap& s, const GateTest& gate,
                                    const PlacedMap* wide = nullptr, const std::vector<char>* keep_if_near = nullptr);

// The median over `landmarks` of each one's distance to the nearest other [m] (infinite
// for fewer than two): the spacing a chance fit can shift a map by.
double MedianNearestNeighbourDistance(const SubmapGraph& graph, const std::vector<int>& landmarks);

LoopFlags FlagLoopLandmarks(const SubmapAssociationOptions& o, const SubmapGraph& graph, double sigma_xy,
                            const std::vector<int>& candidates, const CandidateGeometry& geometry);

// The marginal of [P_s, L_c] for each candidate — from the joiner's pairwise blocks when
// it has them (no cross-covariances between candidates are formed), else from the joint
// covariance of all candidates — and each candidate's prediction from P_s.
CandidateGeometry Geometry(int start_anchor, const std::vector<int>& candidates, const Pose2& P_s,
                           const SubmapGraph& graph, const SubmapAssociator::PairCovarianceFn& pair_covariance,
                           const TimedCovariance& timed_covariance, double* covariance_seconds);

// Step 3: individual compatibility of each (feature, candidate) pair; each feature's
// compatible candidates by increasing score.
association::AssociationProblem IndividualCompatibility(const LocalSubmap& s, const std::vector<int>& candidates,
                                                        const PlacedMap& m, const SubmapGraph& graph,
                                                        const CandidateGeometry& geometry, const GateTest& gate);

}  // namespace subslam::association::submap_matching

#endif  // SUBSLAM_ASSOCIATION_SRC_ASSOCIATION_GATING_H_
