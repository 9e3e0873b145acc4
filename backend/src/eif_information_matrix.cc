// EifInformationMatrix: Λ assembled from the factors — its pattern, values and lower
// triangle.

#include "eif_information_matrix.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "state_blocks.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/internal/sparse_cholesky.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/core/check.h"
#include "subslam/core/stage_timer.h"
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

const Eigen::SparseMatrix<double>& EifInformationMatrix::Full(const std::vector<EifFactor>& factors, int dim) {
  const SparseLowerTriangle& lower = Lower(factors, dim);
  if (full_valid_ && full_.rows() == dim) return full_;
  // Both triangles from the lower one.
  const Eigen::Map<const Eigen::SparseMatrix<double>> lower_view(lower.n, lower.n, lower.p[lower.n], lower.p.data(),
                                                                 lower.i.data(), lower.x.data());
  full_ = lower_view.selfadjointView<Eigen::Lower>();
  full_valid_ = true;
  return full_;
}

void EifInformationMatrix::FillValues(const std::vector<EifFactor>& factors, size_t first_factor,
                                      std::vector<double>* values) const {
  values->assign(lower_.i.size(), 0.0);
  double* x = values->data();
  size_t entries = 0;
  for (size_t k = 0; k < first_factor; ++k) entries += static_cast<size_t>(factors[k].H.size());
  const int* slot = slots_.data() + entries;
  for (size_t k = first_factor; k < factors.size(); ++k) {
    factors[k].ForEachEntry([&](int, int, double h) {
      if (*slot >= 0) x[*slot] += h;
      ++slot;
    });
  }
}

const SparseLowerTriangle& EifInformationMatrix::Lower(const std::vector<EifFactor>& factors, int dim) {
  if (factors_summed_ == factors.size() && lower_.n == dim) return lower_;
  full_valid_ = false;
  if (factors_summed_ == 0 && lower_.n == dim && !slots_.empty() && FactorOffsets(factors) == slot_offsets_) {
    // The same factors over the same variables (relinearised): refill Λ's values.
    FillValues(factors, 0, &lower_.x);
    factors_summed_ = factors.size();
    return lower_;
  }
  if (factors_summed_ > 0 && lower_.n <= dim) {
    // Joins since the last assembly, the older factors unchanged: the new pattern, the
    // old sums carried over and the new factors' sum added to them (Λ_old + ΔΛ, as
    // assembling ΔΛ on its own and adding it would).
    const SparseLowerTriangle old = std::move(lower_);
    BuildPattern(factors, dim);
    std::vector<double> added;
    FillValues(factors, factors_summed_, &added);
    std::vector<double>& x = lower_.x;
    x.assign(lower_.i.size(), 0.0);
    for (int c = 0; c < old.n; ++c) {  // the old pattern lies within the new one, columns sorted
      int k = lower_.p[c];
      for (int q = old.p[c]; q < old.p[c + 1]; ++q) {
        while (k < lower_.p[c + 1] && lower_.i[k] != old.i[q]) ++k;
        SUBSLAM_CHECK(k < lower_.p[c + 1]) << "Λ's old pattern is not within the new one, column " << c;
        x[k] = old.x[q];
      }
    }
    for (size_t k = 0; k < x.size(); ++k) x[k] += added[k];
    factors_summed_ = factors.size();
    return lower_;
  }
  // Relinearised factors over a new pattern: Λ's structure is built from the factors'
  // variable blocks, and each H entry's place in Λ's values is recorded for the refill
  // above and the next ones.
  BuildPattern(factors, dim);
  FillValues(factors, 0, &lower_.x);
  factors_summed_ = factors.size();
  return lower_;
}

void EifInformationMatrix::BuildPattern(const std::vector<EifFactor>& factors, int dim) {
  const BlockNeighbours nb = BlockNeighboursOf(factors, dim);
  SparseLowerTriangle& lower = lower_;
  lower.n = dim;
  lower.p.assign(dim + 1, 0);
  for (int o = 0; o < dim; ++o) {
    for (int j = 0; j < nb.size_of[o]; ++j) lower.p[o + j + 1] = nb.size_of[o] - j + nb.later_rows[o];
  }
  for (int c = 0; c < dim; ++c) lower.p[c + 1] += lower.p[c];
  const int nonzeros = lower.p[dim];
  lower.i.resize(static_cast<size_t>(nonzeros));
  for (int o = 0; o < dim; ++o) {
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
  std::vector<size_t> entry_start(factors.size() + 1, 0);
  std::vector<int> touching_count(dim + 1, 0);
  for (size_t k = 0; k < factors.size(); ++k) {
    entry_start[k + 1] = entry_start[k] + static_cast<size_t>(factors[k].H.size());
    for (int o : factors[k].offsets) ++touching_count[o + 1];
  }
  for (int o = 0; o < dim; ++o) touching_count[o + 1] += touching_count[o];
  std::vector<std::pair<int, int>> touching(static_cast<size_t>(touching_count[dim]));  // (factor, block)
  std::vector<int> touching_fill(touching_count.begin(), touching_count.end() - 1);
  for (size_t k = 0; k < factors.size(); ++k) {
    for (size_t v = 0; v < factors[k].offsets.size(); ++v) {
      touching[touching_fill[factors[k].offsets[v]]++] = {static_cast<int>(k), static_cast<int>(v)};
    }
  }
  slots_.resize(nb.count);
  std::vector<int> where(dim, -1), block_start;
  for (int o = 0; o < dim; ++o) {
    if (nb.size_of[o] == 0) continue;
    const int size_o = nb.size_of[o];
    for (int k = nb.first[o]; k < nb.first[o] + nb.unique[o]; ++k) {
      if (nb.neighbour[k] > o) where[nb.neighbour[k]] = nb.below[k];
    }
    for (int t = touching_count[o]; t < touching_count[o + 1]; ++t) {
      const EifFactor& f = factors[touching[t].first];
      const int b = touching[t].second, blocks = static_cast<int>(f.offsets.size());
      const int cols = static_cast<int>(f.H.cols());
      block_start.assign(blocks + 1, 0);
      for (int v = 0; v < blocks; ++v) block_start[v + 1] = block_start[v] + f.sizes[v];
      int* base = slots_.data() + entry_start[touching[t].first];
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
  slot_offsets_ = FactorOffsets(factors);
}

std::vector<int> EifInformationMatrix::FactorOffsets(const std::vector<EifFactor>& factors) {
  std::vector<int> offsets;
  for (const EifFactor& f : factors) {
    offsets.push_back(static_cast<int>(f.offsets.size()));
    offsets.insert(offsets.end(), f.offsets.begin(), f.offsets.end());
  }
  return offsets;
}

void EifInformationMatrix::Forget() {
  factors_summed_ = 0;
  full_valid_ = false;
}

}  // namespace subslam::backend
