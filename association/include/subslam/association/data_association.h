// Data association of detections (or local-map features) to map landmarks with unknown
// identities, shared by the single-map filters, the local mappers and the back-ends.
//
// The caller builds an AssociationProblem: for each detection the individually
// compatible landmarks (Mahalanobis d² = νᵀ S⁻¹ ν below the χ²₂ gate), and a function
// giving the blocks of the joint innovation covariance. Two solvers:
//
//  * NearestNeighbour — one-to-one greedy assignment in increasing d² (each landmark
//    takes at most one detection per scan).
//  * JointCompatibility — branch and bound over hypotheses (Neira & Tardós, IEEE
//    T-RA 2001, "JCBB"): the hypothesis with the most pairings whose joint innovation
//    passes the χ²_{2k} gate, ties broken by the smaller joint d². As in JCBB the gate
//    applies to every prefix of a hypothesis in the branching order, which here is
//    the detections with the fewest candidates first (ties in detection order). The
//    joint test uses an incrementally extended Cholesky factor, O(k²) per node; the
//    search stops after `max_nodes` nodes and returns the best hypothesis found so far
//    (reported). Pairings decided beforehand can be given as required (the
//    innovations are then gated conditionally on them).
//
// Not thread-safe per problem; the functions are re-entrant.
#ifndef SUBSLAM_ASSOCIATION_DATA_ASSOCIATION_H_
#define SUBSLAM_ASSOCIATION_DATA_ASSOCIATION_H_

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace subslam::association {

enum class AssociationMethod { kNearestNeighbour, kJointCompatibility };
const char* ToString(AssociationMethod method);
absl::StatusOr<AssociationMethod> AssociationMethodFromString(const std::string& name);

struct AssociationCandidate {
  int landmark = -1;                                     // caller's landmark index
  double d2 = 0.0;                                       // individual Mahalanobis d²
  Eigen::Vector2d innovation = Eigen::Vector2d::Zero();  // z − ẑ (bearing wrapped)
};

struct AssociationProblem {
  // candidates[j]: individually compatible landmarks of detection j, sorted by d².
  std::vector<std::vector<AssociationCandidate>> candidates;
  // Block of the joint innovation covariance between pairing (detection i, landmark a)
  // and pairing (detection j, landmark b); the diagonal (i = j, a = b) includes the
  // measurement noise. Needed by JointCompatibility only.
  std::function<Eigen::Matrix2d(int i, int a, int j, int b)> covariance_block;
  // JointCompatibility only: detections whose pairing is already decided (their one
  // candidate is in every hypothesis; empty: none). The search conditions on them, as a
  // filter that had fused them would: the other pairings' joint innovation given theirs,
  // d² − d²_required, must pass χ²_{2k} for those k pairings.
  std::vector<char> required;
};

struct AssociationResult {
  std::vector<int> landmark_of_detection;  // −1: unassociated
  int pairings = 0;
  double joint_d2 = 0.0;   // JointCompatibility: of the chosen hypothesis
  long nodes = 0;          // JointCompatibility: nodes visited
  bool truncated = false;  // JointCompatibility: node limit reached
};

AssociationResult NearestNeighbour(const AssociationProblem& problem);

AssociationResult JointCompatibility(const AssociationProblem& problem, double gate_probability, long max_nodes);

}  // namespace subslam::association

#endif  // SUBSLAM_ASSOCIATION_DATA_ASSOCIATION_H_
