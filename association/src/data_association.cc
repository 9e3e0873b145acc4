#include "subslam/association/data_association.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "subslam/core/enum_names.h"
#include "subslam/models/gating.h"

namespace subslam::association {

namespace {
constexpr EnumName<AssociationMethod> kAssociationMethodNames[] = {{AssociationMethod::kNearestNeighbour, "nn"},
                                                                   {AssociationMethod::kJointCompatibility, "jcbb"}};
}  // namespace

const char* ToString(AssociationMethod method) { return NameOf(kAssociationMethodNames, method); }

absl::StatusOr<AssociationMethod> AssociationMethodFromString(const std::string& name) {
  return ParseEnum(kAssociationMethodNames, name, "association method");
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
  std::sort(pairs.begin(), pairs.end(),
            [](const Pair& a, const Pair& b) { return a.d2 < b.d2 || (a.d2 == b.d2 && a.detection < b.detection); });
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
//
// Extending the hypothesis by a pairing solves L₁₁ X = B (B: the pairing's covariances
// with the hypothesis' pairings) by forward substitution, block row by block row; row a
// of X depends only on the hypothesis' first a + 1 pairings. Each candidate pairing keeps
// the rows it solved, stamped with the pairings they were solved under: when the search
// asks for it again under a hypothesis with the same first r pairings, the substitution
// resumes at row r. Depth-first, that is where siblings and descendants differ, so a
// pairing costs O(k) blocks instead of O(k²) — with the same arithmetic, in the same
// order, as solving from row 0.
class Jcbb {
 public:
  Jcbb(const AssociationProblem& problem, double gate_probability, long max_nodes)
      : p_(problem), gate_probability_(gate_probability), max_nodes_(max_nodes) {
    const int m = static_cast<int>(problem.candidates.size());
    L_.setZero(2 * m, 2 * m);
    y_.setZero(2 * m);
    current_.assign(m, -1);
    best_.landmark_of_detection.assign(m, -1);
    for (int k = 1; k <= m; ++k) gates_.push_back(models::ChiSquareQuantile(gate_probability_, 2 * k));
    // Only detections with a candidate branch; the others are unpaired in every
    // hypothesis and would only spend the node budget (hundreds of them in a whole-map join).
    for (int j = 0; j < m; ++j) {
      if (!problem.candidates[j].empty()) branching_.push_back(j);
    }
    // The required pairings first; then the fewest candidates first (ties in detection
    // order): the narrow levels at the top of the tree, where every branch is paid for
    // again below. On combined-2km's joins under an uncertain anchor (40-70 candidates
    // per detection) it visits fewer nodes and hits the node budget less often
    // (bench/RESULTS.md).
    std::stable_sort(branching_.begin(), branching_.end(), [&](int a, int b) {
      if (Required(a) != Required(b)) return Required(a);
      return problem.candidates[a].size() < problem.candidates[b].size();
    });
    for (int j : branching_) num_required_ += Required(j) ? 1 : 0;
    row_stamp_.assign(m, 0);
    rows_before_.assign(m, 0);
    for (size_t t = 0; t < branching_.size(); ++t) rows_before_[branching_[t]] = static_cast<int>(t);
    first_pair_.assign(m + 1, 0);
    for (int j = 0; j < m; ++j) first_pair_[j + 1] = first_pair_[j] + static_cast<int>(problem.candidates[j].size());
    solved_.resize(first_pair_[m]);
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
    if (t == num_required_) {  // the required pairings placed: what the others are gated given
      base_pairings_ = k;
      base_d2_ = d2;
    }
    const int j = branching_[t];
    if (Required(j)) {  // its one candidate, ungated (a decided pairing), no star branch
      const AssociationCandidate& c = p_.candidates[j].front();
      double new_d2;
      if (!Extend(j, k, c, &solved_[first_pair_[j]], &new_d2)) return;
      current_[j] = c.landmark;
      paired_detection_.push_back(j);
      Recurse(t + 1, k + 1, new_d2);
      paired_detection_.pop_back();
      current_[j] = -1;
      return;
    }
    for (size_t ci = 0; ci < p_.candidates[j].size(); ++ci) {
      const AssociationCandidate& c = p_.candidates[j][ci];
      bool taken = false;  // one-to-one: by an earlier detection of this hypothesis
      for (int a : paired_detection_) taken = taken || current_[a] == c.landmark;
      if (taken) continue;
      double new_d2;
      if (!Extend(j, k, c, &solved_[first_pair_[j] + ci], &new_d2)) continue;
      if (new_d2 - base_d2_ > gates_[k - base_pairings_]) continue;
      current_[j] = c.landmark;
      paired_detection_.push_back(j);
      Recurse(t + 1, k + 1, new_d2);
      paired_detection_.pop_back();
      current_[j] = -1;
    }
    // The star branch: leave detection j unpaired if that can still beat the best.
    if (k + (m - t - 1) >= best_.pairings) Recurse(t + 1, k, d2);
  }

  bool Required(int j) const { return !p_.required.empty() && p_.required[j]; }

  // The forward substitution of one candidate pairing, row by row (see the class comment).
  struct Solved {
    int rows = 0;                      // rows solved
    std::vector<long> stamp;           // row_stamp_ of each row when it was solved
    std::vector<Eigen::Matrix2d> X;    // block row a of L₁₁⁻¹ B
    std::vector<Eigen::Matrix2d> C;    // the pairing's covariance less rows 0 … a
    std::vector<Eigen::Vector2d> rhs;  // its innovation less rows 0 … a
  };

  // Appends pairing (j, c) as block row k of L and y (its rows solved so far in *s,
  // updated); returns the joint d².
  bool Extend(int j, int k, const AssociationCandidate& c, Solved* s, double* d2) {
    // X = L11⁻¹ B, B the covariances of the hypothesis' pairings with the new one, by
    // forward substitution over 2 × 2 blocks in plain fixed-size arithmetic (Eigen's
    // triangular solves dispatch to their general kernels even for 2 × 2 blocks), resumed
    // after the rows solved under the same pairings.
    if (static_cast<int>(s->X.size()) < k) {  // sized once, for the deepest row j can see
      const size_t rows = static_cast<size_t>(rows_before_[j]);
      s->stamp.resize(rows);
      s->X.resize(rows);
      s->C.resize(rows);
      s->rhs.resize(rows);
    }
    int r = 0;
    while (r < s->rows && r < k && s->stamp[r] == row_stamp_[r]) ++r;
    Eigen::Matrix2d C = r == 0 ? p_.covariance_block(j, c.landmark, j, c.landmark) : s->C[r - 1];
    Eigen::Vector2d rhs = r == 0 ? c.innovation : s->rhs[r - 1];
    for (int a = r; a < k; ++a) {
      const int detection_a = paired_detection_[a];
      Eigen::Matrix2d X = p_.covariance_block(detection_a, current_[detection_a], j, c.landmark);
      for (int b = 0; b < a; ++b) {
        X.noalias() -= Eigen::Matrix2d(L_.block<2, 2>(2 * a, 2 * b)) * s->X[b];
      }
      SolveLower2(L_.block<2, 2>(2 * a, 2 * a), &X);
      s->X[a] = X;
      C.noalias() -= X.transpose() * X;
      rhs.noalias() -= X.transpose() * y_.segment<2>(2 * a);
      s->C[a] = C;
      s->rhs[a] = rhs;
      s->stamp[a] = row_stamp_[a];
    }
    s->rows = k;
    // L22 L22ᵀ = C, the conditional covariance of the new innovation.
    if (!(C(0, 0) > 0.0)) return false;
    Eigen::Matrix2d L22 = Eigen::Matrix2d::Zero();
    L22(0, 0) = std::sqrt(C(0, 0));
    L22(1, 0) = C(1, 0) / L22(0, 0);
    const double schur = C(1, 1) - L22(1, 0) * L22(1, 0);
    if (!(schur > 0.0)) return false;
    L22(1, 1) = std::sqrt(schur);
    for (int a = 0; a < k; ++a) L_.block<2, 2>(2 * k, 2 * a) = s->X[a].transpose();
    L_.block<2, 2>(2 * k, 2 * k) = L22;
    row_stamp_[k] = ++stamps_;  // row k now holds this pairing
    Eigen::Matrix<double, 2, 1> y2 = rhs;
    SolveLower2(L22, &y2);
    y_.segment<2>(2 * k) = y2;
    *d2 = y_.head(2 * k + 2).squaredNorm();
    return true;
  }

  // X ← L⁻¹ X for a lower-triangular 2 × 2 L.
  template <typename Lower, int Cols>
  static void SolveLower2(const Lower& L, Eigen::Matrix<double, 2, Cols>* X) {
    X->row(0) /= L(0, 0);
    X->row(1) = (X->row(1) - L(1, 0) * X->row(0)) / L(1, 1);
  }

  const AssociationProblem& p_;
  double gate_probability_;
  long max_nodes_;
  long nodes_ = 0;
  std::vector<double> gates_;
  Eigen::MatrixXd L_;
  Eigen::VectorXd y_;
  std::vector<long> row_stamp_;  // a stamp per block row of L, new whenever it is rewritten
  long stamps_ = 0;
  std::vector<int> first_pair_;        // candidate pairings of detection j: first_pair_[j] …
  std::vector<Solved> solved_;         // by candidate pairing
  std::vector<int> rows_before_;       // at most this many pairings precede detection j's
  std::vector<int> current_;           // landmark per detection in the hypothesis
  std::vector<int> paired_detection_;  // detection of block row a
  std::vector<int> branching_;         // detections with a candidate, fewest candidates first
  int num_required_ = 0;               // the first num_required_ of branching_ are required
  int base_pairings_ = 0;              // pairings and joint d² of the required ones
  double base_d2_ = 0.0;
  AssociationResult best_;
};

}  // namespace

AssociationResult JointCompatibility(const AssociationProblem& problem, double gate_probability, long max_nodes) {
  if (problem.candidates.empty()) return {};
  return Jcbb(problem, gate_probability, max_nodes).Solve();
}

}  // namespace subslam::association
