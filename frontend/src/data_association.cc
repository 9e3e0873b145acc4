#include "subslam/frontend/data_association.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "subslam/models/gating.h"

namespace subslam::frontend {

const char* ToString(AssociationMethod method) {
  return method == AssociationMethod::kNearestNeighbour ? "nn" : "jcbb";
}

absl::StatusOr<AssociationMethod> AssociationMethodFromString(const std::string& name) {
  if (name == "nn") return AssociationMethod::kNearestNeighbour;
  if (name == "jcbb") return AssociationMethod::kJointCompatibility;
  return absl::InvalidArgumentError(
      absl::StrCat("unknown association method \"", name, "\" (expected nn or jcbb)"));
}

AssociationResult NearestNeighbour(const AssociationProblem& problem) {
  const int m = static_cast<int>(problem.candidates.size());
  struct Pair {
    double d2;
    int detection, landmark;
  };
  std::vector<Pair> pairs;
  for (int j = 0; j < m; ++j) {
    for (const AssociationCandidate& c : problem.candidates[j]) pairs.push_back({c.d2, j, c.landmark});
  }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) {
    return a.d2 < b.d2 || (a.d2 == b.d2 && a.detection < b.detection);
  });
  AssociationResult r;
  r.landmark_of_detection.assign(m, -1);
  std::vector<int> taken;
  for (const Pair& p : pairs) {
    if (r.landmark_of_detection[p.detection] != -1) continue;
    if (std::find(taken.begin(), taken.end(), p.landmark) != taken.end()) continue;
    r.landmark_of_detection[p.detection] = p.landmark;
    taken.push_back(p.landmark);
    r.joint_d2 += p.d2;
    ++r.pairings;
  }
  return r;
}

namespace {

// Depth-first JCBB with an incrementally grown Cholesky factor of the joint
// innovation covariance of the current hypothesis.
class Jcbb {
 public:
  Jcbb(const AssociationProblem& problem, double gate_probability, long max_nodes)
      : p_(problem), gate_probability_(gate_probability), max_nodes_(max_nodes) {
    const int m = static_cast<int>(problem.candidates.size());
    L_.setZero(2 * m, 2 * m);
    y_.setZero(2 * m);
    L21t_.resize(2 * m, 2);
    current_.assign(m, -1);
    best_.landmark_of_detection.assign(m, -1);
    for (int k = 1; k <= m; ++k) gates_.push_back(models::ChiSquareQuantile(gate_probability_, 2 * k));
    // Only detections with a candidate branch; the others are unpaired in every
    // hypothesis and would only spend the node budget (hundreds of them in a whole-map join).
    for (int j = 0; j < m; ++j) {
      if (!problem.candidates[j].empty()) branching_.push_back(j);
    }
  }

  AssociationResult Solve() {
    Recurse(0, 0, 0.0);
    best_.nodes = nodes_;
    best_.truncated = nodes_ >= max_nodes_;
    return best_;
  }

 private:
  // Branches on the t-th detection that has candidates.
  void Recurse(int t, int k, double d2) {
    const int m = static_cast<int>(branching_.size());
    // Even pairing every remaining detection cannot reach the best hypothesis' count
    // (a tie can still win on d², so only a strict shortfall prunes).
    if (k + (m - t) < best_.pairings) return;
    // At best a tie on pairings, which must then win on d²; adding pairings never lowers
    // the joint d² (each adds ‖y₂‖² ≥ 0), so this subtree cannot.
    if (k + (m - t) == best_.pairings && best_.pairings > 0 && d2 >= best_.joint_d2) return;
    if (nodes_++ >= max_nodes_) return;
    if (t == m) {
      if (k > best_.pairings || (k == best_.pairings && d2 < best_.joint_d2)) {
        best_.pairings = k;
        best_.joint_d2 = d2;
        best_.landmark_of_detection = current_;
      }
      return;
    }
    const int j = branching_[t];
    for (const AssociationCandidate& c : p_.candidates[j]) {
      bool taken = false;  // one-to-one: by an earlier detection of this hypothesis
      for (int a : paired_detection_) taken = taken || current_[a] == c.landmark;
      if (taken) continue;
      double new_d2;
      if (!Extend(j, k, c, &new_d2)) continue;
      if (new_d2 > gates_[k]) continue;
      current_[j] = c.landmark;
      paired_detection_.push_back(j);
      Recurse(t + 1, k + 1, new_d2);
      paired_detection_.pop_back();
      current_[j] = -1;
    }
    // The star branch: leave detection j unpaired if that can still beat the best.
    if (k + (m - t - 1) >= best_.pairings) Recurse(t + 1, k, d2);
  }

  // Appends pairing (j, c) as block row k of L and y; returns the joint d².
  bool Extend(int j, int k, const AssociationCandidate& c, double* d2) {
    // L21t = L11⁻¹ B, B the covariances of the hypothesis' pairings with the new one; in a
    // buffer sized once (no allocation per node).
    auto L21t = L21t_.topRows(2 * k);
    for (int a = 0; a < k; ++a) {
      const int detection_a = paired_detection_[a];
      L21t.block<2, 2>(2 * a, 0) = p_.covariance_block(detection_a, current_[detection_a], j, c.landmark);
    }
    if (k > 0) {
      L_.topLeftCorner(2 * k, 2 * k).triangularView<Eigen::Lower>().solveInPlace(L21t);
    }
    Eigen::Matrix2d C = p_.covariance_block(j, c.landmark, j, c.landmark) - L21t.transpose() * L21t;
    Eigen::LLT<Eigen::Matrix2d> llt(C);
    if (llt.info() != Eigen::Success) return false;
    const Eigen::Matrix2d L22 = llt.matrixL();
    L_.block(2 * k, 0, 2, 2 * k) = L21t.transpose();
    L_.block<2, 2>(2 * k, 2 * k) = L22;
    Eigen::Vector2d rhs = c.innovation;
    if (k > 0) rhs -= L21t.transpose() * y_.head(2 * k);
    const Eigen::Vector2d y2 = L22.triangularView<Eigen::Lower>().solve(rhs);
    y_.segment<2>(2 * k) = y2;
    *d2 = y_.head(2 * k + 2).squaredNorm();
    return true;
  }

  const AssociationProblem& p_;
  double gate_probability_;
  long max_nodes_;
  long nodes_ = 0;
  std::vector<double> gates_;
  Eigen::MatrixXd L_;
  Eigen::Matrix<double, Eigen::Dynamic, 2> L21t_;
  Eigen::VectorXd y_;
  std::vector<int> current_;           // landmark per detection in the hypothesis
  std::vector<int> paired_detection_;  // detection of block row a
  std::vector<int> branching_;         // detections with at least one candidate, in order
  AssociationResult best_;
};

}  // namespace

AssociationResult JointCompatibility(const AssociationProblem& problem, double gate_probability,
                                     long max_nodes) {
  if (problem.candidates.empty()) return {};
  return Jcbb(problem, gate_probability, max_nodes).Solve();
}

}  // namespace subslam::frontend
