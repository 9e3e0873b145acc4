// A sparse LDLᵀ factor of a symmetric positive definite matrix A (CHOLMOD, simplicial)
// that can grow: besides a full factorisation with a fill-reducing ordering (AMD or
// METIS nested dissection; the analysis is reused while the pattern is the same),
// it takes rank-k updates A += W Wᵀ (cholmod_updown) and new variables, which occupy
// spare slots kept as identity rows at the end of the ordering until claimed. This is the
// incremental factor of the EIF joiner (internal: not part of the API).
//
// With the spare slots last in the ordering, a join's update touches only the columns on
// the elimination-tree paths from its variables, so a join that extends the map (its
// start anchor and new variables near the end of the ordering) costs little; a loop
// closure touching old landmarks costs more, and the fill grows until the caller asks for
// a full factorisation with a new ordering.
#ifndef SUBSLAM_BACKEND_INTERNAL_SPARSE_CHOLESKY_H_
#define SUBSLAM_BACKEND_INTERNAL_SPARSE_CHOLESKY_H_

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <map>
#include <optional>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/backend/fill_reducing_ordering.h"

struct cholmod_common_struct;
struct cholmod_factor_struct;
struct cholmod_sparse_struct;

namespace subslam::backend {

// The lower triangle (diagonal included) of a symmetric n × n matrix in compressed
// columns: column c's rows, sorted and all ≥ c, are i[p[c]] … i[p[c + 1] − 1], with
// values x; p has n + 1 entries.
struct SparseLowerTriangle {
  int n = 0;
  std::vector<int> p = {0}, i;
  std::vector<double> x;
};

class SparseCholesky {
 public:
  SparseCholesky();
  ~SparseCholesky();
  // An exact copy: the factor and the symbolic analysis (cholmod_copy_factor, with the
  // columns' slack for later updates), and what was computed from them.
  SparseCholesky(const SparseCholesky& other);
  SparseCholesky& operator=(const SparseCholesky&) = delete;

  // Factorises A (n × n, symmetric; both triangles stored or the lower one) with the
  // given fill-reducing ordering of A and `spare` identity slots after it. The symbolic
  // analysis (ordering, elimination tree, column counts) is redone only when A's pattern
  // (or n, or spare, or the ordering asked for) differs from the last analysed one;
  // otherwise it is reused, with the same result.
  // `last`: variables the ordering puts after all others (before the spare slots) — the
  // ones the next updates will touch, so that their elimination-tree paths are short
  // (iSAM2 constrains its ordering the same way): CAMD's constrained minimum degree, or
  // nested dissection's order with them moved to its end.
  absl::Status Factorize(const Eigen::SparseMatrix<double>& A, int spare,
                         FillReducingOrdering ordering = FillReducingOrdering::kAmd, const std::vector<int>& last = {});
  // The same from A's lower triangle as it is stored. A malformed A (sizes, columns'
  // ranges, rows unsorted or above the diagonal) is rejected before anything changes:
  // the previous factor stays.
  absl::Status Factorize(const SparseLowerTriangle& A, int spare,
                         FillReducingOrdering ordering = FillReducingOrdering::kAmd, const std::vector<int>& last = {});
  // A += W Wᵀ, where row r of W belongs to variable rows[r]; variables numbered from dim()
  // up to new_dim − 1 are new and claim spare slots (their identity is removed).
  // Requires new_dim ≤ capacity().
  absl::Status Update(int new_dim, const std::vector<int>& rows, const Eigen::MatrixXd& W);
  // A⁻¹ B for B with dim() rows.
  Eigen::MatrixXd Solve(const Eigen::MatrixXd& B) const;
  // Carries a solution over a change of the system: `x` (dim() entries; the solution of
  // the system before, new variables at 0) becomes x + Δx with A Δx = r, where r, the new
  // right-hand side minus A x, is non-zero on the variables `rows` only (r_local, in that
  // order). The forward solve runs over the elimination-tree paths from those rows to the
  // root alone (exact); the back substitution runs from the roots down and solves a column
  // only on those paths or where a row of it changed by more than `threshold`: where the
  // changes die out, the columns under them are left as they are (the "wildfire" of
  // iSAM2's partial state update, which tests a clique's separator the same way; a column
  // left out misses at most threshold · Σ|L_ij| over its rows; threshold 0 carries every
  // change that is not exactly zero). Appends the variables whose value changed to `changed` and, when given, the
  // changes to `change_sizes`. Work: the paths, the columns entered, and one pass over the
  // elimination tree's parents.
  void SolveChange(const std::vector<int>& rows, const Eigen::VectorXd& r_local, double threshold, Eigen::VectorXd* x,
                   std::vector<int>* changed, std::vector<double>* change_sizes = nullptr) const;
  // The block of A⁻¹ on the listed variables (rows and columns in the listed order):
  // with P A Pᵀ = L D Lᵀ, (A⁻¹)_SS = Yᵀ D⁻¹ Y for Y = L⁻¹ P E_S, each column of Y by a
  // forward solve limited to the reach of its unit right-hand side — the elimination-tree
  // path from the variable to the root, short for the recent variables association asks
  // about.
  Eigen::MatrixXd InverseBlock(const std::vector<int>& variables) const;
  // The off-diagonal block (A⁻¹)_{left, right}, entry by entry the value InverseBlock
  // gives for it when `left` is listed before `right` (the same dot products): with the
  // diagonal blocks kept, a pair's joint block costs its cross terms only.
  Eigen::MatrixXd CrossBlock(const std::vector<int>& left, const std::vector<int>& right) const;
  // For each group, the block of A⁻¹ on [hub, group] — the hub's and the group's own
  // entries and their cross terms, never two groups' cross terms: each column solved
  // once, dot products only where needed.
  std::vector<Eigen::MatrixXd> InverseStarBlocks(const std::vector<int>& hub,
                                                 const std::vector<std::vector<int>>& groups) const;

  // Rows `rows` of A⁻¹'s columns `columns` ((A⁻¹)_{rows, columns}), without the other
  // rows: each column's forward solve (cached, as for InverseBlock), then a back
  // substitution over the elimination-tree paths from the requested rows to the root
  // only (x_j needs x on j's ancestors alone). O(Σ nnz(L_j)) over those paths instead of
  // O(nnz(L)) for a full solve: a join's start anchor against its candidate landmarks.
  Eigen::MatrixXd InverseColumnsAt(const std::vector<int>& columns, const std::vector<int>& rows) const;
  // The diagonal blocks of A⁻¹ on many groups of variables at once (each group's block,
  // rows and columns in the listed order; no cross terms between groups), from A⁻¹'s
  // entries on the pattern of L: the sparse-inverse (Takahashi) recursion
  // Z_kj = −Σ_{i∈L_j} L_ij Z_ik, Z_jj = 1/D_j − Σ_{i∈L_j} L_ij Z_ij over the columns from
  // the last, O(Σ_j nnz(L_j)²) once per factor instead of a forward solve per variable.
  // A group's pairs lie on L's pattern when they are coupled in A (a landmark's x and y,
  // an anchor's three coordinates); a group with an uncoupled pair gets its block by
  // forward solves instead (InverseBlock). For all marginals of a map; a few blocks are
  // cheaper by InverseBlock.
  std::vector<Eigen::MatrixXd> DiagonalInverseBlocks(const std::vector<std::vector<int>>& groups) const;

  bool ready() const { return factor_ != nullptr; }
  int dim() const { return dim_; }
  int capacity() const { return capacity_; }
  // Entries of L (a measure of fill) now and right after the last full factorisation.
  long nonzeros() const;
  long nonzeros_after_factorize() const { return nonzeros_after_factorize_; }
  // Forward columns solved for InverseBlock / InverseStarBlocks so far, and the sum of
  // their reaches (rows touched): the work of covariance recovery.
  long columns_solved() const { return columns_solved_; }
  long reach_solved() const { return reach_solved_; }
  // Successful Factorize() calls that reused the previous symbolic analysis.
  long symbolic_reuses() const { return symbolic_reuses_; }
  // The ordering of the factor (kAmd or kNestedDissection; fill_reducing_ordering.h) and
  // the flops of its numeric factorisation as CHOLMOD's analysis predicts them
  // (Common::fl: the LLᵀ count of the whole capacity × capacity matrix, spare slots
  // included).
  FillReducingOrdering ordering() const { return analysed_with_; }
  double factorization_flops() const { return symbolic_flops_; }
  // kAmdOrNestedDissection switches to nested dissection from this many flops per entry
  // of A's lower triangle (factorization_flops() over the entries stored, explicit zeros
  // included). METIS's ordering takes about as long as 20-120 flops of numeric
  // factorisation per entry (measured: 40-70 ns per entry, at 0.5-1.7 GFlop/s), so below
  // about this AMD's whole factorisation costs less than METIS would. The EIF's matrices
  // lie far on either side: 29 flops per entry on combined-2km (one loop), 100-780 on
  // the random worlds (bench/RESULTS.md).
  static constexpr double kNestedDissectionMinFlopsPerEntry = 50.0;
  // Whether a nested-dissection ordering was asked for and AMD used instead, because this
  // CHOLMOD has no METIS.
  bool nested_dissection_unavailable() const { return nested_dissection_unavailable_; }

 private:
  cholmod_common_struct* common_;
  cholmod_factor_struct* factor_ = nullptr;
  // The last symbolic analysis and the pattern (lower triangle and spare slots, compressed
  // columns) it was made for; lower_*: Factorize()'s matrix, kept to reuse its storage.
  cholmod_factor_struct* symbolic_ = nullptr;
  int analysed_n_ = -1;
  FillReducingOrdering analysed_ordering_ = FillReducingOrdering::kAmd;  // asked for
  FillReducingOrdering analysed_with_ = FillReducingOrdering::kAmd;      // used
  double symbolic_flops_ = 0.0;
  // kAmdOrNestedDissection has switched to nested dissection (for good).
  bool automatic_chose_nested_ = false;
  std::vector<int> analysed_p_, analysed_i_, analysed_last_;
  bool nested_dissection_unavailable_ = false;
  // The fill-reducing permutation of A's n × n lower triangle `a` into perm[0, n).
  // (kAmd or kNestedDissection only.) Returns the ordering used: AMD where METIS is not
  // installed.
  absl::StatusOr<FillReducingOrdering> Order(FillReducingOrdering ordering, cholmod_sparse_struct* a, int* perm,
                                             const std::vector<int>& last);
  // The symbolic analysis of `all` (A's lower triangle `a`, then the spare slots) with
  // A ordered by `ordering` (kAmd or kNestedDissection) and the spare slots last.
  struct Analysis {
    cholmod_factor_struct* symbolic = nullptr;                   // owned by the caller
    FillReducingOrdering ordering = FillReducingOrdering::kAmd;  // used
    double flops = 0.0;                                          // of a numeric factorisation
  };
  absl::StatusOr<Analysis> Analyse(FillReducingOrdering ordering, cholmod_sparse_struct* a, cholmod_sparse_struct* all,
                                   const std::vector<int>& last);
  // kAmdOrNestedDissection's analysis: nested dissection once switched (AMD if METIS
  // fails); before, AMD's, or nested dissection's when AMD's costs at least
  // kNestedDissectionMinFlopsPerEntry per entry of `a` (the switch).
  absl::StatusOr<Analysis> AnalyseAutomatically(cholmod_sparse_struct* a, cholmod_sparse_struct* all,
                                                const std::vector<int>& last);
  std::vector<int> lower_p_, lower_i_;
  std::vector<double> lower_x_;
  long symbolic_reuses_ = 0;
  struct SparseColumn {
    std::vector<int> rows;       // the reach, in the factor's order
    std::vector<double> values;  // y_r / √D_r, so that (A⁻¹)_ab is a plain dot product
  };
  const SparseColumn& ForwardColumn(int variable) const;
  // Solves (and caches) the columns of the listed variables not cached yet, carrying every
  // variable that lies on a walk's path in that walk.
  void SolveColumns(const std::vector<int>& variables) const;
  // For many columns at once (`pending`, sorted by position, none cached): each walks its
  // path only until it meets the path S of the first one to the root; the part in S is
  // solved for all of them together, one sweep over S's columns updating every
  // right-hand side at once (S is where the paths merge; near the root L is dense). False
  // (nothing done) if S is shorter than kSharedPathMinLength or longer than
  // kSharedPathMaxLength (the |S| × R block of right-hand sides).
  bool SolveThroughSharedPath(const std::vector<int>& pending) const;
  static constexpr int kSharedPathMinColumns = 6;
  // InverseBlock() on at least this many variables forms YᵀY as one dense product.
  static constexpr int kDenseBlockMinColumns = 8;
  static constexpr int kMaxCarried = 4;  // right-hand sides one SolveColumns() walk carries
  static constexpr int kSharedPathMinLength = 150;
  static constexpr int kSharedPathMaxLength = 2000;
  bool PositiveDiagonal() const;
  // A⁻¹ on L's pattern, computed on first use after the factor last changed
  // (DiagonalInverseBlocks): per factor column j (factor order), its rows below the
  // diagonal sorted, and Z there; Z's diagonal apart.
  struct SelectedInverse {
    std::vector<int> start;  // column j's entries: [start[j], start[j + 1])
    std::vector<int> rows;
    std::vector<double> lower;  // L_ij
    std::vector<double> z;      // Z_ij
    std::vector<double> diagonal;
  };
  const SelectedInverse& Selected() const;
  // Drops what was computed from the factor (forward columns, the selected inverse — a few
  // arrays of nnz(L) entries, kept until the factor changes — and the parents); called
  // before the factor changes, so an error part-way leaves nothing stale. An update keeps
  // the parents it does not change (RefreshParentsFrom renews the others).
  void InvalidateCaches(int capacity, bool keep_parents = false);
  // Z at factor positions (a, b) if it lies on L's pattern.
  std::optional<double> SelectedEntry(int a, int b) const;
  mutable std::optional<SelectedInverse> selected_;
  // out[o] = aᵀ others[o] for o ≥ begin (the columns carry D^{-1/2}); a is scattered once.
  void Dots(const SparseColumn& a, const std::vector<const SparseColumn*>& others, int begin, double* out) const;

  std::vector<int> position_;            // variable → row of the permuted factor
  mutable std::vector<double> scatter_;  // Dots()' dense scatter of one column, all zero between calls
  // Columns of Y solved since the factor last changed (std::map: references stay valid).
  mutable std::map<int, SparseColumn> column_cache_;
  // The walks' y (capacity × kMaxCarried), all zero between walks; sized on first use.
  std::vector<double>& ForwardWorkspace() const;
  mutable std::vector<double> forward_workspace_;
  mutable std::vector<int> forward_stamp_;  // SolveColumns()'s rows written, by walk
  // Position → index in SolveThroughSharedPath()'s path S, or in InverseBlock()'s dense Y;
  // all −1 between uses.
  mutable std::vector<int> path_index_;
  // Column j's parent in the elimination tree (its smallest row; −1 at a root), found on
  // first use after a factorisation (−2: not yet); an update refreshes the columns it
  // changed (the paths from its rows to the root), the others keep theirs.
  int Parent(int j) const;
  // Also checks those columns' pivots: false if one is not positive.
  bool RefreshParentsFrom(const std::vector<int>& positions);
  mutable std::vector<double> change_workspace_;  // SolveChange(): all zero between calls
  mutable std::vector<char> change_live_, change_touched_;
  mutable std::vector<int> parent_;
  mutable std::vector<int> back_stamp_;  // InverseColumnsAt(): positions on a requested path
  mutable int back_walks_ = 0;
  mutable int walks_ = 0;
  int dim_ = 0, capacity_ = 0;
  long nonzeros_after_factorize_ = 0;
  mutable long columns_solved_ = 0, reach_solved_ = 0;
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_INTERNAL_SPARSE_CHOLESKY_H_
