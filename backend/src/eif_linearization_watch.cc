// EifLinearizationWatch: the rows that moved since the relinearisation trigger's last test.

#include "eif_linearization_watch.h"

#include <cmath>

namespace subslam::backend {

void EifLinearizationWatch::OnExactSolve(int dim) {
  changed_all_ = true;
  changed_rows_.clear();
  drift_.assign(dim, 0.0);
}

void EifLinearizationWatch::OnPartialRecovery(int dim, const std::vector<int>& moved,
                                              const std::vector<double>& change) {
  if (changed_all_) return;  // every factor is tested anyway
  drift_.resize(dim, 0.0);
  for (size_t k = 0; k < moved.size(); ++k) {
    double& drift = drift_[moved[k]];
    drift += std::abs(change[k]);
    if (drift > kRecheckDrift) {
      changed_rows_.push_back(moved[k]);
      drift = 0.0;
    }
  }
}

void EifLinearizationWatch::OnFactorAdded(const EifFactor& f, int index, int dim) {
  if (!factors_of_row_valid_) return;
  factors_of_row_.resize(dim);
  for (size_t v = 0; v < f.offsets.size(); ++v) {
    for (int i = 0; i < f.sizes[v]; ++i) factors_of_row_[f.offsets[v] + i].push_back(index);
  }
}

void EifLinearizationWatch::ForgetFactorRows() { factors_of_row_valid_ = false; }

void EifLinearizationWatch::Reset() {
  factors_of_row_valid_ = false;
  changed_all_ = true;
  changed_rows_.clear();
  drift_.clear();
}

void EifLinearizationWatch::FactorsToTest(const std::vector<EifFactor>& factors, int dim, bool* all,
                                          std::vector<int>* which) {
  *all = changed_all_;
  which->clear();
  if (changed_all_) return;
  if (!factors_of_row_valid_) {
    factors_of_row_.assign(dim, {});
    for (size_t k = 0; k < factors.size(); ++k) {
      const EifFactor& f = factors[k];
      for (size_t v = 0; v < f.offsets.size(); ++v) {
        for (int i = 0; i < f.sizes[v]; ++i) factors_of_row_[f.offsets[v] + i].push_back(static_cast<int>(k));
      }
    }
    factors_of_row_valid_ = true;
  }
  if (candidate_stamp_.size() < factors.size()) candidate_stamp_.resize(factors.size(), 0);
  const int walk = ++candidate_walks_;
  for (int row : changed_rows_) {
    for (int k : factors_of_row_[row]) {
      if (candidate_stamp_[k] != walk) {
        candidate_stamp_[k] = walk;
        which->push_back(k);
      }
    }
  }
}

void EifLinearizationWatch::MarkTested(int dim) {
  changed_rows_.clear();
  if (changed_all_) drift_.assign(dim, 0.0);
  changed_all_ = false;
}

}  // namespace subslam::backend
