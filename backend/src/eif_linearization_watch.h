// Which factors the EIF joiner's relinearisation trigger must test next (private to the
// back-end).
//
// The trigger asks after each join whether some factor's linear model is more than its
// noise off the estimate (EifFactor::LinearizationErrorAbove). After an exact solve every
// variable may have moved: every factor is tested. After a partial recovery only the rows
// it moved can have changed a factor's error, and a row whose accumulated change since its
// factors were last tested stays below kRecheckDrift changes it negligibly: only the
// factors on the other rows are tested.
#ifndef SUBSLAM_BACKEND_SRC_EIF_LINEARIZATION_WATCH_H_
#define SUBSLAM_BACKEND_SRC_EIF_LINEARIZATION_WATCH_H_

#include <vector>

#include "eif_factor.h"

namespace subslam::backend {

class EifLinearizationWatch {
 public:
  // A factor's linearisation error moves by a negligible amount when its variables move by
  // less than this [m, rad] (levers of 100 m and headings 0.1 rad off their linearisation
  // change it by 10⁻⁵ m against local-map noise of centimetres and more).
  static constexpr double kRecheckDrift = 1e-6;

  // An exact solve over `dim` rows: test every factor next.
  void OnExactSolve(int dim);
  // A partial recovery moved rows `moved` by `change` (same order).
  void OnPartialRecovery(int dim, const std::vector<int>& moved, const std::vector<double>& change);
  // Factor `index` was appended (its rows in f.offsets).
  void OnFactorAdded(const EifFactor& f, int index, int dim);
  // The factors' rows changed (a new layout): the row → factors table is built again when needed.
  void ForgetFactorRows();
  // The joiner was restored to an earlier state.
  void Reset();
  // The factors to test now: every one (`*all`), or `which`.
  void FactorsToTest(const std::vector<EifFactor>& factors, int dim, bool* all, std::vector<int>* which);
  // After the trigger's test: the rows it covered are tested (and, after a test of every
  // factor, every row's drift starts again).
  void MarkTested(int dim);

 private:
  // Per state row, the factors on it (valid while factors_of_row_valid_).
  std::vector<std::vector<int>> factors_of_row_;
  bool factors_of_row_valid_ = false;
  // Each row's change since its factors were last tested, and the rows past kRecheckDrift.
  std::vector<double> drift_;
  std::vector<int> changed_rows_;
  bool changed_all_ = true;           // an exact solve since the last test
  std::vector<int> candidate_stamp_;  // FactorsToTest()'s factors seen, by walk
  int candidate_walks_ = 0;
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_SRC_EIF_LINEARIZATION_WATCH_H_
