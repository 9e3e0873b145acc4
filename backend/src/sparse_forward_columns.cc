// SparseCholesky: the forward columns Y = L⁻¹ P E_S of covariance recovery, each solved
// along its elimination-tree path (many at once where their paths merge) and cached
// until the factor changes, and the dot products that make blocks of the inverse of them.

#include <cholmod.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "subslam/backend/internal/sparse_cholesky.h"
#include "subslam/core/check.h"

namespace subslam::backend {

const SparseCholesky::SparseColumn& SparseCholesky::ForwardColumn(int variable) const {
  SolveColumns({variable});
  return column_cache_.at(variable);
}

void SparseCholesky::SolveColumns(const std::vector<int>& variables) const {
  // Columns asked again within one join (the start anchor, then the compatible
  // candidates) are cached until the factor changes.
  std::vector<int> pending;
  for (int v : variables) {
    if (column_cache_.count(v) == 0) pending.push_back(v);
  }
  std::sort(pending.begin(), pending.end(), [this](int a, int b) { return position_[a] < position_[b]; });
  pending.erase(std::unique(pending.begin(), pending.end()), pending.end());
  if (static_cast<int>(pending.size()) >= kSharedPathMinColumns && SolveThroughSharedPath(pending)) return;
  // y = L⁻¹ P e_v. The right-hand side has one non-zero, at k = P(v), so y's non-zeros are
  // the elimination-tree path from k to the root (the rows of column j of L are ancestors
  // of j; the parent is the smallest): a column-oriented forward solve walks that path,
  // O(Σ nnz(L_j)) over it, with L's unit diagonal (D sits there). A variable coupled to
  // another in A (a landmark's x and y, an anchor's x, y and θ) lies on its path, so one
  // walk carries both right-hand sides, each from its own start: one pass over L.
  const double* Lx = static_cast<const double*>(factor_->x);
  const int* Lp = static_cast<const int*>(factor_->p);
  const int* Li = static_cast<const int*>(factor_->i);
  const int* Lnz = static_cast<const int*>(factor_->nz);
  std::vector<double>& y = ForwardWorkspace();  // row-major capacity × kMaxCarried
  // Every row a walk writes must be on its path, or y would keep a non-zero: checked by
  // stamping written rows and counting the ones the path then visits.
  std::vector<int>& stamp = forward_stamp_;
  if (static_cast<int>(stamp.size()) != capacity_) stamp.assign(capacity_, 0);
  while (!pending.empty()) {
    const int this_walk = ++walks_;
    std::vector<int> carried, left_over;
    std::vector<SparseColumn> columns;
    size_t next = 0;  // into pending, by position
    int written = 0, visited = 0;
    for (int j = position_[pending[0]]; j >= 0;) {
      // Variables the path has passed without visiting wait for a walk of their own.
      while (next < pending.size() && position_[pending[next]] < j) left_over.push_back(pending[next++]);
      if (next < pending.size() && position_[pending[next]] == j && carried.size() < kMaxCarried) {
        y[static_cast<size_t>(j) * kMaxCarried + carried.size()] = 1.0;
        if (stamp[j] != this_walk) {
          stamp[j] = this_walk;
          ++written;
        }
        carried.push_back(pending[next++]);
        columns.emplace_back();
      }
      ++visited;
      const int n_carried = static_cast<int>(carried.size());
      double y_j[kMaxCarried];
      const double inv_sqrt_d = 1.0 / std::sqrt(Lx[Lp[j]]);
      for (int r = 0; r < n_carried; ++r) {
        double& slot = y[static_cast<size_t>(j) * kMaxCarried + r];
        y_j[r] = slot;
        slot = 0.0;
        columns[r].rows.push_back(j);
        columns[r].values.push_back(y_j[r] * inv_sqrt_d);
      }
      int parent = -1;
      for (int p = Lp[j] + 1; p < Lp[j] + Lnz[j]; ++p) {
        const int row = Li[p];
        double* target = &y[static_cast<size_t>(row) * kMaxCarried];
        for (int r = 0; r < n_carried; ++r) target[r] -= Lx[p] * y_j[r];
        if (stamp[row] != this_walk) {
          stamp[row] = this_walk;
          ++written;
        }
        if (parent < 0 || row < parent) parent = row;
      }
      j = parent;
    }
    SUBSLAM_CHECK(written == visited) << "factor pattern is not closed along its elimination tree";
    while (next < pending.size()) left_over.push_back(pending[next++]);
    for (size_t r = 0; r < carried.size(); ++r) {
      ++columns_solved_;
      reach_solved_ += static_cast<long>(columns[r].rows.size());
      column_cache_.emplace(carried[r], std::move(columns[r]));
    }
    pending.swap(left_over);
  }
}

bool SparseCholesky::SolveThroughSharedPath(const std::vector<int>& pending) const {
  const double* Lx = static_cast<const double*>(factor_->x);
  const int* Lp = static_cast<const int*>(factor_->p);
  const int* Li = static_cast<const int*>(factor_->i);
  const int* Lnz = static_cast<const int*>(factor_->nz);
  // S: the elimination-tree path from the lowest pending variable to the root. Every
  // other path meets it (one root), and from there on the walks would all run through
  // the same — near the root dense — columns: those are solved together.
  std::vector<int> path;
  for (int j = position_[pending[0]]; j >= 0; j = Parent(j)) {
    path.push_back(j);
    if (static_cast<int>(path.size()) > kSharedPathMaxLength) return false;  // too many rows for B
  }
  const int s = static_cast<int>(path.size());
  if (s < kSharedPathMinLength) return false;  // short paths: the walks are cheap
  std::vector<int>& index = path_index_;       // position → index in S (−1: not in S)
  if (static_cast<int>(index.size()) != capacity_) index.assign(capacity_, -1);
  for (int q = 0; q < s; ++q) index[path[q]] = q;
  // Each variable's walk up to S (sparse), its values at S gathered into B.
  const int R = static_cast<int>(pending.size());
  // Row-major: the shared solve below updates whole rows (all right-hand sides at once).
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> B =
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>::Zero(s, R);
  std::vector<SparseColumn> columns(R);
  std::vector<int> entry(R);                    // index in S where the walk met S
  std::vector<double>& y = ForwardWorkspace();  // its first capacity entries, one right-hand side
  std::vector<int>& stamp = forward_stamp_;
  if (static_cast<int>(stamp.size()) != capacity_) stamp.assign(capacity_, 0);
  for (int r = 0; r < R; ++r) {
    const int this_walk = ++walks_;
    int written = 0, visited = 0;
    std::vector<int> written_in_s;
    int j = position_[pending[r]];
    y[j] = 1.0;
    if (index[j] < 0) {
      stamp[j] = this_walk;
      ++written;
    } else {
      written_in_s.push_back(j);
    }
    bool met = index[j] >= 0;
    while (!met) {
      const double y_j = y[j];
      y[j] = 0.0;
      ++visited;
      columns[r].rows.push_back(j);
      columns[r].values.push_back(y_j / std::sqrt(Lx[Lp[j]]));
      int up = -1;
      for (int p = Lp[j] + 1; p < Lp[j] + Lnz[j]; ++p) {
        const int row = Li[p];
        y[row] -= Lx[p] * y_j;
        if (stamp[row] != this_walk) {
          stamp[row] = this_walk;
          if (index[row] < 0) {
            ++written;
          } else {
            written_in_s.push_back(row);
          }
        }
        up = up < 0 ? row : std::min(up, row);
      }
      if (up < 0) break;  // a root outside S (another component): the column is complete
      j = up;
      met = index[j] >= 0;
    }
    SUBSLAM_CHECK(written == visited) << "factor pattern is not closed along its elimination tree";
    entry[r] = met ? index[j] : s;
    for (int row : written_in_s) {
      B(index[row], r) = y[row];
      y[row] = 0.0;
    }
  }
  // The shared part for every variable at once: L_SS Z = B (unit lower), in place (B
  // becomes Z), by columns of S — the rows of a column of S are its ancestors, all in
  // S — so the work is O(nnz(L_SS) · R), with no dense s × s matrix.
  double* b = B.data();
  for (int q = 0; q < s; ++q) {
    const int j = path[q];
    const double* b_q = b + static_cast<size_t>(q) * R;
    for (int p = Lp[j] + 1; p < Lp[j] + Lnz[j]; ++p) {
      const int row = index[Li[p]];
      SUBSLAM_CHECK(row > q) << "factor pattern is not closed along its elimination tree";
      double* b_row = b + static_cast<size_t>(row) * R;
      const double l = Lx[p];
      for (int r = 0; r < R; ++r) b_row[r] -= l * b_q[r];
    }
  }
  for (int r = 0; r < R; ++r) {
    for (int q = entry[r]; q < s; ++q) {
      columns[r].rows.push_back(path[q]);
      columns[r].values.push_back(B(q, r) / std::sqrt(Lx[Lp[path[q]]]));
    }
    ++columns_solved_;
    reach_solved_ += static_cast<long>(columns[r].rows.size());
    column_cache_.emplace(pending[r], std::move(columns[r]));
  }
  for (int q = 0; q < s; ++q) index[path[q]] = -1;
  return true;
}

std::vector<double>& SparseCholesky::ForwardWorkspace() const {
  const size_t size = static_cast<size_t>(capacity_) * kMaxCarried;
  if (forward_workspace_.size() != size) forward_workspace_.assign(size, 0.0);
  return forward_workspace_;
}

void SparseCholesky::Dots(const SparseColumn& a, const std::vector<const SparseColumn*>& others, int begin,
                          double* out) const {
  std::vector<double>& scatter = scatter_;
  if (static_cast<int>(scatter.size()) != capacity_) scatter.assign(capacity_, 0.0);
  for (size_t t = 0; t < a.rows.size(); ++t) scatter[a.rows[t]] = a.values[t];
  for (size_t o = begin; o < others.size(); ++o) {
    const SparseColumn& b = *others[o];
    double dot = 0.0;
    for (size_t t = 0; t < b.rows.size(); ++t) dot += scatter[b.rows[t]] * b.values[t];
    out[o] = dot;
  }
  for (int r : a.rows) scatter[r] = 0.0;
}

}  // namespace subslam::backend
