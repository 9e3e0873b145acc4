// The EIF joiner's information matrix Λ = Σ_f H_f, assembled from the factors' dense
// blocks (private to the back-end).
//
// Joins only append factors, so Λ is kept as the sum over its first factors and grows
// by the newer ones; after a relinearisation over the same variables only its values are
// refilled (each H entry's slot in Λ's values recorded when the pattern was built); after
// a change of layout (merges, splits, an undone join) it is assembled again. Λ is built
// only when a full factorisation, or a caller of Full(), asks for it.
#ifndef SUBSLAM_BACKEND_SRC_EIF_INFORMATION_MATRIX_H_
#define SUBSLAM_BACKEND_SRC_EIF_INFORMATION_MATRIX_H_

#include <Eigen/SparseCore>
#include <cstddef>
#include <vector>

#include "eif_factor.h"
#include "subslam/backend/internal/sparse_cholesky.h"

namespace subslam::backend {

class EifInformationMatrix {
 public:
  // Λ's lower triangle (what a factorisation takes) over `dim` state rows.
  const SparseLowerTriangle& Lower(const std::vector<EifFactor>& factors, int dim);
  // Λ, both triangles (for tests and tools).
  const Eigen::SparseMatrix<double>& Full(const std::vector<EifFactor>& factors, int dim);
  // Every factor's H may have changed (relinearised, re-keyed, or the factors replaced):
  // the next call assembles or refills Λ from all of them.
  void Forget();

 private:
  // Λ's lower triangle's pattern (values left unset) and slots_ from the factors'
  // variable blocks.
  void BuildPattern(const std::vector<EifFactor>& factors, int dim);
  // values = Σ over factors from first_factor on of their H entries in the lower
  // triangle, at their slots (slots_ must be this pattern's).
  void FillValues(const std::vector<EifFactor>& factors, size_t first_factor, std::vector<double>* values) const;
  // The variable offsets of every factor, concatenated (what Λ's pattern depends on).
  static std::vector<int> FactorOffsets(const std::vector<EifFactor>& factors);

  // Λ's lower triangle as the sum of the first `factors_summed_` factors' H (0: none, or
  // forgotten since). full_: both triangles, built from it for Full().
  SparseLowerTriangle lower_;
  size_t factors_summed_ = 0;
  Eigen::SparseMatrix<double> full_;
  bool full_valid_ = false;
  // Where each factor's H entries (in ForEachEntry's order, factors in order) sit in the
  // lower triangle's values (−1: above the diagonal), and the factors' variable offsets
  // they were found for: while those are the same, a relinearised Λ is only refilled
  // (same pattern), not assembled again.
  std::vector<int> slots_;
  std::vector<int> slot_offsets_;
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_SRC_EIF_INFORMATION_MATRIX_H_
