#include "subslam/backend/internal/sparse_cholesky.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <random>

#include "test_util.h"

namespace subslam::backend {
namespace {

using testing::MatricesNear;

// A random sparse symmetric positive definite matrix: a chain with a few long links.
Eigen::MatrixXd RandomSpd(int n, std::mt19937_64* rng) {
  std::normal_distribution<double> normal;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  for (int k = 0; k < 3 * n; ++k) {
    std::uniform_int_distribution<int> pick(0, n - 1);
    const int i = pick(*rng), j = (k < n) ? std::min(n - 1, i + 1) : pick(*rng);
    Eigen::Vector2d w(normal(*rng), normal(*rng));
    A(i, i) += w[0] * w[0];
    A(j, j) += w[1] * w[1];
    A(i, j) += w[0] * w[1];
    A(j, i) += w[0] * w[1];
  }
  A += 0.5 * Eigen::MatrixXd::Identity(n, n);
  return A;
}

Eigen::SparseMatrix<double> Sparse(const Eigen::MatrixXd& A) { return A.sparseView(); }

// A's lower triangle in compressed columns, as SparseLowerTriangle holds it.
SparseLowerTriangle LowerOf(const Eigen::MatrixXd& A) {
  SparseLowerTriangle lower;
  lower.n = static_cast<int>(A.rows());
  for (int c = 0; c < lower.n; ++c) {
    for (int r = c; r < lower.n; ++r) {
      if (A(r, c) == 0.0) continue;
      lower.i.push_back(r);
      lower.x.push_back(A(r, c));
    }
    lower.p.push_back(static_cast<int>(lower.i.size()));
  }
  return lower;
}

TEST(SparseCholesky, FactorizeSolvesAndRecoversInverseBlocks) {
  std::mt19937_64 rng(1);
  const Eigen::MatrixXd A = RandomSpd(30, &rng);
  SparseCholesky L;
  ASSERT_TRUE(L.Factorize(Sparse(A), 10).ok());
  EXPECT_EQ(L.dim(), 30);
  EXPECT_EQ(L.capacity(), 40);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(30, 3);
  EXPECT_TRUE(MatricesNear(A.ldlt().solve(B), L.Solve(B), 1e-10));
  const Eigen::MatrixXd inverse = A.inverse();
  const std::vector<int> vars = {29, 3, 17, 0};
  EXPECT_TRUE(MatricesNear(inverse(vars, vars), L.InverseBlock(vars), 1e-10));
  // Star blocks: [hub, group] for each group, and nothing between groups.
  const std::vector<Eigen::MatrixXd> star = L.InverseStarBlocks({5, 6}, {{7, 8}, {20}, {}});
  ASSERT_EQ(star.size(), 3u);
  EXPECT_TRUE(MatricesNear(inverse({5, 6, 7, 8}, {5, 6, 7, 8}), star[0], 1e-10));
  EXPECT_TRUE(MatricesNear(inverse({5, 6, 20}, {5, 6, 20}), star[1], 1e-10));
  EXPECT_TRUE(MatricesNear(inverse({5, 6}, {5, 6}), star[2], 1e-10));
  // A cross block: InverseBlock's off-diagonal with the left variables first, to the bit.
  const Eigen::MatrixXd joint = L.InverseBlock({12, 13, 25, 2});
  EXPECT_TRUE(L.CrossBlock({12, 13}, {25, 2}) == joint.topRightCorner(2, 2));
  EXPECT_TRUE(MatricesNear(inverse({12, 13}, {25, 2}), L.CrossBlock({12, 13}, {25, 2}), 1e-10));
}

// A chain of `chain` variables (each linked to the next) and, apart, a second chain of
// `other`: a sparse factor whose pattern is known (no path between the two).
Eigen::MatrixXd TwoChains(int chain, int other, std::mt19937_64* rng) {
  const int n = chain + other;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  std::normal_distribution<double> normal;
  const auto link = [&](int i, int j) {
    const Eigen::Vector2d w(normal(*rng), normal(*rng));
    A(i, i) += w[0] * w[0];
    A(j, j) += w[1] * w[1];
    A(i, j) += w[0] * w[1];
    A(j, i) += w[0] * w[1];
  };
  for (int i = 0; i + 1 < chain; ++i) link(i, i + 1);
  for (int i = chain; i + 1 < n; ++i) link(i, i + 1);
  A += 0.1 * Eigen::MatrixXd::Identity(n, n);
  return A;
}

// Adds W Wᵀ on `rows` to a copy of A grown to n rows.
Eigen::MatrixXd Updated(const Eigen::MatrixXd& A, int n, const std::vector<int>& rows, const Eigen::MatrixXd& W) {
  Eigen::MatrixXd grown = Eigen::MatrixXd::Zero(n, n);
  grown.topLeftCorner(A.rows(), A.cols()) = A;
  for (size_t r = 0; r < rows.size(); ++r) {
    for (size_t q = 0; q < rows.size(); ++q) {
      grown(rows[r], rows[q]) += W.row(static_cast<int>(r)).dot(W.row(static_cast<int>(q)));
    }
  }
  return grown;
}

// Many columns at once go through the shared path to the root as one dense solve (a
// long chain: paths of hundreds of rows), also after rank updates, and with variables in
// a second, disconnected component (whose paths never meet the first one's): the blocks
// equal the dense inverse's.
TEST(SparseCholesky, ManyColumnsThroughTheSharedPathEqualTheDenseInverse) {
  const int chain = 700, other = 40, n = chain + other;
  std::mt19937_64 rng(5);
  const Eigen::MatrixXd A = TwoChains(chain, other, &rng);
  SparseCholesky L;
  ASSERT_TRUE(L.Factorize(Sparse(A), 8).ok());
  std::vector<int> vars = {n - 1, chain + 3};  // the second component too
  for (int k = 0; k < 24; ++k) vars.push_back((k * 97 + 11) % chain);
  const long reach_before = L.reach_solved();
  EXPECT_TRUE(MatricesNear(A.inverse()(vars, vars), L.InverseBlock(vars), 1e-9));
  EXPECT_GT(L.reach_solved() - reach_before, 150L * 20);  // long paths: the shared solve ran
  // After a rank update touching both ends of the chain (the cache is dropped).
  Eigen::MatrixXd W = Eigen::MatrixXd::Zero(3, 1);
  W << 0.7, -0.4, 0.9;
  const std::vector<int> rows = {0, chain / 2, chain - 1};
  ASSERT_TRUE(L.Update(n, rows, W).ok());
  const Eigen::MatrixXd A2 = Updated(A, n, rows, W);
  const std::vector<Eigen::MatrixXd> star = L.InverseStarBlocks({vars[2], vars[3]}, {{vars[4], vars[5]}, {n - 2}});
  const Eigen::MatrixXd inverse = A2.inverse();
  EXPECT_TRUE(
      MatricesNear(inverse({vars[2], vars[3], vars[4], vars[5]}, {vars[2], vars[3], vars[4], vars[5]}), star[0], 1e-9));
  EXPECT_TRUE(MatricesNear(inverse({vars[2], vars[3], n - 2}, {vars[2], vars[3], n - 2}), star[1], 1e-9));
  EXPECT_TRUE(MatricesNear(inverse(vars, vars), L.InverseBlock(vars), 1e-9));
}

// The diagonal blocks from A⁻¹ on L's pattern (the sparse-inverse recursion) equal the
// dense inverse's: coupled pairs and triples, single variables, a pair across the two
// components (off L's pattern: answered by forward solves), after a full factorisation and
// after rank updates — a long link in the middle of a chain (fill in the columns between
// its ends) and new variables claiming spare slots.
TEST(SparseCholesky, DiagonalInverseBlocksEqualTheDenseInverse) {
  std::mt19937_64 rng(9);
  const int chain = 50, other = 10, n = chain + other;
  Eigen::MatrixXd A = TwoChains(chain, other, &rng);
  // 40, 41, 42 coupled to each other, as an anchor's coordinates are.
  A(40, 42) = A(42, 40) = 0.2;
  A(40, 40) += 1.0;
  A(42, 42) += 1.0;
  SparseCholesky L;
  ASSERT_TRUE(L.Factorize(Sparse(A), 5).ok());
  std::vector<std::vector<int>> groups = {{10, 11}, {42, 40, 41}, {55, 56}};
  for (int v = 0; v < n; ++v) groups.push_back({v});
  const auto check = [&](const Eigen::MatrixXd& matrix) {
    const Eigen::MatrixXd inverse = matrix.inverse();
    const long solved_before = L.columns_solved();
    const std::vector<Eigen::MatrixXd> blocks = L.DiagonalInverseBlocks(groups);
    EXPECT_EQ(blocks.size(), groups.size());
    for (size_t g = 0; g < groups.size() && g < blocks.size(); ++g) {
      EXPECT_TRUE(MatricesNear(inverse(groups[g], groups[g]), blocks[g], 1e-9)) << "group " << g;
    }
    return L.columns_solved() - solved_before;
  };
  EXPECT_EQ(check(A), 0);     // every group on the pattern: no forward solve
  groups.push_back({3, 57});  // across the components: off the pattern
  EXPECT_GT(check(A), 0);
  // A long link in the first chain, then new variables linked to both chains.
  const std::vector<int> link = {5, 45};
  const Eigen::MatrixXd W1 = Eigen::MatrixXd::Random(2, 2);
  ASSERT_TRUE(L.Update(n, link, W1).ok());
  const Eigen::MatrixXd A1 = Updated(A, n, link, W1);
  groups.push_back({5, 45});
  check(A1);
  const std::vector<int> rows = {1, 20, 58, 60, 61, 62};
  const Eigen::MatrixXd W2 = Eigen::MatrixXd::Random(static_cast<int>(rows.size()), 6);
  ASSERT_TRUE(L.Update(n + 3, rows, W2).ok());
  groups.push_back({60, 61, 62});
  groups.push_back({1, 20});
  check(Updated(A1, n + 3, rows, W2));
  EXPECT_TRUE(L.DiagonalInverseBlocks({}).empty());
}

// Selected rows of A⁻¹'s columns (a back substitution over the rows' paths to the root
// only) equal the dense inverse's: more columns than one pass carries, rows among the
// columns, rows in a second component, after a full factorisation and after an update
// that changes the elimination tree (a long link in a chain: rows far below it now have
// other ancestors).
TEST(SparseCholesky, InverseColumnsAtSelectedRowsEqualTheDenseInverse) {
  std::mt19937_64 rng(13);
  const int chain = 70, other = 10, n = chain + other;
  const Eigen::MatrixXd A = TwoChains(chain, other, &rng);
  SparseCholesky L;
  ASSERT_TRUE(L.Factorize(Sparse(A), 4).ok());
  const std::vector<int> columns = {3, 4, 5, 40, 66, 71};
  const std::vector<int> rows = {0, 5, 17, 40, 41, 69, 72, 79, 3};
  EXPECT_TRUE(MatricesNear(A.inverse()(rows, columns), L.InverseColumnsAt(columns, rows), 1e-9));
  // Twice: the workspace is left clean.
  EXPECT_TRUE(MatricesNear(A.inverse()(rows, columns), L.InverseColumnsAt(columns, rows), 1e-9));
  // A long link between the chain's ends; then a new variable.
  const std::vector<int> link = {1, 68};
  const Eigen::MatrixXd W1 = Eigen::MatrixXd::Random(2, 1);
  ASSERT_TRUE(L.Update(n, link, W1).ok());
  const Eigen::MatrixXd A1 = Updated(A, n, link, W1);
  const std::vector<int> rows1 = {2, 10, 30, 50, 67};
  const std::vector<int> columns1 = {0, 69};
  EXPECT_TRUE(MatricesNear(A1.inverse()(rows1, columns1), L.InverseColumnsAt(columns1, rows1), 1e-9));
  const std::vector<int> update_rows = {2, 60, 80};
  const Eigen::MatrixXd W2 = Eigen::MatrixXd::Random(3, 3);
  ASSERT_TRUE(L.Update(n + 1, update_rows, W2).ok());
  const Eigen::MatrixXd A2 = Updated(A1, n + 1, update_rows, W2);
  const std::vector<int> columns2 = {80, 2};
  const std::vector<int> rows2 = {1, 60, 80, 75, 33};
  EXPECT_TRUE(MatricesNear(A2.inverse()(rows2, columns2), L.InverseColumnsAt(columns2, rows2), 1e-9));
  EXPECT_EQ(L.InverseColumnsAt({}, rows2).cols(), 0);
}

// A += W Wᵀ with new variables claiming spare slots equals factorising the grown matrix,
// including when a variable is listed twice (its rows add up).
// A grown by `added` new variables and the update W Wᵀ, row r of W on variable rows[r].
Eigen::MatrixXd Grown(const Eigen::MatrixXd& A, int added, const std::vector<int>& rows, const Eigen::MatrixXd& W) {
  const int n = static_cast<int>(A.rows());
  Eigen::MatrixXd grown = Eigen::MatrixXd::Zero(n + added, n + added);
  grown.topLeftCorner(n, n) = A;
  Eigen::MatrixXd Wfull = Eigen::MatrixXd::Zero(n + added, W.cols());
  for (size_t r = 0; r < rows.size(); ++r) Wfull.row(rows[r]) += W.row(static_cast<int>(r));
  return grown + Wfull * Wfull.transpose();
}

TEST(SparseCholesky, UpdateWithNewVariablesEqualsRefactorizing) {
  std::mt19937_64 rng(2);
  const int n = 25, added = 4;
  const Eigen::MatrixXd A = RandomSpd(n, &rng);
  SparseCholesky L;
  ASSERT_TRUE(L.Factorize(Sparse(A), 8).ok());
  // W over old variables 3, 24, 24 (twice) and the new ones 25 … 28 (full rank on them).
  const std::vector<int> rows = {3, 24, 24, 25, 26, 27, 28};
  Eigen::MatrixXd W = Eigen::MatrixXd::Random(static_cast<int>(rows.size()), 6);
  Eigen::MatrixXd grown = Grown(A, added, rows, W);
  ASSERT_TRUE(L.Update(n + added, rows, W).ok());
  EXPECT_EQ(L.dim(), n + added);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n + added, 2);
  EXPECT_TRUE(MatricesNear(grown.ldlt().solve(B), L.Solve(B), 1e-9));
  const std::vector<int> vars = {24, 25, 28, 3};
  EXPECT_TRUE(MatricesNear(grown.inverse()(vars, vars), L.InverseBlock(vars), 1e-9));
  // More columns than rows (the update is applied as its m × m triangular equivalent),
  // rows given out of the factor's order.
  const std::vector<int> rows2 = {10, 3, 27};
  const Eigen::MatrixXd W2 = Eigen::MatrixXd::Random(3, 5);
  for (size_t r = 0; r < rows2.size(); ++r) {
    for (size_t q = 0; q < rows2.size(); ++q) {
      grown(rows2[r], rows2[q]) += W2.row(static_cast<int>(r)).dot(W2.row(static_cast<int>(q)));
    }
  }
  ASSERT_TRUE(L.Update(n + added, rows2, W2).ok());
  EXPECT_TRUE(MatricesNear(grown.ldlt().solve(B), L.Solve(B), 1e-9));
  EXPECT_TRUE(MatricesNear(grown.inverse()(vars, vars), L.InverseBlock(vars), 1e-9));
}

// SolveChange carries A x = b over an update: with threshold 0 it is the solution of the
// updated system to rounding, also after several updates with new variables; with a
// threshold the changes it leaves out are each below it, so the solution stays within a
// small multiple; every variable it reports changed, and no other, moved.
TEST(SparseCholesky, SolveChangeCarriesTheSolutionOverUpdates) {
  for (double threshold : {0.0, 1e-6}) {
    SCOPED_TRACE(threshold);
    std::mt19937_64 rng(7);
    const int n = 60;
    Eigen::MatrixXd A = RandomSpd(n, &rng);
    SparseCholesky L;
    ASSERT_TRUE(L.Factorize(Sparse(A), 12).ok());
    Eigen::VectorXd b = Eigen::VectorXd::Random(n);
    Eigen::VectorXd x = A.ldlt().solve(b);
    int dim = n;
    for (int step = 0; step < 4; ++step) {
      // An update on an old variable, the last one and (from step 1) two new ones, and a
      // change of b on those rows.
      std::vector<int> rows = {step * 7, dim - 1};
      const int added = step == 0 ? 0 : 2;
      for (int a = 0; a < added; ++a) rows.push_back(dim + a);
      const Eigen::MatrixXd W = Eigen::MatrixXd::Random(static_cast<int>(rows.size()), 3);
      const Eigen::MatrixXd grown = Grown(A, added, rows, W);
      Eigen::VectorXd b_new = Eigen::VectorXd::Zero(dim + added);
      b_new.head(dim) = b;
      Eigen::VectorXd delta_b = Eigen::VectorXd::Random(static_cast<int>(rows.size()));
      for (size_t r = 0; r < rows.size(); ++r) b_new[rows[r]] += delta_b[static_cast<Eigen::Index>(r)];
      ASSERT_TRUE(L.Update(dim + added, rows, W).ok());
      Eigen::VectorXd x_before = Eigen::VectorXd::Zero(dim + added);
      x_before.head(dim) = x;
      const Eigen::VectorXd residual = b_new - grown * x_before;
      Eigen::VectorXd r_local(static_cast<int>(rows.size()));
      for (size_t r = 0; r < rows.size(); ++r) r_local[static_cast<Eigen::Index>(r)] = residual[rows[r]];
      // The residual is zero off the update's rows (x solved the system before).
      for (int i = 0; i < dim + added; ++i) {
        if (std::find(rows.begin(), rows.end(), i) == rows.end()) {
          EXPECT_NEAR(residual[i], 0.0, 1e-9);
        }
      }
      x = x_before;
      std::vector<int> changed;
      L.SolveChange(rows, r_local, threshold, &x, &changed);
      const Eigen::VectorXd exact = grown.ldlt().solve(b_new);
      const double tolerance = threshold == 0.0 ? 1e-9 : 1e3 * threshold;
      EXPECT_LT((x - exact).cwiseAbs().maxCoeff(), tolerance) << "step " << step;
      for (int i = 0; i < dim + added; ++i) {
        const bool reported = std::find(changed.begin(), changed.end(), i) != changed.end();
        if (!reported) {
          EXPECT_EQ(x[i], x_before[i]) << i;
        }
      }
      A = grown;
      b = b_new;
      dim += added;
      if (threshold == 0.0) x = exact;  // the next step starts from the exact solution
    }
  }
}

// A chain's end variable ordered last: extending the chain from it (an update on it and
// a new variable) fills no column on the way, where minimum degree alone eliminates the
// end of a path first and the update fills a column per variable on its path to the root.
TEST(SparseCholesky, VariablesOrderedLastKeepAnExtendingUpdateCheap) {
  const int n = 400;
  Eigen::MatrixXd A = 2.0 * Eigen::MatrixXd::Identity(n, n);
  for (int i = 0; i + 1 < n; ++i) A(i, i + 1) = A(i + 1, i) = -0.9;
  const std::vector<int> rows = {n - 1, n};
  const Eigen::MatrixXd W = (Eigen::MatrixXd(2, 2) << 1.0, 0.3, -1.0, 0.7).finished();
  const Eigen::MatrixXd grown = Grown(A, 1, rows, W);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(n + 1, -1.0, 1.0);
  for (FillReducingOrdering ordering : {FillReducingOrdering::kAmd, FillReducingOrdering::kNestedDissection}) {
    SparseCholesky constrained, free;
    ASSERT_TRUE(constrained.Factorize(Sparse(A), 4, ordering, {n - 1}).ok());
    ASSERT_TRUE(free.Factorize(Sparse(A), 4, ordering).ok());
    ASSERT_TRUE(constrained.Update(n + 1, rows, W).ok());
    ASSERT_TRUE(free.Update(n + 1, rows, W).ok());
    EXPECT_LE(constrained.nonzeros() - constrained.nonzeros_after_factorize(), 3);
    if (ordering == FillReducingOrdering::kAmd) {  // minimum degree puts a path's end first
      EXPECT_GT(free.nonzeros() - free.nonzeros_after_factorize(), 100);
    }
    EXPECT_TRUE(MatricesNear(grown.ldlt().solve(b), constrained.Solve(b), 1e-9));
    EXPECT_TRUE(MatricesNear(grown.ldlt().solve(b), free.Solve(b), 1e-9));
  }
  SparseCholesky bad;
  EXPECT_FALSE(bad.Factorize(Sparse(A), 4, FillReducingOrdering::kAmd, {n}).ok());
}

// A 2-D grid of side × side variables, each linked to its right and lower neighbours
// with random weights: the graph on which nested dissection and minimum degree differ.
Eigen::MatrixXd Grid(int side, std::mt19937_64* rng) {
  const int n = side * side;
  std::uniform_real_distribution<double> weight(0.5, 2.0);
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(n, n);
  const auto link = [&](int a, int b) {
    const double w = weight(*rng);
    A(a, a) += w;
    A(b, b) += w;
    A(a, b) -= w;
    A(b, a) -= w;
  };
  for (int r = 0; r < side; ++r) {
    for (int c = 0; c < side; ++c) {
      if (c + 1 < side) link(r * side + c, r * side + c + 1);
      if (r + 1 < side) link(r * side + c, (r + 1) * side + c);
    }
  }
  return A;
}

// The same grid stored sparse only, for grids too large for dense checks.
Eigen::SparseMatrix<double> SparseGrid(int side, std::mt19937_64* rng) {
  const int n = side * side;
  std::uniform_real_distribution<double> weight(0.5, 2.0);
  std::vector<Eigen::Triplet<double>> entries;
  for (int k = 0; k < n; ++k) entries.emplace_back(k, k, 1.0);
  const auto link = [&](int a, int b) {
    const double w = weight(*rng);
    entries.emplace_back(a, a, w);
    entries.emplace_back(b, b, w);
    entries.emplace_back(a, b, -w);
    entries.emplace_back(b, a, -w);
  };
  for (int r = 0; r < side; ++r) {
    for (int c = 0; c < side; ++c) {
      if (c + 1 < side) link(r * side + c, r * side + c + 1);
      if (r + 1 < side) link(r * side + c, (r + 1) * side + c);
    }
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(entries.begin(), entries.end());
  return A;
}

// A factor ordered by METIS nested dissection is another factor of the same matrix:
// solves, inverse blocks and rank updates with new variables agree with the dense
// algebra and with the AMD-ordered factor; the analysis is reused only for the ordering
// it was made with.
TEST(SparseCholesky, NestedDissectionOrderingFactorizesTheSameMatrix) {
  std::mt19937_64 rng(6);
  const int side = 14, n = side * side, added = 3;
  const Eigen::MatrixXd A = Grid(side, &rng);
  SparseCholesky amd, nested;
  ASSERT_TRUE(amd.Factorize(Sparse(A), 4, FillReducingOrdering::kAmd).ok());
  ASSERT_TRUE(nested.Factorize(LowerOf(A), 4, FillReducingOrdering::kNestedDissection).ok());
  // Debian's CHOLMOD links METIS (libmetis5), so the ordering is METIS's: a different
  // permutation, hence a different fill of L.
  EXPECT_FALSE(nested.nested_dissection_unavailable());
  EXPECT_NE(nested.nonzeros(), amd.nonzeros());
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, 2);
  EXPECT_TRUE(MatricesNear(A.ldlt().solve(B), nested.Solve(B), 1e-10));
  const Eigen::MatrixXd inverse = A.inverse();
  const std::vector<int> vars = {0, n / 2, n - 1, 17};
  EXPECT_TRUE(MatricesNear(inverse(vars, vars), nested.InverseBlock(vars), 1e-10));
  EXPECT_TRUE(MatricesNear(amd.InverseBlock(vars), nested.InverseBlock(vars), 1e-10));
  const std::vector<Eigen::MatrixXd> diagonal = nested.DiagonalInverseBlocks({{0, 1}, {n - 1}});
  ASSERT_EQ(diagonal.size(), 2u);
  EXPECT_TRUE(MatricesNear(inverse({0, 1}, {0, 1}), diagonal[0], 1e-10));
  EXPECT_TRUE(MatricesNear(inverse({n - 1}, {n - 1}), diagonal[1], 1e-10));
  // New variables n … n + 2 linked to a corner and the centre.
  const std::vector<int> rows = {0, n / 2 + side / 2, n, n + 1, n + 2};
  const Eigen::MatrixXd W = Eigen::MatrixXd::Random(static_cast<int>(rows.size()), 5);
  const Eigen::MatrixXd grown = Grown(A, added, rows, W);
  ASSERT_TRUE(nested.Update(n + added, rows, W).ok());
  const Eigen::MatrixXd C = Eigen::MatrixXd::Random(n + added, 2);
  EXPECT_TRUE(MatricesNear(grown.ldlt().solve(C), nested.Solve(C), 1e-9));
  const std::vector<int> grown_vars = {n, n + 2, 0};
  EXPECT_TRUE(MatricesNear(grown.inverse()(grown_vars, grown_vars), nested.InverseBlock(grown_vars), 1e-9));
  // The analysis belongs to its ordering.
  ASSERT_TRUE(nested.Factorize(Sparse(A), 4, FillReducingOrdering::kNestedDissection).ok());
  EXPECT_EQ(nested.symbolic_reuses(), 1);
  ASSERT_TRUE(nested.Factorize(Sparse(A), 4, FillReducingOrdering::kAmd).ok());
  EXPECT_EQ(nested.symbolic_reuses(), 1);
  EXPECT_EQ(nested.nonzeros(), amd.nonzeros());
  EXPECT_EQ(nested.Solve(B), amd.Solve(B));  // the same ordering and arithmetic
}

// kAmdOrNestedDissection: on a chain AMD's factor costs a few flops per entry and stays;
// on a 60 × 60 grid it costs more than kNestedDissectionMinFlopsPerEntry, and nested
// dissection is taken (whose factor costs fewer flops there). Either way the factor is
// the one the chosen ordering gives alone.
TEST(SparseCholesky, AutomaticOrderingTakesNestedDissectionWhereAmdsFactorIsCostly) {
  std::mt19937_64 rng(7);
  const auto flops_per_entry = [](const SparseCholesky& L, const Eigen::SparseMatrix<double>& A) {
    return L.factorization_flops() / (0.5 * (static_cast<double>(A.nonZeros()) + static_cast<double>(A.rows())));
  };
  {
    const Eigen::SparseMatrix<double> chain = Sparse(TwoChains(300, 0, &rng));
    SparseCholesky automatic, amd;
    ASSERT_TRUE(automatic.Factorize(chain, 4, FillReducingOrdering::kAmdOrNestedDissection).ok());
    ASSERT_TRUE(amd.Factorize(chain, 4, FillReducingOrdering::kAmd).ok());
    EXPECT_LT(flops_per_entry(amd, chain), SparseCholesky::kNestedDissectionMinFlopsPerEntry);
    EXPECT_EQ(automatic.ordering(), FillReducingOrdering::kAmd);
    EXPECT_EQ(automatic.nonzeros(), amd.nonzeros());
  }
  const Eigen::SparseMatrix<double> grid = SparseGrid(60, &rng);
  SparseCholesky automatic, amd, nested;
  ASSERT_TRUE(automatic.Factorize(grid, 4, FillReducingOrdering::kAmdOrNestedDissection).ok());
  ASSERT_TRUE(amd.Factorize(grid, 4, FillReducingOrdering::kAmd).ok());
  ASSERT_TRUE(nested.Factorize(grid, 4, FillReducingOrdering::kNestedDissection).ok());
  EXPECT_GE(flops_per_entry(amd, grid), SparseCholesky::kNestedDissectionMinFlopsPerEntry);
  EXPECT_LT(nested.factorization_flops(), amd.factorization_flops());
  EXPECT_EQ(automatic.ordering(), FillReducingOrdering::kNestedDissection);
  EXPECT_EQ(automatic.factorization_flops(), nested.factorization_flops());
  EXPECT_EQ(automatic.nonzeros(), nested.nonzeros());
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(grid.rows(), 2);
  EXPECT_LT((grid * automatic.Solve(B) - B).norm(), 1e-10 * B.norm());
  // Refactorising the same pattern reuses the chosen analysis.
  ASSERT_TRUE(automatic.Factorize(grid, 4, FillReducingOrdering::kAmdOrNestedDissection).ok());
  EXPECT_EQ(automatic.symbolic_reuses(), 1);
  EXPECT_EQ(automatic.ordering(), FillReducingOrdering::kNestedDissection);
  // Once switched, nested dissection stays, even for a matrix AMD would factorise cheaply.
  const Eigen::SparseMatrix<double> chain = Sparse(TwoChains(300, 0, &rng));
  ASSERT_TRUE(automatic.Factorize(chain, 4, FillReducingOrdering::kAmdOrNestedDissection).ok());
  EXPECT_EQ(automatic.ordering(), FillReducingOrdering::kNestedDissection);
  const Eigen::VectorXd b = Eigen::VectorXd::Random(chain.rows());
  EXPECT_LT((chain * automatic.Solve(b) - b).norm(), 1e-10 * b.norm());
  // A copy (as a cloned EIF's) is exact — its solves equal the original's bit for bit,
  // also after the same rank update on both — and keeps the switch: refactorised, it
  // orders the chain by nested dissection too, where a fresh factor takes AMD.
  SparseCholesky copy(automatic), fresh;
  EXPECT_EQ(copy.Solve(b), automatic.Solve(b));
  const std::vector<int> rows = {3, 17};
  const Eigen::MatrixXd W = Eigen::MatrixXd::Random(2, 1);
  ASSERT_TRUE(copy.Update(copy.dim(), rows, W).ok());
  ASSERT_TRUE(automatic.Update(automatic.dim(), rows, W).ok());
  EXPECT_EQ(copy.Solve(b), automatic.Solve(b));
  ASSERT_TRUE(copy.Factorize(chain, 4, FillReducingOrdering::kAmdOrNestedDissection).ok());
  ASSERT_TRUE(fresh.Factorize(chain, 4, FillReducingOrdering::kAmdOrNestedDissection).ok());
  EXPECT_EQ(copy.ordering(), FillReducingOrdering::kNestedDissection);
  EXPECT_EQ(fresh.ordering(), FillReducingOrdering::kAmd);
}

// The ordering's names (flag --eif_ordering) round-trip; anything else is rejected with
// the accepted names.
// A refactorisation with A's pattern reuses the symbolic analysis — also after rank
// updates have grown the factor's pattern — and equals a fresh factorisation; a
// different pattern (an entry more, or more spare slots) is analysed again.
TEST(SparseCholesky, RefactorizingTheSamePatternReusesTheAnalysis) {
  std::mt19937_64 rng(4);
  const int n = 40;
  const Eigen::MatrixXd A = RandomSpd(n, &rng);
  Eigen::MatrixXd A2 = A;  // the same pattern, other values
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      if (A(r, c) != 0.0) A2(r, c) = r == c ? A(r, c) + 1.0 : 0.5 * A(r, c);
    }
  }
  SparseCholesky L;
  ASSERT_TRUE(L.Factorize(Sparse(A), 5).ok());
  ASSERT_TRUE(L.Update(n + 1, {2, n}, Eigen::MatrixXd::Ones(2, 1)).ok());
  ASSERT_TRUE(L.Factorize(Sparse(A2), 5).ok());
  EXPECT_EQ(L.symbolic_reuses(), 1);
  SparseCholesky fresh;
  ASSERT_TRUE(fresh.Factorize(Sparse(A2), 5).ok());
  EXPECT_EQ(fresh.symbolic_reuses(), 0);
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, 2);
  EXPECT_TRUE(MatricesNear(A2.ldlt().solve(B), L.Solve(B), 1e-10));
  EXPECT_EQ(L.Solve(B), fresh.Solve(B));  // the same ordering and arithmetic
  EXPECT_EQ(L.nonzeros(), fresh.nonzeros());
  const std::vector<int> vars = {0, 17, 39};
  EXPECT_TRUE(MatricesNear(A2.inverse()(vars, vars), L.InverseBlock(vars), 1e-10));
  // An entry more: analysed again.
  Eigen::MatrixXd A3 = A2;
  int far = n - 1;
  while (far > 0 && A3(0, far) != 0.0) --far;
  ASSERT_GT(far, 0);
  A3(0, far) = A3(far, 0) = 0.01;
  ASSERT_TRUE(L.Factorize(Sparse(A3), 5).ok());
  EXPECT_EQ(L.symbolic_reuses(), 1);
  EXPECT_TRUE(MatricesNear(A3.ldlt().solve(B), L.Solve(B), 1e-10));
  // More spare slots: analysed again.
  ASSERT_TRUE(L.Factorize(Sparse(A3), 9).ok());
  EXPECT_EQ(L.symbolic_reuses(), 1);
  EXPECT_EQ(L.capacity(), n + 9);
  ASSERT_TRUE(L.Factorize(Sparse(A3), 9).ok());
  EXPECT_EQ(L.symbolic_reuses(), 2);
  EXPECT_TRUE(MatricesNear(A3.ldlt().solve(B), L.Solve(B), 1e-10));
  // The same stored pattern for another n (a last variable alone on the diagonal, or a
  // spare slot there): analysed again, so the spare slots stay last in the ordering.
  Eigen::MatrixXd D = Eigen::MatrixXd::Identity(6, 6);
  D.topLeftCorner(5, 5) = RandomSpd(5, &rng) + Eigen::MatrixXd::Ones(5, 5);
  SparseCholesky M;
  ASSERT_TRUE(M.Factorize(Sparse(D), 2).ok());
  ASSERT_TRUE(M.Factorize(Sparse(Eigen::MatrixXd(D.topLeftCorner(5, 5))), 3).ok());
  EXPECT_EQ(M.symbolic_reuses(), 0);
}

TEST(SparseCholesky, LowerTriangleInputEqualsTheMatrixInput) {
  std::mt19937_64 rng(4);
  const Eigen::MatrixXd A = RandomSpd(25, &rng);
  SparseCholesky from_matrix, from_lower;
  ASSERT_TRUE(from_matrix.Factorize(Sparse(A), 6).ok());
  ASSERT_TRUE(from_lower.Factorize(LowerOf(A), 6).ok());
  EXPECT_EQ(from_lower.capacity(), 31);
  EXPECT_EQ(from_lower.nonzeros(), from_matrix.nonzeros());
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(25, 2);
  EXPECT_EQ(from_lower.Solve(B), from_matrix.Solve(B));  // the same input, to the bit
  EXPECT_TRUE(MatricesNear(A.ldlt().solve(B), from_lower.Solve(B), 1e-10));
}

TEST(SparseCholesky, RejectsAMalformedLowerTriangle) {
  std::mt19937_64 rng(5);
  const SparseLowerTriangle good = LowerOf(RandomSpd(6, &rng));
  SparseCholesky L;
  ASSERT_TRUE(L.Factorize(good, 2).ok());
  const Eigen::MatrixXd B = Eigen::MatrixXd::Random(6, 1);
  const Eigen::MatrixXd solved = L.Solve(B);
  SparseLowerTriangle above = good;  // a row above the diagonal
  above.i[above.p[2]] = 1;
  SparseLowerTriangle unsorted = good;  // a column's rows out of order
  ASSERT_GT(good.p[1] - good.p[0], 1);
  std::swap(unsorted.i[0], unsorted.i[1]);
  SparseLowerTriangle short_p = good;  // p without its last entry
  short_p.p.pop_back();
  SparseLowerTriangle out_of_range = good;  // a row beyond n
  out_of_range.i[out_of_range.p[6] - 1] = 6;
  SparseLowerTriangle backwards = good;  // a column that ends before it starts
  backwards.p[1] = backwards.p[2] + 1;
  SparseLowerTriangle short_x = good;  // fewer values than rows
  short_x.x.pop_back();
  for (const SparseLowerTriangle* bad : {&above, &unsorted, &short_p, &out_of_range, &backwards, &short_x}) {
    const absl::Status st = L.Factorize(*bad, 2);
    EXPECT_EQ(st.code(), absl::StatusCode::kInvalidArgument) << st;
    // Nothing changed: the previous factor still solves.
    ASSERT_TRUE(L.ready());
    EXPECT_EQ(L.Solve(B), solved);
  }
}

TEST(SparseCholesky, RejectsWhatItCannotDo) {
  std::mt19937_64 rng(3);
  const Eigen::MatrixXd A = RandomSpd(10, &rng);
  SparseCholesky L;
  EXPECT_FALSE(L.Update(10, {0}, Eigen::MatrixXd::Ones(1, 1)).ok());  // nothing factorised
  ASSERT_TRUE(L.Factorize(Sparse(A), 2).ok());
  EXPECT_FALSE(L.Update(13, {12}, Eigen::MatrixXd::Ones(1, 1)).ok());  // beyond the spare slots
  Eigen::MatrixXd indefinite = -Eigen::MatrixXd::Identity(4, 4);
  EXPECT_FALSE(L.Factorize(Sparse(indefinite), 0).ok());
  EXPECT_FALSE(L.ready());
}

}  // namespace
}  // namespace subslam::backend
