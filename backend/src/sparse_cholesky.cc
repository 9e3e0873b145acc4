#include "subslam/backend/internal/sparse_cholesky.h"

#include <cholmod.h>

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <mutex>
#include <numeric>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "subslam/core/check.h"
#include "subslam/core/enum_names.h"

namespace subslam::backend {

namespace {
constexpr EnumName<FillReducingOrdering> kOrderingNames[] = {
    {FillReducingOrdering::kAmd, "amd"},
    {FillReducingOrdering::kNestedDissection, "nested_dissection"},
    {FillReducingOrdering::kAmdOrNestedDissection, "auto"}};
}  // namespace

const char* ToString(FillReducingOrdering o) { return NameOf(kOrderingNames, o); }

absl::StatusOr<FillReducingOrdering> FillReducingOrderingFromString(const std::string& name) {
  return ParseEnum(kOrderingNames, name, "fill-reducing ordering");
}

namespace {

// A CHOLMOD view of the leading rows × cols block of a compressed column matrix (p, i, x)
// whose first cols columns hold rows < rows only (no copy).
cholmod_sparse View(const std::vector<int>& p, const std::vector<int>& i, const std::vector<double>& x, int rows,
                    int cols) {
  cholmod_sparse s{};
  s.nrow = rows;
  s.ncol = cols;
  s.p = const_cast<int*>(p.data());
  s.i = const_cast<int*>(i.data());
  s.x = const_cast<double*>(x.data());
  s.nzmax = p[cols];
  s.stype = -1;  // the lower triangle of a symmetric matrix
  s.itype = CHOLMOD_INT;
  s.xtype = CHOLMOD_REAL;
  s.dtype = CHOLMOD_DOUBLE;
  s.sorted = 1;
  s.packed = 1;
  return s;
}

}  // namespace

SparseCholesky::SparseCholesky() : common_(new cholmod_common) {
  cholmod_start(common_);
  common_->supernodal = CHOLMOD_SIMPLICIAL;  // update/downdate need a simplicial LDLᵀ
  common_->final_ll = 0;
  common_->final_pack = 0;  // slack in each column for the fill of later updates
  common_->nmethods = 1;
  common_->method[0].ordering = CHOLMOD_GIVEN;
  common_->postorder = 0;  // keep the spare slots last
  common_->print = 0;
}

SparseCholesky::SparseCholesky(const SparseCholesky& other) : SparseCholesky() {
  if (other.factor_ != nullptr) factor_ = cholmod_copy_factor(other.factor_, common_);
  if (other.symbolic_ != nullptr) symbolic_ = cholmod_copy_factor(other.symbolic_, common_);
  SUBSLAM_CHECK((other.factor_ == nullptr) == (factor_ == nullptr) &&
                (other.symbolic_ == nullptr) == (symbolic_ == nullptr))
      << "CHOLMOD: out of memory";
  analysed_n_ = other.analysed_n_;
  analysed_ordering_ = other.analysed_ordering_;
  analysed_with_ = other.analysed_with_;
  symbolic_flops_ = other.symbolic_flops_;
  automatic_chose_nested_ = other.automatic_chose_nested_;
  analysed_p_ = other.analysed_p_;
  analysed_i_ = other.analysed_i_;
  analysed_last_ = other.analysed_last_;
  nested_dissection_unavailable_ = other.nested_dissection_unavailable_;
  lower_p_ = other.lower_p_;
  lower_i_ = other.lower_i_;
  lower_x_ = other.lower_x_;
  symbolic_reuses_ = other.symbolic_reuses_;
  selected_ = other.selected_;
  position_ = other.position_;
  scatter_ = other.scatter_;
  column_cache_ = other.column_cache_;
  forward_workspace_ = other.forward_workspace_;
  forward_stamp_ = other.forward_stamp_;
  path_index_ = other.path_index_;
  change_workspace_ = other.change_workspace_;
  change_live_ = other.change_live_;
  change_touched_ = other.change_touched_;
  parent_ = other.parent_;
  back_stamp_ = other.back_stamp_;
  back_walks_ = other.back_walks_;
  walks_ = other.walks_;
  dim_ = other.dim_;
  capacity_ = other.capacity_;
  nonzeros_after_factorize_ = other.nonzeros_after_factorize_;
  columns_solved_ = other.columns_solved_;
  reach_solved_ = other.reach_solved_;
}

SparseCholesky::~SparseCholesky() {
  if (factor_ != nullptr) cholmod_free_factor(&factor_, common_);
  if (symbolic_ != nullptr) cholmod_free_factor(&symbolic_, common_);
  cholmod_finish(common_);
  delete common_;
}

absl::Status SparseCholesky::Factorize(const Eigen::SparseMatrix<double>& A, int spare, FillReducingOrdering ordering,
                                       const std::vector<int>& last) {
  // The lower triangle of A, column by column (Eigen keeps each column's rows sorted).
  SparseLowerTriangle lower;
  lower.n = static_cast<int>(A.rows());
  lower.i.reserve(static_cast<size_t>(A.nonZeros()) / 2 + static_cast<size_t>(lower.n));
  lower.x.reserve(lower.i.capacity());
  for (int c = 0; c < lower.n; ++c) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, c); it; ++it) {
      if (it.row() < c) continue;
      lower.i.push_back(static_cast<int>(it.row()));
      lower.x.push_back(it.value());
    }
    lower.p.push_back(static_cast<int>(lower.i.size()));
  }
  return Factorize(lower, spare, ordering, last);
}

absl::StatusOr<SparseCholesky::Analysis> SparseCholesky::Analyse(FillReducingOrdering ordering, cholmod_sparse* a,
                                                                 cholmod_sparse* all, const std::vector<int>& last) {
  const int n = static_cast<int>(a->ncol);
  std::vector<int> perm(all->ncol);
  Analysis analysis;
  if (n > 0) {
    absl::StatusOr<FillReducingOrdering> used = Order(ordering, a, perm.data(), last);
    if (!used.ok()) return used.status();
    analysis.ordering = *used;
  }
  std::iota(perm.begin() + n, perm.end(), n);  // the spare slots last
  analysis.symbolic = cholmod_analyze_p(all, perm.data(), nullptr, 0, common_);
  if (analysis.symbolic == nullptr) return absl::InternalError("CHOLMOD: symbolic analysis failed");
  analysis.flops = common_->fl;
  return analysis;
}

absl::StatusOr<SparseCholesky::Analysis> SparseCholesky::AnalyseAutomatically(cholmod_sparse* a, cholmod_sparse* all,
                                                                              const std::vector<int>& last) {
  if (automatic_chose_nested_) {
    absl::StatusOr<Analysis> nested = Analyse(FillReducingOrdering::kNestedDissection, a, all, last);
    if (nested.ok()) return nested;
    common_->status = CHOLMOD_OK;  // METIS failed: AMD instead
    return Analyse(FillReducingOrdering::kAmd, a, all, last);
  }
  absl::StatusOr<Analysis> amd = Analyse(FillReducingOrdering::kAmd, a, all, last);
  const double entries = static_cast<double>(static_cast<const int*>(a->p)[a->ncol]);
  if (!amd.ok() || nested_dissection_unavailable_ || entries == 0 ||
      amd->flops < kNestedDissectionMinFlopsPerEntry * entries) {
    return amd;
  }
  // AMD's factor is costly: nested dissection from here on. Its own flops are not
  // compared: where they are a little higher, its balanced tree still shortens the
  // updates' paths. (If METIS fails, AMD's analysis stands.)
  absl::StatusOr<Analysis> nested = Analyse(FillReducingOrdering::kNestedDissection, a, all, last);
  if (!nested.ok() || nested->ordering != FillReducingOrdering::kNestedDissection) {
    if (nested.ok()) cholmod_free_factor(&nested->symbolic, common_);
    common_->status = CHOLMOD_OK;
    return amd;
  }
  cholmod_free_factor(&amd->symbolic, common_);
  automatic_chose_nested_ = true;
  return nested;
}

absl::StatusOr<FillReducingOrdering> SparseCholesky::Order(FillReducingOrdering ordering, cholmod_sparse* a, int* perm,
                                                           const std::vector<int>& last) {
  const int n = static_cast<int>(a->ncol);
  if (ordering == FillReducingOrdering::kNestedDissection) {
    int ok = 0;
    {
      // METIS keeps its random generator in process-wide state (reseeded at each call, so
      // each ordering is reproducible): one ordering at a time.
      static std::mutex metis_mutex;
      std::lock_guard<std::mutex> lock(metis_mutex);
      ok = cholmod_metis(a, nullptr, 0, /*postorder=*/1, perm, common_);
    }
    if (ok) {
      // The `last` variables moved to the end, the others in METIS's order.
      std::vector<char> is_last(n, 0);
      for (int v : last) is_last[v] = 1;
      std::stable_partition(perm, perm + n, [&](int v) { return !is_last[v]; });
      return FillReducingOrdering::kNestedDissection;
    }
    if (common_->status != CHOLMOD_NOT_INSTALLED) {
      return absl::InternalError("CHOLMOD: nested-dissection (METIS) ordering failed");
    }
    common_->status = CHOLMOD_OK;
    nested_dissection_unavailable_ = true;
  }
  if (last.empty()) {
    if (!cholmod_amd(a, nullptr, 0, perm, common_)) return absl::InternalError("CHOLMOD: AMD ordering failed");
    return FillReducingOrdering::kAmd;
  }
  // Constrained minimum degree: set 0 first, the `last` variables (set 1) after it.
  std::vector<int> member(n, 0);
  for (int v : last) member[v] = 1;
  if (!cholmod_camd(a, nullptr, 0, member.data(), perm, common_)) {
    return absl::InternalError("CHOLMOD: constrained AMD ordering failed");
  }
  return FillReducingOrdering::kAmd;
}

absl::Status SparseCholesky::Factorize(const SparseLowerTriangle& A, int spare, FillReducingOrdering ordering,
                                       const std::vector<int>& last_variables) {
  const int n = A.n;
  std::vector<int> last;
  for (int v : last_variables) {
    if (v < 0 || v >= n) return absl::InvalidArgumentError(absl::StrCat("Factorize: variable ", v, " out of range"));
    last.push_back(v);
  }
  std::sort(last.begin(), last.end());
  last.erase(std::unique(last.begin(), last.end()), last.end());
  if (static_cast<int>(A.p.size()) != n + 1 || A.p[0] != 0 || static_cast<size_t>(A.p[n]) != A.i.size() ||
      A.i.size() != A.x.size()) {
    return absl::InvalidArgumentError("Factorize: malformed lower triangle");
  }
  for (int c = 0; c < n; ++c) {
    if (A.p[c + 1] < A.p[c]) {
      return absl::InvalidArgumentError(absl::StrCat("Factorize: column ", c, " ends before it starts"));
    }
  }
  for (int c = 0; c < n; ++c) {
    for (int k = A.p[c]; k < A.p[c + 1]; ++k) {
      if (A.i[k] < c || A.i[k] >= n || (k > A.p[c] && A.i[k] <= A.i[k - 1])) {
        return absl::InvalidArgumentError(
            absl::StrCat("Factorize: column ", c, " is not a sorted lower-triangle column"));
      }
    }
  }
  if (factor_ != nullptr) cholmod_free_factor(&factor_, common_);
  const int capacity = n + std::max(0, spare);
  InvalidateCaches(capacity);
  // A's lower triangle, then the spare slots' identity: their columns come after A's, so
  // the first n columns alone are A.
  std::vector<int>& p = lower_p_;
  std::vector<int>& i = lower_i_;
  std::vector<double>& x = lower_x_;
  p.assign(A.p.begin(), A.p.end());
  i.reserve(A.i.size() + static_cast<size_t>(capacity - n));
  x.reserve(i.capacity());
  i.assign(A.i.begin(), A.i.end());
  x.assign(A.x.begin(), A.x.end());
  for (int s = n; s < capacity; ++s) {
    i.push_back(s);
    x.push_back(1.0);
    p.push_back(static_cast<int>(i.size()));
  }
  cholmod_sparse all = View(p, i, x, capacity, capacity);
  // The symbolic analysis (the ordering of A alone, the spare slots last; elimination tree; column
  // counts) depends on the pattern only: while it is the last analysed one — Gauss-Newton
  // iterations relinearise the same factors — a copy of that analysis is factorised again.
  // (p's length is capacity + 1, so equal p means equal spare slots too.)
  const bool same_pattern = symbolic_ != nullptr && n == analysed_n_ && ordering == analysed_ordering_ &&
                            p == analysed_p_ && i == analysed_i_ && last == analysed_last_;
  if (same_pattern) {
    factor_ = cholmod_copy_factor(symbolic_, common_);
    if (factor_ == nullptr) return absl::ResourceExhaustedError("CHOLMOD: out of memory");
  } else {
    if (symbolic_ != nullptr) cholmod_free_factor(&symbolic_, common_);
    analysed_n_ = -1;  // until the new analysis exists
    cholmod_sparse a = View(p, i, x, n, n);
    absl::StatusOr<Analysis> analysis = ordering == FillReducingOrdering::kAmdOrNestedDissection
                                            ? AnalyseAutomatically(&a, &all, last)
                                            : Analyse(ordering, &a, &all, last);
    if (!analysis.ok()) return analysis.status();
    symbolic_ = analysis->symbolic;
    analysed_with_ = analysis->ordering;
    symbolic_flops_ = analysis->flops;
    analysed_n_ = n;
    analysed_ordering_ = ordering;
    analysed_p_ = p;
    analysed_i_ = i;
    analysed_last_ = last;
    factor_ = cholmod_copy_factor(symbolic_, common_);
    if (factor_ == nullptr) return absl::ResourceExhaustedError("CHOLMOD: out of memory");
  }
  cholmod_factorize(&all, factor_, common_);
  // A simplicial LDLᵀ factorises some indefinite matrices too: D must be positive.
  if (common_->status != CHOLMOD_OK || factor_->minor < factor_->n || !PositiveDiagonal()) {
    cholmod_free_factor(&factor_, common_);
    return absl::InternalError("CHOLMOD: the matrix is not positive definite");
  }
  if (same_pattern) ++symbolic_reuses_;
  position_.assign(capacity, 0);
  const int* P = static_cast<const int*>(factor_->Perm);
  for (int k = 0; k < capacity; ++k) position_[P[k]] = k;
  dim_ = n;
  capacity_ = capacity;
  nonzeros_after_factorize_ = nonzeros();
  return absl::OkStatus();
}

absl::Status SparseCholesky::Update(int new_dim, const std::vector<int>& rows, const Eigen::MatrixXd& W) {
  if (factor_ == nullptr) return absl::FailedPreconditionError("no factor to update");
  if (new_dim < dim_ || new_dim > capacity_) return absl::OutOfRangeError("no spare slot for the new variables");
  // The factor changes from here on, also when a later step fails (the caller then
  // factorises afresh, which renews the parents too).
  InvalidateCaches(capacity_, /*keep_parents=*/true);
  const int k = static_cast<int>(W.cols());
  // C = P W: rows in the factor's order, sorted and unique within each column (a variable
  // listed twice, e.g. two features joined to one landmark, sums its rows).
  std::vector<int> order(rows.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return position_[rows[a]] < position_[rows[b]]; });
  std::vector<int> unique_position;
  Eigen::MatrixXd merged(static_cast<Eigen::Index>(rows.size()), k);
  for (int r : order) {
    if (!unique_position.empty() && unique_position.back() == position_[rows[r]]) {
      merged.row(static_cast<Eigen::Index>(unique_position.size()) - 1) += W.row(r);
    } else {
      merged.row(static_cast<Eigen::Index>(unique_position.size())) = W.row(r);
      unique_position.push_back(position_[rows[r]]);
    }
  }
  const int m = static_cast<int>(unique_position.size());
  merged.conservativeResize(m, Eigen::NoChange);
  // The same update C Cᵀ = W Wᵀ with C lower trapezoidal in the factor's order (C = Rᵀ of
  // Wᵀ = QR): column j starts at the j-th row, so only as many columns as there are
  // rows before the last ones walk the long elimination-tree paths from the early
  // (old) variables; the rest start at the newest variables, near the root.
  const int kc = std::min(k, m);
  Eigen::MatrixXd R = Eigen::HouseholderQR<Eigen::MatrixXd>(merged.transpose()).matrixQR();
  cholmod_sparse* C =
      cholmod_allocate_sparse(capacity_, kc, static_cast<size_t>(m) * kc, 1, 1, 0, CHOLMOD_REAL, common_);
  if (C == nullptr) return absl::ResourceExhaustedError("CHOLMOD: out of memory");
  int* Cp = static_cast<int*>(C->p);
  int* Ci = static_cast<int*>(C->i);
  double* Cx = static_cast<double*>(C->x);
  int nz = 0;
  for (int j = 0; j < kc; ++j) {
    Cp[j] = nz;
    for (int r = j; r < m; ++r) {
      Ci[nz] = unique_position[r];
      Cx[nz++] = R(j, r);
    }
  }
  Cp[kc] = nz;
  const int ok = cholmod_updown(1, C, factor_, common_);
  cholmod_free_sparse(&C, common_);
  if (!ok || common_->status != CHOLMOD_OK) return absl::InternalError("CHOLMOD: update failed");
  // The new variables' slots lose their identity: a downdate by their unit vectors.
  const int added = new_dim - dim_;
  if (added > 0) {
    cholmod_sparse* E = cholmod_allocate_sparse(capacity_, added, added, 1, 1, 0, CHOLMOD_REAL, common_);
    if (E == nullptr) return absl::ResourceExhaustedError("CHOLMOD: out of memory");
    int* Ep = static_cast<int*>(E->p);
    int* Ei = static_cast<int*>(E->i);
    double* Ex = static_cast<double*>(E->x);
    for (int j = 0; j < added; ++j) {
      Ep[j] = j;
      Ei[j] = position_[dim_ + j];
      Ex[j] = 1.0;
    }
    Ep[added] = added;
    const int down = cholmod_updown(0, E, factor_, common_);
    cholmod_free_sparse(&E, common_);
    if (!down || common_->status != CHOLMOD_OK) return absl::InternalError("CHOLMOD: downdate failed");
  }
  // A downdate that lost positive definiteness leaves a non-positive pivot in D; only
  // the columns on the update's paths changed.
  std::vector<int> starts = unique_position;
  for (int v = dim_; v < new_dim; ++v) starts.push_back(position_[v]);
  if (!RefreshParentsFrom(starts)) {
    return absl::InternalError("CHOLMOD: the updated matrix is not positive definite");
  }
  dim_ = new_dim;
  return absl::OkStatus();
}

Eigen::MatrixXd SparseCholesky::Solve(const Eigen::MatrixXd& B) const {
  const int k = static_cast<int>(B.cols());
  cholmod_dense* b = cholmod_zeros(capacity_, k, CHOLMOD_REAL, common_);
  Eigen::Map<Eigen::MatrixXd>(static_cast<double*>(b->x), capacity_, k).topRows(dim_) = B;
  cholmod_dense* x = cholmod_solve(CHOLMOD_A, factor_, b, common_);
  Eigen::MatrixXd out = Eigen::Map<Eigen::MatrixXd>(static_cast<double*>(x->x), capacity_, k).topRows(dim_);
  cholmod_free_dense(&b, common_);
  cholmod_free_dense(&x, common_);
  return out;
}

bool SparseCholesky::PositiveDiagonal() const {
  const double* Lx = static_cast<const double*>(factor_->x);
  const int* Lp = static_cast<const int*>(factor_->p);
  for (size_t j = 0; j < factor_->n; ++j) {
    if (!(Lx[Lp[j]] > 0.0)) return false;  // D_jj sits first in column j of an LDLᵀ factor
  }
  return true;
}

long SparseCholesky::nonzeros() const {
  if (factor_ == nullptr) return 0;
  const int* nz = static_cast<const int*>(factor_->nz);
  long total = 0;
  for (size_t j = 0; j < factor_->n; ++j) total += nz[j];
  return total;
}

}  // namespace subslam::backend
