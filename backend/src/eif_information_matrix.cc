// EifJoiner: the information matrix Λ — its pattern, values and lower triangle — and its
// factorisation, full or by the incremental update of the newest factor.

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
#include "subslam/graph/check.h"
#include "subslam/graph/stage_timer.h"
#include "subslam/models/gating.h"

namespace subslam::backend {
namespace {

// The variable blocks of Λ by their first row, from the factors that link them: each block's
// size, the sorted first rows of the blocks it shares a factor with (itself included), all
// lists in one flat array (block o's from first[o], unique ones first, length unique[o]);
// below[first[o] + k]: the rows of the neighbours after o that come before neighbour k (k
// after o) in each of o's columns; later_rows[o]: the rows of the neighbours after o; count:
// the factors' Jacobian entries.
struct BlockNeighbours {
  std::vector<int> size_of, first, unique, neighbour, below, later_rows;
  size_t count = 0;
};

template <typename Factors>
BlockNeighbours BlockNeighboursOf(const Factors& factors, int dim) {
  // Each variable block by its first row: its size and the sorted first rows of the
  // blocks it shares a factor with (itself included), all lists in one flat array
  // (block o's from first[o], unique ones first, length unique[o]).
  BlockNeighbours nb;
  nb.size_of.assign(dim, 0);
  nb.first.assign(dim + 1, 0);
  nb.unique.assign(dim, 0);
  std::vector<int>& size_of = nb.size_of;
  std::vector<int>& first = nb.first;
  std::vector<int>& unique = nb.unique;
  size_t& count = nb.count;
  for (const auto& f : factors) {
    count += static_cast<size_t>(f.H.size());
    for (size_t b = 0; b < f.offsets.size(); ++b) {
      size_of[f.offsets[b]] = f.sizes[b];
      first[f.offsets[b] + 1] += static_cast<int>(f.offsets.size());
    }
  }
  for (int o = 0; o < dim; ++o) first[o + 1] += first[o];
  nb.neighbour.assign(static_cast<size_t>(first[dim]), 0);
  std::vector<int>& neighbour = nb.neighbour;
  std::vector<int> fill(first.begin(), first.end() - 1);
  for (const auto& f : factors) {
    for (int b : f.offsets) {
      for (int a : f.offsets) neighbour[fill[b]++] = a;
    }
  }
  // The lower triangle: column j of block o holds rows j … of block o itself, then every
  // row of the neighbours after o. below[first[o] + k]: the rows of the neighbours after o
  // that come before neighbour k (k after o) in each of o's columns.
  nb.below.assign(neighbour.size(), 0);
  nb.later_rows.assign(dim, 0);
  std::vector<int>& below = nb.below;
  std::vector<int>& later_rows = nb.later_rows;
  for (int o = 0; o < dim; ++o) {
    if (size_of[o] == 0) continue;
    int* begin = neighbour.data() + first[o];
    std::sort(begin, neighbour.data() + first[o + 1]);
    unique[o] = static_cast<int>(std::unique(begin, neighbour.data() + first[o + 1]) - begin);
    int rows = 0;
    for (int k = 0; k < unique[o]; ++k) {
      if (begin[k] <= o) continue;
      below[first[o] + k] = rows;
      rows += size_of[begin[k]];
    }
    later_rows[o] = rows;
  }
  return nb;
}

}  // namespace

template <typename Visit>
void EifJoiner::Impl::ForEachEntry(const Factor& f, Visit visit) {
  int row = 0;
  for (size_t a = 0; a < f.offsets.size(); ++a) {
    int col = 0;
    for (size_t b = 0; b < f.offsets.size(); ++b) {
      for (int i = 0; i < f.sizes[a]; ++i) {
        for (int j = 0; j < f.sizes[b]; ++j) visit(f.offsets[a] + i, f.offsets[b] + j, f.H(row + i, col + j));
      }
      col += f.sizes[b];
    }
    row += f.sizes[a];
  }
}

const Eigen::SparseMatrix<double>& EifJoiner::Impl::information() const {
  const SparseLowerTriangle& lower = LowerInformation();
  if (lambda_full_valid_ && Lambda_.rows() == dim_) return Lambda_;
  // Both triangles from the lower one.
  const Eigen::Map<const Eigen::SparseMatrix<double>> lower_view(lower.n, lower.n, lower.p[lower.n], lower.p.data(),
                                                                 lower.i.data(), lower.x.data());
  Lambda_ = lower_view.selfadjointView<Eigen::Lower>();
  lambda_full_valid_ = true;
  return Lambda_;
}

void EifJoiner::Impl::FillLambdaValues(size_t first_factor, std::vector<double>* values) const {
  values->assign(solver_.lambda_lower.i.size(), 0.0);
  double* x = values->data();
  size_t entries = 0;
  for (size_t k = 0; k < first_factor; ++k) entries += static_cast<size_t>(factors_[k].H.size());
  const int* slot = lambda_slots_.data() + entries;
  for (size_t k = first_factor; k < factors_.size(); ++k) {
    ForEachEntry(factors_[k], [&](int, int, double h) {
      if (*slot >= 0) x[*slot] += h;
      ++slot;
    });
  }
}

const SparseLowerTriangle& EifJoiner::Impl::LowerInformation() const {
  if (lambda_factors_ == factors_.size() && solver_.lambda_lower.n == dim_) return solver_.lambda_lower;
  lambda_full_valid_ = false;
  if (lambda_factors_ == 0 && solver_.lambda_lower.n == dim_ && !lambda_slots_.empty() &&
      FactorOffsets() == lambda_slot_offsets_) {
    // The same factors over the same variables (relinearised): refill Λ's values.
    FillLambdaValues(0, &solver_.lambda_lower.x);
    lambda_factors_ = factors_.size();
    return solver_.lambda_lower;
  }
  if (lambda_factors_ > 0 && solver_.lambda_lower.n <= dim_) {
    // Joins since the last assembly, the older factors unchanged: the new pattern, the
    // old sums carried over and the new factors' sum added to them (Λ_old + ΔΛ, as
    // assembling ΔΛ on its own and adding it would).
    const SparseLowerTriangle old = std::move(solver_.lambda_lower);
    BuildLambdaPattern();
    std::vector<double> added;
    FillLambdaValues(lambda_factors_, &added);
    std::vector<double>& x = solver_.lambda_lower.x;
    x.assign(solver_.lambda_lower.i.size(), 0.0);
    for (int c = 0; c < old.n; ++c) {  // the old pattern lies within the new one, columns sorted
      int k = solver_.lambda_lower.p[c];
      for (int q = old.p[c]; q < old.p[c + 1]; ++q) {
        while (k < solver_.lambda_lower.p[c + 1] && solver_.lambda_lower.i[k] != old.i[q]) ++k;
        SUBSLAM_CHECK(k < solver_.lambda_lower.p[c + 1]) << "Λ's old pattern is not within the new one, column " << c;
        x[k] = old.x[q];
      }
    }
    for (size_t k = 0; k < x.size(); ++k) x[k] += added[k];
    lambda_factors_ = factors_.size();
    return solver_.lambda_lower;
  }
  // Relinearised factors over a new pattern: Λ's structure is built from the factors'
  // variable blocks, and each H entry's place in Λ's values is recorded for the refill
  // above and the next ones.
  BuildLambdaPattern();
  FillLambdaValues(0, &solver_.lambda_lower.x);
  lambda_factors_ = factors_.size();
  return solver_.lambda_lower;
}

void EifJoiner::Impl::BuildLambdaPattern() const {
  const BlockNeighbours nb = BlockNeighboursOf(factors_, dim_);
  SparseLowerTriangle& lower = solver_.lambda_lower;
  lower.n = dim_;
  lower.p.assign(dim_ + 1, 0);
  for (int o = 0; o < dim_; ++o) {
    for (int j = 0; j < nb.size_of[o]; ++j) lower.p[o + j + 1] = nb.size_of[o] - j + nb.later_rows[o];
  }
  for (int c = 0; c < dim_; ++c) lower.p[c + 1] += lower.p[c];
  const int nonzeros = lower.p[dim_];
  lower.i.resize(static_cast<size_t>(nonzeros));
  for (int o = 0; o < dim_; ++o) {
    for (int j = 0; j < nb.size_of[o]; ++j) {
      int* row = lower.i.data() + lower.p[o + j];
      for (int i = j; i < nb.size_of[o]; ++i) *row++ = o + i;
      for (int k = nb.first[o]; k < nb.first[o] + nb.unique[o]; ++k) {
        if (nb.neighbour[k] <= o) continue;
        for (int i = 0; i < nb.size_of[nb.neighbour[k]]; ++i) *row++ = nb.neighbour[k] + i;
      }
      SUBSLAM_CHECK(row == lower.i.data() + lower.p[o + j + 1]) << "Λ's pattern, column " << o + j;
    }
  }
  // Each H entry's slot in the lower triangle's values, in ForEachEntry's order (block
  // pairs (a, b), rows i outer, columns j inner: entry (a, b, i, j) of a factor sits at
  // start[a]·cols + size_a·start[b] + i·size_b + j, start the blocks' first rows in H);
  // −1 above the diagonal. By column block: with `where` holding, for the blocks after
  // it, their first row's place in its columns, every factor touching the block fills
  // the entries of its column (one pass over the entries, no search).
  std::vector<size_t> entry_start(factors_.size() + 1, 0);
  std::vector<int> touching_count(dim_ + 1, 0);
  for (size_t k = 0; k < factors_.size(); ++k) {
    entry_start[k + 1] = entry_start[k] + static_cast<size_t>(factors_[k].H.size());
    for (int o : factors_[k].offsets) ++touching_count[o + 1];
  }
  for (int o = 0; o < dim_; ++o) touching_count[o + 1] += touching_count[o];
  std::vector<std::pair<int, int>> touching(static_cast<size_t>(touching_count[dim_]));  // (factor, block)
  std::vector<int> touching_fill(touching_count.begin(), touching_count.end() - 1);
  for (size_t k = 0; k < factors_.size(); ++k) {
    for (size_t v = 0; v < factors_[k].offsets.size(); ++v) {
      touching[touching_fill[factors_[k].offsets[v]]++] = {static_cast<int>(k), static_cast<int>(v)};
    }
  }
  lambda_slots_.resize(nb.count);
  std::vector<int> where(dim_, -1), block_start;
  for (int o = 0; o < dim_; ++o) {
    if (nb.size_of[o] == 0) continue;
    const int size_o = nb.size_of[o];
    for (int k = nb.first[o]; k < nb.first[o] + nb.unique[o]; ++k) {
      if (nb.neighbour[k] > o) where[nb.neighbour[k]] = nb.below[k];
    }
    for (int t = touching_count[o]; t < touching_count[o + 1]; ++t) {
      const Factor& f = factors_[touching[t].first];
      const int b = touching[t].second, blocks = static_cast<int>(f.offsets.size());
      const int cols = static_cast<int>(f.H.cols());
      block_start.assign(blocks + 1, 0);
      for (int v = 0; v < blocks; ++v) block_start[v + 1] = block_start[v] + f.sizes[v];
      int* base = lambda_slots_.data() + entry_start[touching[t].first];
      for (int a = 0; a < blocks; ++a) {
        const int size_a = f.sizes[a], row_block = f.offsets[a];
        int* slot = base + block_start[a] * cols + size_a * block_start[b];
        for (int i = 0; i < size_a; ++i) {
          for (int j = 0; j < size_o; ++j) {
            int position = -1;
            if (row_block == o) {
              if (i >= j) position = i - j;
            } else if (row_block > o) {
              position = size_o - j + where[row_block] + i;
            }
            slot[i * size_o + j] = position < 0 ? -1 : lower.p[o + j] + position;
          }
        }
      }
    }
    for (int k = nb.first[o]; k < nb.first[o] + nb.unique[o]; ++k) {
      if (nb.neighbour[k] > o) where[nb.neighbour[k]] = -1;
    }
  }
  lambda_slot_offsets_ = FactorOffsets();
}

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
    return solver_.factor.Factorize(LowerInformation(), /*spare=*/0, options_.ordering);
  }
  // Spare slots for the next joins' new variables (about 15 % of the state).
  // The last anchor, where the next join starts, is ordered last: the next joins' updates
  // then walk short paths (a chain's last anchor elsewhere in the order would fill a
  // column per variable on its path with every update).
  return solver_.factor.Factorize(LowerInformation(), 64 + dim_ / 6, options_.ordering, LastAnchorVariables());
}

absl::Status EifJoiner::Impl::RecoverAcrossNewestFactor(Eigen::Index old_dim) {
  // Carry the estimate over the new factor: Λ'Δx = η' − Λ'x with x the estimate before
  // (the new variables at 0, their spare slots' solution), non-zero on its rows only.
  StageTimer timer(&times_, "recovery");
  Eigen::VectorXd x = StateVector();
  x.tail(dim_ - old_dim).setZero();
  const Factor& f = factors_.back();
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
  SetStateRows(x, moved);
  estimate_exact_ = false;
  if (options_.relinearize_linearization_chi2 > 0 && !changed_all_) {
    drift_.resize(dim_, 0.0);
    for (size_t k = 0; k < moved.size(); ++k) {
      double& drift = drift_[moved[k]];
      drift += std::abs(change[k]);
      if (drift > kLinearizationRecheckDrift) {
        changed_rows_.push_back(moved[k]);
        drift = 0.0;
      }
    }
  }
  return absl::OkStatus();
}

absl::Status EifJoiner::Impl::Rebuild(bool only_last_factor) {
  converged_ = false;
  const Eigen::Index old_dim = eta_.size();
  {
    StageTimer timer(&times_, "update");
    // Λ itself is assembled only when a full factorisation needs it (information()).
    if (only_last_factor) {
      eta_.conservativeResize(dim_);
      eta_.tail(dim_ - old_dim).setZero();
      AddToEta(factors_.back(), &eta_);
      if (factors_of_row_valid_) {
        factors_of_row_.resize(dim_);
        const Factor& f = factors_.back();
        for (size_t v = 0; v < f.offsets.size(); ++v) {
          for (int i = 0; i < f.sizes[v]; ++i)
            factors_of_row_[f.offsets[v] + i].push_back(static_cast<int>(factors_.size()) - 1);
        }
      }
    } else {
      // Every factor may have been relinearised: Λ need not have grown, so the marginal
      // bounds are forgotten.
      marginal_bound_.assign(graph_.num_landmarks(), Eigen::Matrix2d::Constant(NAN));
      relative_bounds_.Clear();
      eta_ = Eigen::VectorXd::Zero(dim_);
      for (const Factor& f : factors_) AddToEta(f, &eta_);
      lambda_factors_ = 0;
      factors_of_row_valid_ = false;
      owner_of_row_valid_ = false;
    }
  }
  bool incremental = false;
  {
    StageTimer timer(&times_, "factorization");
    SparseCholesky& L = solver_.factor;
    // The newest factor as a rank update of the existing factor, while there are spare
    // slots and the fill has not doubled since the last ordering.
    if (only_last_factor && options_.incremental_factorization && L.ready() && !solver_.stale && dim_ <= L.capacity() &&
        L.nonzeros() <= options_.refactorize_fill_ratio * static_cast<double>(L.nonzeros_after_factorize())) {
      const Factor& f = factors_.back();
      std::vector<int> rows;
      for (size_t v = 0; v < f.offsets.size(); ++v) {
        for (int i = 0; i < f.sizes[v]; ++i) rows.push_back(f.offsets[v] + i);
      }
      incremental = L.Update(dim_, rows, solver_.last_whitened_jacobian.transpose()).ok();
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
      Eigen::VectorXd Lambda_x = Eigen::VectorXd::Zero(dim_);
      for (const Factor& f : factors_) AddInformationTimes(f, x, &Lambda_x);
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
  SetState(x);
  estimate_exact_ = true;
  // Every variable may have moved (and the layout may have changed): the trigger tests
  // every factor next time.
  changed_all_ = true;
  changed_rows_.clear();
  drift_.assign(dim_, 0.0);
  return absl::OkStatus();
}

void EifJoiner::Impl::MarkLinearizationTested() {
  changed_rows_.clear();
  if (changed_all_) drift_.assign(dim_, 0.0);
  changed_all_ = false;
}

std::vector<int> EifJoiner::Impl::LastAnchorVariables() const {
  if (graph_.num_anchors() < 2) return {};
  const int offset = anchor_offset_[graph_.num_anchors() - 1];
  return {offset, offset + 1, offset + 2};
}

void EifJoiner::Impl::EnsureFactorsOfRow() const {
  if (factors_of_row_valid_) return;
  factors_of_row_.assign(dim_, {});
  for (size_t k = 0; k < factors_.size(); ++k) {
    const Factor& f = factors_[k];
    for (size_t v = 0; v < f.offsets.size(); ++v) {
      for (int i = 0; i < f.sizes[v]; ++i) factors_of_row_[f.offsets[v] + i].push_back(static_cast<int>(k));
    }
  }
  factors_of_row_valid_ = true;
}

}  // namespace subslam::backend
