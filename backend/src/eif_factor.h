// One local map's factor in the EIF joiner's information form (private to the back-end):
// its linearisation at the estimate, its information blocks, and how far its linear model
// is from the estimate (what the relinearisation trigger tests).
//
// The factor r = h(x) ⊖ z of local map Q (docs/conventions.md, "The submap factor")
// touches its start anchor (none for the fixed P0), its end anchor and its landmarks.
// Linearised at x̂ it contributes H = Jᵀ Q⁻¹ J to Λ and b = Jᵀ Q⁻¹ (J x̂ − r(x̂)) to η, over
// its variable blocks stacked in that order. It is nonlinear only through the start
// anchor's heading θ_s: each position row is Rᵀ(θ_s) v, v a lever from the start anchor.
#ifndef SUBSLAM_BACKEND_SRC_EIF_FACTOR_H_
#define SUBSLAM_BACKEND_SRC_EIF_FACTOR_H_

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "eif_estimate.h"

namespace subslam::backend {

class EifFactor {
 public:
  // The factor of graph factor `index`, not yet linearised, its variables' rows set;
  // `screened`: with the smallest eigenvalue of Q that LinearizationErrorAbove's bound uses.
  static EifFactor Make(const EifEstimate& estimate, int index, bool screened);
  // A copy of `other`'s local-map terms (Q's factor, Q⁻¹, its smallest eigenvalue) for
  // graph factor `index` of `estimate`, its rows set, not linearised.
  static EifFactor WithTermsOf(const EifFactor& other, const EifEstimate& estimate, int index);

  // Its variables' rows, from the graph's factor record (again after a layout change).
  void SetLayout(const EifEstimate& estimate);
  // H, b and the cost at the estimate, and (if asked) the whitened Jacobian L_Q⁻¹ J (the
  // newest factor's rank update of the incremental factor).
  void Linearize(const EifEstimate& estimate, Eigen::MatrixXd* whitened_jacobian = nullptr);

  // The whitened linearisation error at the estimate,
  // ‖L_Q⁻¹ (r(x) − r(x₀) − J(x₀)(x − x₀))‖², x₀ its linearisation point.
  double LinearizationError(const EifEstimate& estimate) const;
  // Whether that error exceeds chi2, most factors settled by a bound without the error
  // itself (`scratch` reused between calls).
  bool LinearizationErrorAbove(const EifEstimate& estimate, double chi2, Eigen::VectorXd* scratch) const;
  // |heading now − heading at the linearisation|, the larger of its two anchors'.
  double HeadingDrift(const EifEstimate& estimate) const;
  // rᵀ Q⁻¹ r at the estimate (its term of the joiner's Cost()).
  double NormalizedResidual(const EifEstimate& estimate) const;

  // Adds b to η, or H x_f to y (x, y over the whole state).
  void AddToEta(Eigen::VectorXd* eta) const;
  void AddInformationTimes(const Eigen::VectorXd& x, Eigen::VectorXd* y) const;
  // visit(row, col, value) for each entry of H, at its place in the state: block pairs
  // (a, b), rows i outer, columns j inner.
  template <typename Visit>
  void ForEachEntry(Visit visit) const;

  // What Linearize sets, set aside while Gauss-Newton tries the next linearisation
  // (swapped, never copied).
  struct Linearization {
    Eigen::MatrixXd H;
    Eigen::VectorXd b;
    double start_theta = 0.0, end_theta = 0.0;
    std::vector<Eigen::Vector2d> levers;
    double cost = 0.0;
  };
  void SwapLinearization(Linearization* l);

  int index = 0;             // into the graph's factors()
  std::vector<int> offsets;  // state offset of each variable block (−1: fixed P0)
  std::vector<int> sizes;    // 3 or 2
  Eigen::MatrixXd H;         // Jᵀ Q⁻¹ J over the stacked variable blocks
  Eigen::VectorXd b;         // Jᵀ Q⁻¹ (J x̂ − r)
  double cost = 0.0;         // rᵀ Q⁻¹ r at the linearisation point
  double start_theta = 0.0;  // the anchors' headings at the linearisation
  double end_theta = 0.0;

 private:
  // The headings and levers of the linearisation at (start, end) and the estimate's landmarks.
  void RecordLinearizationPoint(const EifEstimate& estimate, const Pose2& start, const Pose2& end);
  // H and b from the Jacobian's block structure and Q⁻¹ (no whitening).
  void LinearizeStructured(const EifEstimate& estimate);
  // The linearisation error before whitening, e (3 + 2n; the heading row 0).
  void UnwhitenedLinearizationError(const EifEstimate& estimate, Eigen::VectorXd* e) const;

  // The levers from the start anchor to the end anchor and to each landmark at the
  // linearisation (what the linearisation error needs).
  std::vector<Eigen::Vector2d> levers_;
  double covariance_min_eigenvalue_ = 0.0;  // of Q (when screened)
  // L of the local map's covariance Q = L Lᵀ (lower triangular), which whitens the
  // factor; computed once, shared by copies.
  std::shared_ptr<const Eigen::MatrixXd> covariance_sqrt_;
  // Q⁻¹, computed on the factor's first structured linearisation (copies made before that
  // compute their own).
  std::shared_ptr<const Eigen::MatrixXd> information_;
};

template <typename Visit>
void EifFactor::ForEachEntry(Visit visit) const {
  int row = 0;
  for (size_t a = 0; a < offsets.size(); ++a) {
    int col = 0;
    for (size_t b = 0; b < offsets.size(); ++b) {
      for (int i = 0; i < sizes[a]; ++i) {
        for (int j = 0; j < sizes[b]; ++j) visit(offsets[a] + i, offsets[b] + j, H(row + i, col + j));
      }
      col += sizes[b];
    }
    row += sizes[a];
  }
}

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_SRC_EIF_FACTOR_H_
