// SparseCholesky: blocks of the inverse of the factored matrix — by columns, on the
// factor's pattern (the sparse-inverse recursion, every block the pattern holds at once),
// and the diagonal blocks of groups of variables.

#include <cholmod.h>

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <mutex>
#include <numeric>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "subslam/backend/internal/sparse_cholesky.h"
#include "subslam/core/check.h"

namespace subslam::backend {

Eigen::MatrixXd SparseCholesky::InverseBlock(const std::vector<int>& variables) const {
  const int k = static_cast<int>(variables.size());
  Eigen::MatrixXd out(k, k);
  SolveColumns(variables);
  std::vector<const SparseColumn*> Y;
  Y.reserve(k);
  for (int v : variables) Y.push_back(&ForwardColumn(v));
  if (k >= kDenseBlockMinColumns) {
    // Many columns (association's joint covariance): their paths share the rows near the
    // root, so the columns are laid side by side over the union of their rows and
    // (A⁻¹)_SS = YᵀY is one dense product instead of k² / 2 sparse dot products.
    std::vector<int>& index = path_index_;  // position → row of the dense Y (−1: none)
    if (static_cast<int>(index.size()) != capacity_) index.assign(capacity_, -1);
    std::vector<int> rows;
    for (const SparseColumn* y : Y) {
      for (int r : y->rows) {
        if (index[r] < 0) {
          index[r] = static_cast<int>(rows.size());
          rows.push_back(r);
        }
      }
    }
    Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()), k);
    for (int c = 0; c < k; ++c) {
      for (size_t t = 0; t < Y[c]->rows.size(); ++t) dense(index[Y[c]->rows[t]], c) = Y[c]->values[t];
    }
    for (int r : rows) index[r] = -1;
    out.noalias() = dense.transpose() * dense;
    return out;
  }
  for (int a = 0; a < k; ++a) {
    Dots(*Y[a], Y, a, out.col(a).data());  // the lower triangle, column by column
    for (int c = a + 1; c < k; ++c) out(a, c) = out(c, a);
  }
  return out;
}

Eigen::MatrixXd SparseCholesky::CrossBlock(const std::vector<int>& left, const std::vector<int>& right) const {
  std::vector<int> all = left;
  all.insert(all.end(), right.begin(), right.end());
  SolveColumns(all);
  std::vector<const SparseColumn*> R;
  R.reserve(right.size());
  for (int v : right) R.push_back(&ForwardColumn(v));
  Eigen::MatrixXd out(right.size(), left.size());  // filled by columns: one scatter of each left column
  for (size_t a = 0; a < left.size(); ++a)
    Dots(ForwardColumn(left[a]), R, 0, out.col(static_cast<Eigen::Index>(a)).data());
  return out.transpose();
}

std::vector<Eigen::MatrixXd> SparseCholesky::InverseStarBlocks(const std::vector<int>& hub,
                                                               const std::vector<std::vector<int>>& groups) const {
  std::vector<int> all = hub;
  for (const std::vector<int>& group : groups) all.insert(all.end(), group.begin(), group.end());
  SolveColumns(all);
  std::vector<const SparseColumn*> H;
  for (int v : hub) H.push_back(&ForwardColumn(v));
  const int h = static_cast<int>(hub.size());
  Eigen::MatrixXd hub_block(h, h);
  for (int a = 0; a < h; ++a) {
    Dots(*H[a], H, a, hub_block.col(a).data());
    for (int c = a + 1; c < h; ++c) hub_block(a, c) = hub_block(c, a);
  }
  // Every group's columns against the hub: each hub column scattered once for all of them.
  std::vector<const SparseColumn*> grouped;
  for (const std::vector<int>& group : groups) {
    for (int v : group) grouped.push_back(&ForwardColumn(v));
  }
  Eigen::MatrixXd hub_dots(grouped.size(), h);  // row: a grouped column, column: a hub one
  for (int a = 0; a < h; ++a) Dots(*H[a], grouped, 0, hub_dots.col(a).data());
  std::vector<Eigen::MatrixXd> out;
  out.reserve(groups.size());
  int first = 0;  // the group's first row in hub_dots
  for (const std::vector<int>& group : groups) {
    const int g = static_cast<int>(group.size());
    const std::vector<const SparseColumn*> G(grouped.begin() + first, grouped.begin() + first + g);
    Eigen::MatrixXd m(h + g, h + g);
    m.topLeftCorner(h, h) = hub_block;
    m.bottomLeftCorner(g, h) = hub_dots.middleRows(first, g);
    m.topRightCorner(h, g) = m.bottomLeftCorner(g, h).transpose();
    first += g;
    for (int a = 0; a < g; ++a) {
      Dots(*G[a], G, a, m.col(h + a).data() + h);  // the lower triangle, column by column
      for (int c = a + 1; c < g; ++c) m(h + a, h + c) = m(h + c, h + a);
    }
    out.push_back(std::move(m));
  }
  return out;
}

void SparseCholesky::InvalidateCaches(int capacity, bool keep_parents) {
  column_cache_.clear();
  selected_.reset();
  if (!keep_parents || static_cast<int>(parent_.size()) != capacity) parent_.assign(capacity, -2);
}

bool SparseCholesky::RefreshParentsFrom(const std::vector<int>& positions) {
  // The columns an update changed are those on the paths, in the updated tree, from its
  // rows to the root: recompute each one's parent on the way up, and check its pivot.
  const double* Lx = static_cast<const double*>(factor_->x);
  const int* Lp = static_cast<const int*>(factor_->p);
  std::vector<int>& stamp = back_stamp_;
  if (static_cast<int>(stamp.size()) != capacity_) stamp.assign(capacity_, 0);
  const int this_walk = ++back_walks_;
  bool positive = true;
  for (int start : positions) {
    for (int j = start; j >= 0 && stamp[j] != this_walk;) {
      stamp[j] = this_walk;
      positive = positive && Lx[Lp[j]] > 0.0;  // D_jj sits first in column j
      parent_[j] = -2;
      j = Parent(j);
    }
  }
  return positive;
}

void SparseCholesky::SolveChange(const std::vector<int>& rows, const Eigen::VectorXd& r_local, double threshold,
                                 Eigen::VectorXd* x, std::vector<int>* changed,
                                 std::vector<double>* change_sizes) const {
  const double* Lx = static_cast<const double*>(factor_->x);
  const int* Lp = static_cast<const int*>(factor_->p);
  const int* Li = static_cast<const int*>(factor_->i);
  const int* Lnz = static_cast<const int*>(factor_->nz);
  const int* perm = static_cast<const int*>(factor_->Perm);
  std::vector<double>& d = change_workspace_;
  if (static_cast<int>(d.size()) != capacity_) d.assign(capacity_, 0.0);
  std::vector<char>& live = change_live_;
  if (static_cast<int>(live.size()) != capacity_) live.assign(capacity_, 0);
  std::vector<int>& stamp = back_stamp_;
  if (static_cast<int>(stamp.size()) != capacity_) stamp.assign(capacity_, 0);
  const int this_walk = ++back_walks_;
  // U: the union of the paths from the rows to the root, ascending.
  std::vector<int> U;
  for (size_t k = 0; k < rows.size(); ++k) {
    SUBSLAM_CHECK(rows[k] >= 0 && rows[k] < dim_) << "variable " << rows[k] << " out of range";
    d[position_[rows[k]]] += r_local[static_cast<Eigen::Index>(k)];
    for (int j = position_[rows[k]]; j >= 0 && stamp[j] != this_walk; j = Parent(j)) {
      stamp[j] = this_walk;
      U.push_back(j);
    }
  }
  std::sort(U.begin(), U.end());
  // Forward: y = L⁻¹ P r over U (column j's rows are ancestors of j, so in U), then D⁻¹.
  for (int j : U) {
    const double yj = d[j];
    for (int p = Lp[j] + 1; p < Lp[j] + Lnz[j]; ++p) d[Li[p]] -= Lx[p] * yj;
  }
  for (int j : U) d[j] /= Lx[Lp[j]];
  // Back: Lᵀ Δx = D⁻¹ y from the roots down; Δx_j = z_j − Σ_{i∈L_j} L_ij Δx_i. Off the
  // paths a column is solved when a row of it changed by more than the threshold ("live").
  // Its rows lie in its parent's column and the parent itself (L_c ⊆ {p} ∪ L_p), so a
  // column whose parent neither is live nor has a live row ("touched") has none either,
  // and its whole subtree is passed over.
  std::vector<char>& touched = change_touched_;
  if (static_cast<int>(touched.size()) != capacity_) touched.assign(capacity_, 0);
  std::vector<int> entered;
  for (int j = capacity_ - 1; j >= 0; --j) {
    const bool on_path = stamp[j] == this_walk;
    if (!on_path) {
      const int parent = Parent(j);
      if (parent < 0 || !touched[parent]) continue;
    }
    bool live_row = false;
    double dj = on_path ? d[j] : 0.0;
    for (int p = Lp[j] + 1; p < Lp[j] + Lnz[j]; ++p) {
      live_row = live_row || live[Li[p]];
      dj -= Lx[p] * d[Li[p]];
    }
    entered.push_back(j);
    if (!on_path && !live_row) continue;  // only changes below the threshold reach it
    d[j] = dj;
    live[j] = std::abs(dj) > threshold;
    touched[j] = live[j] || live_row;
  }
  for (int j : entered) {
    const int v = perm[j];
    if (d[j] != 0.0 && v < dim_) {
      (*x)[v] += d[j];
      changed->push_back(v);
      if (change_sizes != nullptr) change_sizes->push_back(d[j]);
    }
  }
  for (int j : entered) {
    d[j] = 0.0;
    live[j] = 0;
    touched[j] = 0;
  }
  for (int j : U) d[j] = 0.0;
}

int SparseCholesky::Parent(int j) const {
  int& parent = parent_[j];
  if (parent == -2) {
    const int* Lp = static_cast<const int*>(factor_->p);
    const int* Li = static_cast<const int*>(factor_->i);
    const int* Lnz = static_cast<const int*>(factor_->nz);
    parent = -1;
    for (int p = Lp[j] + 1; p < Lp[j] + Lnz[j]; ++p) parent = parent < 0 ? Li[p] : std::min(parent, Li[p]);
  }
  return parent;
}

Eigen::MatrixXd SparseCholesky::InverseColumnsAt(const std::vector<int>& columns, const std::vector<int>& rows) const {
  const int k = static_cast<int>(columns.size());
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()), k);
  if (k == 0 || rows.empty()) return out;
  const double* Lx = static_cast<const double*>(factor_->x);
  const int* Lp = static_cast<const int*>(factor_->p);
  const int* Li = static_cast<const int*>(factor_->i);
  const int* Lnz = static_cast<const int*>(factor_->nz);
  for (int v : columns) SUBSLAM_CHECK(v >= 0 && v < dim_) << "variable " << v << " out of range";
  for (int v : rows) SUBSLAM_CHECK(v >= 0 && v < dim_) << "variable " << v << " out of range";
  // U: the union of the paths from the requested rows to the root (each column's rows
  // are its ancestors, the parent the smallest), in factor positions.
  std::vector<int>& stamp = back_stamp_;
  if (static_cast<int>(stamp.size()) != capacity_) stamp.assign(capacity_, 0);
  const int this_walk = ++back_walks_;
  std::vector<int> U;
  for (int v : rows) {
    for (int j = position_[v]; j >= 0 && stamp[j] != this_walk; j = Parent(j)) {
      stamp[j] = this_walk;
      U.push_back(j);
    }
  }
  std::sort(U.begin(), U.end());
  // z = D⁻¹ L⁻¹ P e_c from the cached forward columns (they hold y / √D), then
  // Lᵀ x = z from the root down, over U only: x_j = z_j − Σ_{i∈L_j} L_ij x_i, where every
  // i is an ancestor of j, so in U. (The columns are solved before the workspace is used.)
  SolveColumns(columns);
  std::vector<const SparseColumn*> Y;
  for (int v : columns) Y.push_back(&ForwardColumn(v));
  std::vector<double>& x = ForwardWorkspace();  // capacity × kMaxCarried, all zero between uses
  for (int c0 = 0; c0 < k; c0 += kMaxCarried) {
    const int width = std::min(kMaxCarried, k - c0);
    for (int c = 0; c < width; ++c) {
      const SparseColumn& y = *Y[c0 + c];
      for (size_t t = 0; t < y.rows.size(); ++t) {
        const int r = y.rows[t];
        if (stamp[r] == this_walk) x[static_cast<size_t>(r) * kMaxCarried + c] = y.values[t] / std::sqrt(Lx[Lp[r]]);
      }
    }
    for (auto it = U.rbegin(); it != U.rend(); ++it) {
      const int j = *it;
      double* xj = &x[static_cast<size_t>(j) * kMaxCarried];
      for (int p = Lp[j] + 1; p < Lp[j] + Lnz[j]; ++p) {
        const double* xi = &x[static_cast<size_t>(Li[p]) * kMaxCarried];
        for (int c = 0; c < width; ++c) xj[c] -= Lx[p] * xi[c];
      }
    }
    for (size_t r = 0; r < rows.size(); ++r) {
      for (int c = 0; c < width; ++c)
        out(static_cast<Eigen::Index>(r), c0 + c) = x[static_cast<size_t>(position_[rows[r]]) * kMaxCarried + c];
    }
    for (int j : U) std::fill_n(&x[static_cast<size_t>(j) * kMaxCarried], kMaxCarried, 0.0);
  }
  return out;
}

const SparseCholesky::SelectedInverse& SparseCholesky::Selected() const {
  if (selected_.has_value()) return *selected_;
  const double* Lx = static_cast<const double*>(factor_->x);
  const int* Lp = static_cast<const int*>(factor_->p);
  const int* Li = static_cast<const int*>(factor_->i);
  const int* Lnz = static_cast<const int*>(factor_->nz);
  const int n = capacity_;
  SelectedInverse sel;
  sel.start.assign(n + 1, 0);
  for (int j = 0; j < n; ++j) sel.start[j + 1] = sel.start[j] + Lnz[j] - 1;  // D sits first
  const int nnz = sel.start[n];
  sel.rows.resize(nnz);
  sel.lower.resize(nnz);
  sel.z.assign(nnz, 0.0);
  sel.diagonal.assign(n, 0.0);
  // Column j's rows sorted, with their values. (Every factor seen so far, also after
  // updates added fill, had its columns' rows in order; the lookups below need them so,
  // and the order is not something this code relies on CHOLMOD for.)
  std::vector<std::pair<int, double>> column;
  for (int j = 0; j < n; ++j) {
    column.clear();
    for (int p = Lp[j] + 1; p < Lp[j] + Lnz[j]; ++p) column.emplace_back(Li[p], Lx[p]);
    if (!std::is_sorted(column.begin(), column.end())) std::sort(column.begin(), column.end());
    for (size_t t = 0; t < column.size(); ++t) {
      sel.rows[sel.start[j] + t] = column[t].first;
      sel.lower[sel.start[j] + t] = column[t].second;
    }
  }
  // From the last column to the first: column j's Z needs Z on its rows' pairs only,
  // which lie in later columns (the rows of column j below row r are rows of column r:
  // the factor's pattern is closed along the elimination tree).
  std::vector<double> acc;
  for (int j = n - 1; j >= 0; --j) {
    const int begin = sel.start[j], m = sel.start[j + 1] - begin;
    const int* R = sel.rows.data() + begin;
    const double* l = sel.lower.data() + begin;
    acc.assign(m, 0.0);  // acc[a] = Σ_b L_{R[b] j} Z_{R[a] R[b]}
    for (int b = 0; b < m; ++b) {
      const int rb = R[b];
      acc[b] += l[b] * sel.diagonal[rb];
      const int* col = sel.rows.data() + sel.start[rb];
      const int* end = sel.rows.data() + sel.start[rb + 1];
      const int* at = col;
      for (int c = b + 1; c < m; ++c) {
        if (at >= end || *at != R[c]) at = std::lower_bound(at, end, R[c]);
        SUBSLAM_CHECK(at < end && *at == R[c]) << "factor pattern is not closed along its elimination tree";
        const double z = sel.z[at - sel.rows.data()];  // Z_{R[c] R[b]}
        acc[c] += l[b] * z;
        acc[b] += l[c] * z;
        ++at;
      }
    }
    double diagonal = 1.0 / Lx[Lp[j]];
    for (int a = 0; a < m; ++a) {
      sel.z[begin + a] = -acc[a];
      diagonal += l[a] * acc[a];
    }
    sel.diagonal[j] = diagonal;
  }
  selected_ = std::move(sel);
  return *selected_;
}

std::optional<double> SparseCholesky::SelectedEntry(int a, int b) const {
  const SelectedInverse& sel = *selected_;
  if (a == b) return sel.diagonal[a];
  if (a > b) std::swap(a, b);
  const int* begin = sel.rows.data() + sel.start[a];
  const int* end = sel.rows.data() + sel.start[a + 1];
  const int* at = std::lower_bound(begin, end, b);
  if (at == end || *at != b) return std::nullopt;
  return sel.z[at - sel.rows.data()];
}

std::vector<Eigen::MatrixXd> SparseCholesky::DiagonalInverseBlocks(const std::vector<std::vector<int>>& groups) const {
  std::vector<Eigen::MatrixXd> out;
  out.reserve(groups.size());
  if (groups.empty()) return out;
  for (const std::vector<int>& group : groups) {
    for (int v : group) SUBSLAM_CHECK(v >= 0 && v < dim_) << "variable " << v << " out of range";
  }
  Selected();
  for (const std::vector<int>& group : groups) {
    const int k = static_cast<int>(group.size());
    Eigen::MatrixXd block(k, k);
    bool on_pattern = true;
    for (int a = 0; a < k && on_pattern; ++a) {
      for (int c = a; c < k; ++c) {
        const std::optional<double> z = SelectedEntry(position_[group[a]], position_[group[c]]);
        if (!z.has_value()) {
          on_pattern = false;
          break;
        }
        block(a, c) = block(c, a) = *z;
      }
    }
    out.push_back(on_pattern ? std::move(block) : InverseBlock(group));
  }
  return out;
}

}  // namespace subslam::backend
