// EifJoiner: the factorisation of Λ, full or by the incremental update of the newest
// factor, and the estimate recovered from it (the information system's solve).

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "eif_joiner_impl.h"
#include "state_blocks.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/internal/sparse_cholesky.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/core/check.h"
#include "subslam/core/stage_timer.h"
#include "subslam/models/gating.h"

namespace subslam::backend {

long EifJoiner::Impl::factor_nonzeros() const { return solver_.factor.nonzeros(); }

FillReducingOrdering EifJoiner::Impl::factor_ordering() const { return solver_.factor.ordering(); }

absl::Status EifJoiner::Impl::FullFactorization() {
  StageTimer full(&times_, "full_factorization");
  SparseCholesky& L = solver_.factor;
  const long reuses = L.symbolic_reuses();
  if (absl::Status st = FactorizeLambda(); !st.ok()) return absl::InternalError(absl::StrCat("EIF: ", st.message()));
  ++counters_.full_factorizations;
  if (L.ordering() == FillReducingOrdering::kNestedDissection) ++counters_.nested_dissection_factorizations;
  counters_.reused_analyses += L.symbolic_reuses() - reuses;
  return absl::OkStatus();
}

absl::Status EifJoiner::Impl::FactorizeLambda() {
  if (!options_.incremental_factorization) {
    // No rank updates will follow: neither spare slots nor a constrained ordering.
    return solver_.factor.Factorize(information_matrix_.Lower(factors_, estimate_.dim), /*spare=*/0, options_.ordering);
  }
  // Spare slots for the next joins' new variables (about 15 % of the state).
  // The last anchor, where the next join starts, is ordered last: the next joins' updates
  // then walk short paths (a chain's last anchor elsewhere in the order would fill a
  // column per variable on its path with every update).
  return solver_.factor.Factorize(information_matrix_.Lower(factors_, estimate_.dim), 64 + estimate_.dim / 6,
                                  options_.ordering, estimate_.LastAnchorRows());
}

absl::Status EifJoiner::Impl::RecoverAcrossNewestFactor(Eigen::Index old_dim) {
  // Carry the estimate over the new factor: Λ'Δx = η' − Λ'x with x the estimate before
  // (the new variables at 0, their spare slots' solution), non-zero on its rows only.
  StageTimer timer(&times_, "recovery");
  Eigen::VectorXd x = estimate_.StateVector();
  x.tail(estimate_.dim - old_dim).setZero();
  const EifFactor& f = factors_.back();
  std::vector<int> rows;
  Eigen::VectorXd x_local(f.H.rows());
  for (size_t v = 0, row = 0; v < f.offsets.size(); row += f.sizes[v], ++v) {
    for (int i = 0; i < f.sizes[v]; ++i) rows.push_back(f.offsets[v] + i);
    x_local.segment(static_cast<Eigen::Index>(row), f.sizes[v]) = x.segment(f.offsets[v], f.sizes[v]);
  }
  const Eigen::VectorXd r = f.b - f.H * x_local;
  std::vector<int> moved;
  std::vector<double> change;
  solver_.factor.SolveChange(rows, r, options_.recovery_change_threshold, &x, &moved, &change);
  if (!x.allFinite()) return absl::InternalError("EIF: state recovery produced a non-finite value");
  estimate_.SetStateRows(x, moved);
  estimate_exact_ = false;
  if (options_.relinearize_linearization_chi2 > 0) linearization_watch_.OnPartialRecovery(estimate_.dim, moved, change);
  return absl::OkStatus();
}

absl::Status EifJoiner::Impl::Rebuild(bool only_last_factor) {
  converged_ = false;
  const Eigen::Index old_dim = eta_.size();
  {
    StageTimer timer(&times_, "update");
    // Λ itself is assembled only when a full factorisation needs it (information()).
    if (only_last_factor) {
      eta_.conservativeResize(estimate_.dim);
      eta_.tail(estimate_.dim - old_dim).setZero();
      factors_.back().AddToEta(&eta_);
      linearization_watch_.OnFactorAdded(factors_.back(), static_cast<int>(factors_.size()) - 1, estimate_.dim);
    } else {
      // Every factor may have been relinearised: Λ need not have grown, so the marginal
      // bounds are forgotten.
      marginal_bound_.assign(estimate_.graph.num_landmarks(), Eigen::Matrix2d::Constant(NAN));
      relative_bounds_.Clear();
      eta_ = Eigen::VectorXd::Zero(estimate_.dim);
      for (const EifFactor& f : factors_) f.AddToEta(&eta_);
      information_matrix_.Forget();
      linearization_watch_.ForgetFactorRows();
    }
  }
  bool incremental = false;
  {
    StageTimer timer(&times_, "factorization");
    SparseCholesky& L = solver_.factor;
    // The newest factor as a rank update of the existing factor, while there are spare
    // slots and the fill has not doubled since the last ordering.
    if (only_last_factor && options_.incremental_factorization && L.ready() && !solver_.stale &&
        estimate_.dim <= L.capacity() &&
        L.nonzeros() <= options_.refactorize_fill_ratio * static_cast<double>(L.nonzeros_after_factorize())) {
      const EifFactor& f = factors_.back();
      std::vector<int> rows;
      for (size_t v = 0; v < f.offsets.size(); ++v) {
        for (int i = 0; i < f.sizes[v]; ++i) rows.push_back(f.offsets[v] + i);
      }
      incremental = L.Update(estimate_.dim, rows, solver_.last_whitened_jacobian.transpose()).ok();
      ++(incremental ? counters_.incremental_updates : counters_.failed_updates);
    }
    solver_.last_whitened_jacobian.resize(0, 0);
    solver_.stale = false;
    if (!incremental) {
      if (absl::Status st = FullFactorization(); !st.ok()) return st;
      updates_since_factorization_ = 0;
    }
  }
  // The guard's schedule: the 1st, 2nd, 4th, … update since the last full factorisation.
  const long update_number = incremental ? ++updates_since_factorization_ : 0;
  const bool guarded = incremental && (update_number & (update_number - 1)) == 0;
  Eigen::VectorXd x;
  if (incremental && !guarded && options_.recovery_change_threshold > 0) {
    return RecoverAcrossNewestFactor(old_dim);
  } else {
    {
      StageTimer timer(&times_, "recovery");
      x = solver_.factor.Solve(eta_);
    }
    if (incremental) {
      // Guard on the updated factor: Λx must give back η, or refactorise. Λx = Σ H_f x_f
      // over the factors' dense blocks (Λ is not assembled).
      StageTimer timer(&times_, "recovery_check");
      Eigen::VectorXd Lambda_x = Eigen::VectorXd::Zero(estimate_.dim);
      for (const EifFactor& f : factors_) f.AddInformationTimes(x, &Lambda_x);
      const double residual = (Lambda_x - eta_).norm();
      if (!(residual <= 1e-8 * std::max(1.0, eta_.norm()))) {
        ++counters_.failed_updates;
        --counters_.incremental_updates;
        if (absl::Status st = FullFactorization(); !st.ok()) return st;
        updates_since_factorization_ = 0;
        x = solver_.factor.Solve(eta_);
      }
    }
  }
  if (!x.allFinite()) return absl::InternalError("EIF: state recovery produced a non-finite value");
  estimate_.SetState(x);
  estimate_exact_ = true;
  // Every variable may have moved (and the layout may have changed): the trigger tests
  // every factor next time.
  linearization_watch_.OnExactSolve(estimate_.dim);
  return absl::OkStatus();
}

double EifJoiner::Impl::InformationNorm(const Eigen::VectorXd& x) const {
  Eigen::VectorXd Lambda_x = Eigen::VectorXd::Zero(x.size());
  for (const EifFactor& f : factors_) f.AddInformationTimes(x, &Lambda_x);
  return x.dot(Lambda_x);
}

const Eigen::SparseMatrix<double>& EifJoiner::Impl::information() const {
  return information_matrix_.Full(factors_, estimate_.dim);
}

}  // namespace subslam::backend
