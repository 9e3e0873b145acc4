#include "subslam/backend/eif_joiner.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "subslam/backend/internal/sparse_cholesky.h"
#include "state_blocks.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/graph/stage_timer.h"
#include "subslam/graph/check.h"
#include "subslam/models/gating.h"

namespace subslam::backend {

struct EifJoiner::Solver {
  SparseCholesky factor;
  SparseLowerTriangle lambda_lower;  // Λ's lower triangle (see lambda_factors_)
  Eigen::MatrixXd last_whitened_jacobian;  // of the newest factor, for the incremental update
  bool stale = false;  // the factor no longer matches Λ (a rejected join was undone)
};

absl::Status EifJoinerOptions::Validate() const {
  if (absl::Status s = association.Validate(); !s.ok()) return s;
  if (absl::Status s = revision.Validate(); !s.ok()) return s;
  if (!(validation_probability > 0 && validation_probability < 1)) {
    return absl::InvalidArgumentError("validation_probability must be in (0, 1)");
  }
  if (loop_confirmation_maps < 0) {
    return absl::InvalidArgumentError(absl::StrCat("loop_confirmation_maps must be >= 0, got ", loop_confirmation_maps));
  }
  if (!(loop_confirmation_min_sigma_radius_m >= 0 && std::isfinite(loop_confirmation_min_sigma_radius_m))) {
    return absl::InvalidArgumentError(absl::StrCat("loop_confirmation_min_sigma_radius_m must be finite and >= 0 [m], got ",
                                                   loop_confirmation_min_sigma_radius_m));
  }
  if (relinearize_every < 0) {
    return absl::InvalidArgumentError(absl::StrCat("relinearize_every must be >= 0, got ", relinearize_every));
  }
  if (max_relinearizations < 1) {
    return absl::InvalidArgumentError(absl::StrCat("max_relinearizations must be >= 1, got ", max_relinearizations));
  }
  if (!(relinearize_step_chi2 >= 0)) {
    return absl::InvalidArgumentError(absl::StrCat("relinearize_step_chi2 must be >= 0, got ", relinearize_step_chi2));
  }
  if (!(relinearize_tolerance > 0)) {
    return absl::InvalidArgumentError(absl::StrCat("relinearize_tolerance must be > 0, got ", relinearize_tolerance));
  }
  if (divergence_rises < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("divergence_rises (--relinearize_max_rises) must be >= 0, got ", divergence_rises));
  }
  if (!(relinearize_linearization_chi2 >= 0)) {
    return absl::InvalidArgumentError(absl::StrCat("relinearize_linearization_chi2 must be >= 0, got ",
                                                   relinearize_linearization_chi2));
  }
  if (!(relinearize_heading_change >= 0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("relinearize_heading_change must be >= 0 [rad], got ", relinearize_heading_change));
  }
  return absl::OkStatus();
}

bool EifJoinerOptions::RelinearizesAfterJoins() const {
  return relinearize_linearization_chi2 > 0 || relinearize_heading_change > 0;
}

EifJoinerOptions EifJoinerOptions::SingleLinearization() const {
  EifJoinerOptions o = *this;
  o.relinearize_heading_change = 0.0;
  o.relinearize_linearization_chi2 = 0.0;
  o.relinearize_every = 0;
  o.relinearize_at_end = false;
  o.revision.merge = o.revision.split = false;  // a revision relinearises every factor
  return o;
}

EifJoiner::EifJoiner(const Pose2& initial_pose, const EifJoinerOptions& options)
    : options_(options),
      graph_(initial_pose),
      solver_(std::make_unique<Solver>()),
      associator_(options.association) {
  SUBSLAM_CHECK(options_.Validate().ok()) << options_.Validate().message();
  anchor_offset_.push_back(-1);  // P0 is fixed
  anchor_theta_.push_back(initial_pose.theta);
  for (const char* stage : {"association", "covariance_recovery", "update", "factorization", "recovery"}) {
    times_[stage] = 0.0;
  }
}

EifJoiner::~EifJoiner() = default;

Eigen::VectorXd EifJoiner::StateVector() const {
  Eigen::VectorXd x(dim_);
  for (int k = 1; k < graph_.num_anchors(); ++k) {
    const Pose2& p = graph_.anchors()[k];
    x.segment<3>(anchor_offset_[k]) << p.x, p.y, anchor_theta_[k];
  }
  for (int j = 0; j < graph_.num_landmarks(); ++j) {
    x.segment<2>(landmark_offset_[j]) = graph_.landmarks()[j];
  }
  return x;
}

void EifJoiner::SetState(const Eigen::VectorXd& x) {
  for (int k = 1; k < graph_.num_anchors(); ++k) {
    const Eigen::Vector3d v = x.segment<3>(anchor_offset_[k]);
    anchor_theta_[k] = v[2];
    graph_.anchor(k) = Pose2(v[0], v[1], WrapAngle(v[2]));
  }
  for (int j = 0; j < graph_.num_landmarks(); ++j) {
    graph_.landmark(j) = x.segment<2>(landmark_offset_[j]);
  }
}

EifJoiner::Factor EifJoiner::MakeFactor(int index) const {
  const SubmapFactor& record = graph_.factors()[index];
  Factor f;
  f.index = index;
  const Eigen::LLT<Eigen::MatrixXd> llt(record.submap.covariance);
  SUBSLAM_CHECK(llt.info() == Eigen::Success) << "local map covariance not positive definite";
  f.covariance_sqrt = std::make_shared<const Eigen::MatrixXd>(llt.matrixL());
  if (options_.relinearize_linearization_chi2 > 0) {  // LinearizationErrorAbove's screen
    f.covariance_min_eigenvalue =
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(record.submap.covariance, Eigen::EigenvaluesOnly)
            .eigenvalues()
            .minCoeff();
  }
  SetLayout(&f);
  return f;
}

void EifJoiner::SetLayout(Factor* f) const {
  const SubmapFactor& record = graph_.factors()[f->index];
  f->offsets.clear();
  f->sizes.clear();
  if (record.start_anchor != 0) {
    f->offsets.push_back(anchor_offset_[record.start_anchor]);
    f->sizes.push_back(3);
  }
  f->offsets.push_back(anchor_offset_[record.end_anchor]);
  f->sizes.push_back(3);
  for (int j : record.landmark_of_feature) {
    f->offsets.push_back(landmark_offset_[j]);
    f->sizes.push_back(2);
  }
}

void EifJoiner::RecordLinearizationPoint(Factor* f, const Pose2& start, const Pose2& end) const {
  const SubmapFactor& record = graph_.factors()[f->index];
  f->start_theta = start.theta;
  f->end_theta = end.theta;
  const Eigen::Vector2d p_s(start.x, start.y);
  f->levers.resize(record.landmark_of_feature.size() + 1);
  f->levers[0] = Eigen::Vector2d(end.x, end.y) - p_s;
  for (size_t i = 0; i < record.landmark_of_feature.size(); ++i) {
    f->levers[i + 1] = graph_.landmarks()[record.landmark_of_feature[i]] - p_s;
  }
}

void EifJoiner::Linearize(Factor* f, Eigen::MatrixXd* whitened_jacobian) const {
  if (whitened_jacobian == nullptr) {
    LinearizeStructured(f);
    return;
  }
  const SubmapFactor& record = graph_.factors()[f->index];
  const LocalSubmap& s = record.submap;
  const Pose2 start = AnchorPose(record.start_anchor), end = AnchorPose(record.end_anchor);
  const std::vector<Eigen::Vector2d> landmarks = FactorLandmarks(record);
  const SubmapFactorLinearization lin = LinearizeSubmapFactor(s, start, end, landmarks);
  RecordLinearizationPoint(f, start, end);

  // Stack the Jacobian over the variable blocks (P0, fixed, has none) and x̂.
  const bool start_fixed = record.start_anchor == 0;
  const int m = static_cast<int>(lin.residual.size());
  const int cols = (start_fixed ? 0 : 3) + 3 + 2 * s.num_landmarks();
  Eigen::MatrixXd J(m, cols);
  Eigen::VectorXd x(cols);
  int c = 0;
  if (!start_fixed) {
    J.middleCols<3>(c) = lin.J_start;
    x.segment<3>(c) = start.vector();
    c += 3;
  }
  J.middleCols<3>(c) = lin.J_end;
  x.segment<3>(c) = end.vector();
  c += 3;
  J.rightCols(2 * s.num_landmarks()) = lin.J_landmarks;
  for (int i = 0; i < s.num_landmarks(); ++i) x.segment<2>(c + 2 * i) = landmarks[i];

  // Whiten with Q = L Lᵀ: A = L⁻¹ J, e = L⁻¹ (J x̂ − r).
  const auto L = f->covariance_sqrt->triangularView<Eigen::Lower>();
  Eigen::MatrixXd A = J;
  L.solveInPlace(A);
  Eigen::VectorXd e = J * x - lin.residual;
  L.solveInPlace(e);
  f->H = A.transpose() * A;
  f->b = A.transpose() * e;
  *whitened_jacobian = std::move(A);
}

// H = Jᵀ Q⁻¹ J and b = Jᵀ Q⁻¹ (J x̂ − r) from J's structure, without whitening: J's
// anchor columns J_a are dense (m × 3 or 6), and its landmark columns hold one 2 × 2 block
// R_i = ∂r_i/∂L_i in feature i's rows only. With W = Q⁻¹ (kept per factor):
//   H_aa = J_aᵀ W J_a,  H_a,i = (W J_a)_iᵀ R_i,  H_i,k = R_iᵀ W_ik R_k,
//   b_a = J_aᵀ w,  b_i = R_iᵀ w_i,  w = W (J x̂ − r),
// O(m² · 6) instead of the O(m³) triangular solve and product (m = 3 + 2n).
void EifJoiner::LinearizeStructured(Factor* f) const {
  const SubmapFactor& record = graph_.factors()[f->index];
  const LocalSubmap& s = record.submap;
  const Pose2 start = AnchorPose(record.start_anchor), end = AnchorPose(record.end_anchor);
  RecordLinearizationPoint(f, start, end);
  const int n = s.num_landmarks(), m = 3 + 2 * n;
  const bool start_fixed = record.start_anchor == 0;
  const int na = start_fixed ? 3 : 6;
  Eigen::MatrixXd J_a = Eigen::MatrixXd::Zero(m, na);
  Eigen::VectorXd x_a(na), r(m), Jx(m);
  Eigen::Matrix3d J_s, J_e;
  const Pose2 relative = Between(start, end, &J_s, &J_e);
  r.head<3>() = relative.vector() - s.mean.head<3>();
  r[2] = WrapAngle(r[2]);
  if (!start_fixed) {
    J_a.topLeftCorner<3, 3>() = J_s;
    x_a.head<3>() = start.vector();
  }
  J_a.block<3, 3>(0, na - 3) = J_e;
  x_a.tail<3>() = end.vector();
  std::vector<Eigen::Matrix2d> R(n);
  std::vector<Eigen::Vector2d> landmarks(n);
  for (int i = 0; i < n; ++i) {
    landmarks[i] = graph_.landmarks()[record.landmark_of_feature[i]];
    Matrix23d J_frame;
    r.segment<2>(3 + 2 * i) = TransformTo(start, landmarks[i], &J_frame, &R[i]) - s.landmark(i);
    if (!start_fixed) J_a.block<2, 3>(3 + 2 * i, 0) = J_frame;
  }
  Jx.noalias() = J_a * x_a;
  for (int i = 0; i < n; ++i) Jx.segment<2>(3 + 2 * i) += R[i] * landmarks[i];
  if (f->information == nullptr) {  // Q⁻¹ = L⁻ᵀ L⁻¹, once per factor
    Eigen::MatrixXd L_inv = Eigen::MatrixXd::Identity(m, m);
    f->covariance_sqrt->triangularView<Eigen::Lower>().solveInPlace(L_inv);
    Eigen::MatrixXd information = L_inv.transpose() * L_inv;
    f->information = std::make_shared<const Eigen::MatrixXd>(0.5 * (information + information.transpose()));
  }
  const Eigen::MatrixXd& W = *f->information;
  const Eigen::MatrixXd WJ_a = W * J_a;
  const Eigen::VectorXd w = W * (Jx - r);
  const int cols = na + 2 * n;
  f->H.resize(cols, cols);
  f->b.resize(cols);
  f->H.topLeftCorner(na, na).noalias() = J_a.transpose() * WJ_a;
  f->H.topLeftCorner(na, na) = 0.5 * (f->H.topLeftCorner(na, na) + f->H.topLeftCorner(na, na).transpose()).eval();
  f->b.head(na).noalias() = J_a.transpose() * w;
  for (int i = 0; i < n; ++i) {
    const Eigen::MatrixXd cross = WJ_a.middleRows<2>(3 + 2 * i).transpose() * R[i];  // na × 2
    f->H.block(0, na + 2 * i, na, 2) = cross;
    f->H.block(na + 2 * i, 0, 2, na) = cross.transpose();
    f->b.segment<2>(na + 2 * i) = R[i].transpose() * w.segment<2>(3 + 2 * i);
    for (int k = 0; k <= i; ++k) {  // H symmetric to the bit
      f->H.block<2, 2>(na + 2 * i, na + 2 * k) = R[i].transpose() * W.block<2, 2>(3 + 2 * i, 3 + 2 * k) * R[k];
      if (k < i) f->H.block<2, 2>(na + 2 * k, na + 2 * i) = f->H.block<2, 2>(na + 2 * i, na + 2 * k).transpose();
    }
  }
}

template <typename Visit>
void EifJoiner::ForEachEntry(const Factor& f, Visit visit) {
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

void EifJoiner::AddInformationTimes(const Factor& f, const Eigen::VectorXd& x, Eigen::VectorXd* y) const {
  Eigen::VectorXd local(f.H.rows());
  int row = 0;
  for (size_t a = 0; a < f.offsets.size(); ++a) {
    local.segment(row, f.sizes[a]) = x.segment(f.offsets[a], f.sizes[a]);
    row += f.sizes[a];
  }
  const Eigen::VectorXd product = f.H * local;
  row = 0;
  for (size_t a = 0; a < f.offsets.size(); ++a) {
    y->segment(f.offsets[a], f.sizes[a]) += product.segment(row, f.sizes[a]);
    row += f.sizes[a];
  }
}

double EifJoiner::InformationNorm(const Eigen::VectorXd& x) const {
  Eigen::VectorXd Lambda_x = Eigen::VectorXd::Zero(x.size());
  for (const Factor& f : factors_) AddInformationTimes(f, x, &Lambda_x);
  return x.dot(Lambda_x);
}

void EifJoiner::AddToEta(const Factor& f, Eigen::VectorXd* eta) const {
  int row = 0;
  for (size_t a = 0; a < f.offsets.size(); ++a) {
    eta->segment(f.offsets[a], f.sizes[a]) += f.b.segment(row, f.sizes[a]);
    row += f.sizes[a];
  }
}

std::vector<int> EifJoiner::FactorOffsets() const {
  std::vector<int> offsets;
  for (const Factor& f : factors_) {
    offsets.push_back(static_cast<int>(f.offsets.size()));
    offsets.insert(offsets.end(), f.offsets.begin(), f.offsets.end());
  }
  return offsets;
}

const Eigen::SparseMatrix<double>& EifJoiner::information() const {
  const SparseLowerTriangle& lower = LowerInformation();
  if (lambda_full_valid_ && Lambda_.rows() == dim_) return Lambda_;
  // Both triangles from the lower one.
  const Eigen::Map<const Eigen::SparseMatrix<double>> lower_view(lower.n, lower.n, lower.p[lower.n], lower.p.data(),
                                                                  lower.i.data(), lower.x.data());
  Lambda_ = lower_view.selfadjointView<Eigen::Lower>();
  lambda_full_valid_ = true;
  return Lambda_;
}

void EifJoiner::FillLambdaValues(size_t first_factor, std::vector<double>* values) const {
  values->assign(solver_->lambda_lower.i.size(), 0.0);
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

const SparseLowerTriangle& EifJoiner::LowerInformation() const {
  if (lambda_factors_ == factors_.size() && solver_->lambda_lower.n == dim_) return solver_->lambda_lower;
  lambda_full_valid_ = false;
  if (lambda_factors_ == 0 && solver_->lambda_lower.n == dim_ && !lambda_slots_.empty() &&
      FactorOffsets() == lambda_slot_offsets_) {
    // The same factors over the same variables (relinearised): refill Λ's values.
    FillLambdaValues(0, &solver_->lambda_lower.x);
    lambda_factors_ = factors_.size();
    return solver_->lambda_lower;
  }
  if (lambda_factors_ > 0 && solver_->lambda_lower.n <= dim_) {
    // Joins since the last assembly, the older factors unchanged: the new pattern, the
    // old sums carried over and the new factors' sum added to them (Λ_old + ΔΛ, as
    // assembling ΔΛ on its own and adding it would).
    const SparseLowerTriangle old = std::move(solver_->lambda_lower);
    BuildLambdaPattern();
    std::vector<double> added;
    FillLambdaValues(lambda_factors_, &added);
    std::vector<double>& x = solver_->lambda_lower.x;
    x.assign(solver_->lambda_lower.i.size(), 0.0);
    for (int c = 0; c < old.n; ++c) {  // the old pattern lies within the new one, columns sorted
      int k = solver_->lambda_lower.p[c];
      for (int q = old.p[c]; q < old.p[c + 1]; ++q) {
        while (k < solver_->lambda_lower.p[c + 1] && solver_->lambda_lower.i[k] != old.i[q]) ++k;
        SUBSLAM_CHECK(k < solver_->lambda_lower.p[c + 1]) << "Λ's old pattern is not within the new one, column " << c;
        x[k] = old.x[q];
      }
    }
    for (size_t k = 0; k < x.size(); ++k) x[k] += added[k];
    lambda_factors_ = factors_.size();
    return solver_->lambda_lower;
  }
  // Relinearised factors over a new pattern: Λ's structure is built from the factors'
  // variable blocks, and each H entry's place in Λ's values is recorded for the refill
  // above and the next ones.
  BuildLambdaPattern();
  FillLambdaValues(0, &solver_->lambda_lower.x);
  lambda_factors_ = factors_.size();
  return solver_->lambda_lower;
}

void EifJoiner::BuildLambdaPattern() const {
  // Each variable block by its first row: its size and the sorted first rows of the
  // blocks it shares a factor with (itself included), all lists in one flat array
  // (block o's from first[o], unique ones first, length unique[o]).
  std::vector<int> size_of(dim_, 0), first(dim_ + 1, 0), unique(dim_, 0);
  size_t count = 0;
  for (const Factor& f : factors_) {
    count += static_cast<size_t>(f.H.size());
    for (size_t b = 0; b < f.offsets.size(); ++b) {
      size_of[f.offsets[b]] = f.sizes[b];
      first[f.offsets[b] + 1] += static_cast<int>(f.offsets.size());
    }
  }
  for (int o = 0; o < dim_; ++o) first[o + 1] += first[o];
  std::vector<int> neighbour(static_cast<size_t>(first[dim_]));
  std::vector<int> fill(first.begin(), first.end() - 1);
  for (const Factor& f : factors_) {
    for (int b : f.offsets) {
      for (int a : f.offsets) neighbour[fill[b]++] = a;
    }
  }
  // The lower triangle: column j of block o holds rows j … of block o itself, then every
  // row of the neighbours after o. below[first[o] + k]: the rows of the neighbours after o
  // that come before neighbour k (k after o) in each of o's columns.
  std::vector<int> below(neighbour.size(), 0);
  std::vector<int> later_rows(dim_, 0);  // rows of the neighbours after block o
  for (int o = 0; o < dim_; ++o) {
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
  SparseLowerTriangle& lower = solver_->lambda_lower;
  lower.n = dim_;
  lower.p.assign(dim_ + 1, 0);
  for (int o = 0; o < dim_; ++o) {
    for (int j = 0; j < size_of[o]; ++j) lower.p[o + j + 1] = size_of[o] - j + later_rows[o];
  }
  for (int c = 0; c < dim_; ++c) lower.p[c + 1] += lower.p[c];
  const int nonzeros = lower.p[dim_];
  lower.i.resize(static_cast<size_t>(nonzeros));
  for (int o = 0; o < dim_; ++o) {
    for (int j = 0; j < size_of[o]; ++j) {
      int* row = lower.i.data() + lower.p[o + j];
      for (int i = j; i < size_of[o]; ++i) *row++ = o + i;
      for (int k = first[o]; k < first[o] + unique[o]; ++k) {
        if (neighbour[k] <= o) continue;
        for (int i = 0; i < size_of[neighbour[k]]; ++i) *row++ = neighbour[k] + i;
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
  lambda_slots_.resize(count);
  std::vector<int> where(dim_, -1), block_start;
  for (int o = 0; o < dim_; ++o) {
    if (size_of[o] == 0) continue;
    const int size_o = size_of[o];
    for (int k = first[o]; k < first[o] + unique[o]; ++k) {
      if (neighbour[k] > o) where[neighbour[k]] = below[k];
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
    for (int k = first[o]; k < first[o] + unique[o]; ++k) {
      if (neighbour[k] > o) where[neighbour[k]] = -1;
    }
  }
  lambda_slot_offsets_ = FactorOffsets();
}

long EifJoiner::factor_nonzeros() const { return solver_->factor.nonzeros(); }

FillReducingOrdering EifJoiner::factor_ordering() const { return solver_->factor.ordering(); }

absl::Status EifJoiner::FullFactorization() {
  StageTimer full(&times_, "full_factorization");
  SparseCholesky& L = solver_->factor;
  const long reuses = L.symbolic_reuses();
  // Spare slots for the next joins' new variables (about 15 % of the state).
  if (absl::Status st = L.Factorize(LowerInformation(), 64 + dim_ / 6, options_.ordering); !st.ok()) {
    return absl::InternalError(absl::StrCat("EIF: ", st.message()));
  }
  ++counters_.full_factorizations;
  if (L.ordering() == FillReducingOrdering::kNestedDissection) ++counters_.nested_dissection_factorizations;
  counters_.reused_analyses += L.symbolic_reuses() - reuses;
  return absl::OkStatus();
}

absl::Status EifJoiner::Rebuild(bool only_last_factor) {
  {
    StageTimer timer(&times_, "update");
    // Λ itself is assembled only when a full factorisation needs it (information()).
    if (only_last_factor) {
      const Eigen::Index old_dim = eta_.size();
      eta_.conservativeResize(dim_);
      eta_.tail(dim_ - old_dim).setZero();
      AddToEta(factors_.back(), &eta_);
    } else {
      // Every factor may have been relinearised: Λ need not have grown, so the marginal
      // bounds are forgotten.
      marginal_bound_.assign(graph_.num_landmarks(), Eigen::Matrix2d::Constant(NAN));
      eta_ = Eigen::VectorXd::Zero(dim_);
      for (const Factor& f : factors_) AddToEta(f, &eta_);
      lambda_factors_ = 0;
    }
  }
  bool incremental = false;
  {
    StageTimer timer(&times_, "factorization");
    SparseCholesky& L = solver_->factor;
    // The newest factor as a rank update of the existing factor, while there are spare
    // slots and the fill has not doubled since the last ordering.
    if (only_last_factor && options_.incremental_factorization && L.ready() && !solver_->stale &&
        dim_ <= L.capacity() &&
        L.nonzeros() <= options_.refactorize_fill_ratio * static_cast<double>(L.nonzeros_after_factorize())) {
      const Factor& f = factors_.back();
      std::vector<int> rows;
      for (size_t v = 0; v < f.offsets.size(); ++v) {
        for (int i = 0; i < f.sizes[v]; ++i) rows.push_back(f.offsets[v] + i);
      }
      incremental = L.Update(dim_, rows, solver_->last_whitened_jacobian.transpose()).ok();
      ++(incremental ? counters_.incremental_updates : counters_.failed_updates);
    }
    solver_->last_whitened_jacobian.resize(0, 0);
    solver_->stale = false;
    if (!incremental) {
      if (absl::Status st = FullFactorization(); !st.ok()) return st;
    }
  }
  Eigen::VectorXd x;
  {
    StageTimer timer(&times_, "recovery");
    x = solver_->factor.Solve(eta_);
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
      x = solver_->factor.Solve(eta_);
    }
  }
  if (!x.allFinite()) return absl::InternalError("EIF: state recovery produced a non-finite value");
  SetState(x);
  return absl::OkStatus();
}

Pose2 EifJoiner::AnchorPose(int k) const {
  const Pose2& p = graph_.anchors()[k];
  return Pose2(p.x, p.y, anchor_theta_[k]);
}

std::vector<Eigen::Vector2d> EifJoiner::FactorLandmarks(const SubmapFactor& record) const {
  std::vector<Eigen::Vector2d> landmarks;
  landmarks.reserve(record.landmark_of_feature.size());
  for (int j : record.landmark_of_feature) landmarks.push_back(graph_.landmarks()[j]);
  return landmarks;
}

double EifJoiner::NormalisedResidual(const Factor& f) const {
  const SubmapFactor& record = graph_.factors()[f.index];
  Eigen::VectorXd r = SubmapResidual(record.submap, AnchorPose(record.start_anchor), AnchorPose(record.end_anchor),
                                     FactorLandmarks(record));
  f.covariance_sqrt->triangularView<Eigen::Lower>().solveInPlace(r);  // rᵀ Q⁻¹ r = |L⁻¹ r|²
  return r.squaredNorm();
}

double EifJoiner::Cost() const {
  double cost = 0.0;
  for (const Factor& f : factors_) cost += NormalisedResidual(f);
  return cost;
}

void EifJoiner::SwapLinearization(Factor* f, Linearization* l) {
  f->H.swap(l->H);
  f->b.swap(l->b);
  std::swap(f->start_theta, l->start_theta);
  std::swap(f->end_theta, l->end_theta);
  f->levers.swap(l->levers);
}

bool EifJoiner::PredictedStepConverged(const Eigen::VectorXd& x) {
  // The factors are linearised at x: Σ_f (H_f x_f − b_f) = Σ_f J_fᵀ Q_f⁻¹ r_f(x) is the
  // gradient g of Cost()/2 at x, and the Gauss-Newton step is −Λ(x)⁻¹ g. The factor at
  // hand is of Λ at the previous linearisation point, a step away, whose headings differ
  // by that step's (the factor is nonlinear only through the headings): δ = −Λ_prev⁻¹ g.
  Eigen::VectorXd g = Eigen::VectorXd::Zero(dim_), eta = Eigen::VectorXd::Zero(dim_);
  for (const Factor& f : factors_) {
    AddInformationTimes(f, x, &g);
    AddToEta(f, &eta);
  }
  g -= eta;
  Eigen::VectorXd step;
  {
    StageTimer timer(&times_, "recovery");
    step = -solver_->factor.Solve(g);
  }
  if (!step.allFinite()) return false;
  // With each step at most half the last (linear convergence), the steps still to come sum
  // to less than twice this one: it is held to half the tolerance and a quarter of the χ²
  // bound, so that the stopped estimate is as close to the converged one as when a step
  // taken is below them.
  if (step.cwiseAbs().maxCoeff() < 0.5 * options_.relinearize_tolerance) return true;
  return options_.relinearize_step_chi2 > 0.0 && -g.dot(step) < 0.25 * options_.relinearize_step_chi2;
}

absl::Status EifJoiner::Relinearize() {
  if (absl::Status st = GaussNewton(); !st.ok()) return st;
  // Every factor moved, so the landmarks' marginal bounds were forgotten: today's exact
  // marginals, all at once from the sparse inverse, bound every later one until the next
  // relinearisation (Λ only grows), so association can skip candidates at once again.
  if (options_.bound_candidate_marginals && graph_.num_landmarks() > 0) {
    StageTimer timer(&times_, "covariance_recovery");
    marginal_bound_ = LandmarkCovariances();
  }
  return absl::OkStatus();
}

absl::Status EifJoiner::GaussNewton() {
  // Gauss-Newton need not lower the cost at every iteration (a first step often raises
  // it a little on the way to a lower minimum), but `divergence_rises` rises in a row
  // mean divergence (seen with wrong associations): then the best iterate is restored —
  // the factors' linearisation whose solution it was — and the iterations end.
  const int max_rises = options_.divergence_rises;
  const bool watch = max_rises > 0 && options_.max_relinearizations >= max_rises;
  double best_cost = watch ? Cost() : 0.0, last_cost = best_cost;
  std::vector<Factor> best_factors;  // their solution is the best iterate so far
  if (watch) best_factors = factors_;
  int rises = 0;
  // The linearisation the factor and the estimate belong to, while the factors hold the
  // next one (swapped, not copied).
  std::vector<Linearization> previous;
  for (int it = 0; it < options_.max_relinearizations; ++it) {
    const Eigen::VectorXd before = StateVector();
    const bool check = it > 0 && options_.predict_convergence;
    if (check) {
      previous.resize(factors_.size());
      for (size_t k = 0; k < factors_.size(); ++k) SwapLinearization(&factors_[k], &previous[k]);
    }
    {
      StageTimer timer(&times_, "update");
      for (Factor& f : factors_) Linearize(&f);
    }
    if (check && PredictedStepConverged(before)) {
      // The estimate solves the previous linearisation and the step from it is already
      // small: that linearisation stays, without another factorisation.
      for (size_t k = 0; k < factors_.size(); ++k) SwapLinearization(&factors_[k], &previous[k]);
      ++counters_.relinearizations_predicted_converged;
      break;
    }
    if (absl::Status s = Rebuild(/*only_last_factor=*/false); !s.ok()) return s;
    ++counters_.relinearizations;
    if (watch) {
      const double cost = Cost();
      // Near convergence the cost changes by its rounding error only (about 1e-12 of it
      // here), up or down: a rise counts when it is well above that.
      constexpr double kRoundingFloor = 1e-8;
      rises = cost > last_cost * (1.0 + kRoundingFloor) ? rises + 1 : 0;
      last_cost = cost;
      if (cost < best_cost) {
        best_cost = cost;
        best_factors = factors_;
      } else if (rises >= max_rises || !std::isfinite(cost)) {
        ++counters_.relinearizations_diverged;
        factors_ = std::move(best_factors);
        return Rebuild(/*only_last_factor=*/false);
      }
    }
    const Eigen::VectorXd step = StateVector() - before;
    if (step.cwiseAbs().maxCoeff() < options_.relinearize_tolerance) break;
    // The step's length in the information metric of the linearisation that produced it
    // (ΔxᵀΛΔx, the decrease of Cost() it predicts): a small fraction of the estimate's
    // uncertainty is converged for estimation, however far it moved an ill-determined
    // variable in metres.
    if (InformationNorm(step) < options_.relinearize_step_chi2) break;
  }
  return absl::OkStatus();
}

Eigen::MatrixXd EifJoiner::JointCovariance(const std::vector<int>& anchors,
                                           const std::vector<int>& landmarks) const {
  const StateBlocks blocks = SelectBlocks(anchors, landmarks, anchor_offset_, landmark_offset_);
  const std::vector<int>& offsets = blocks.offsets;
  const std::vector<int>& sizes = blocks.sizes;
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(blocks.total, blocks.total);
  if (dim_ == 0) return out;
  SUBSLAM_CHECK(solver_->factor.ready()) << "no factorisation to recover covariances from";
  // The block of Λ⁻¹ on the free variables' rows (fixed P0: zero rows and columns), by
  // forward solves limited to each unit right-hand side's reach in the factor.
  std::vector<int> state_rows, out_rows;
  int row = 0;
  for (size_t v = 0; v < offsets.size(); ++v) {
    for (int i = 0; i < sizes[v] && offsets[v] >= 0; ++i) {
      state_rows.push_back(offsets[v] + i);
      out_rows.push_back(row + i);
    }
    row += sizes[v];
  }
  const Eigen::MatrixXd block = solver_->factor.InverseBlock(state_rows);
  out(out_rows, out_rows) = block;
  return 0.5 * (out + out.transpose());
}

std::vector<Eigen::Matrix3d> EifJoiner::AnchorCovariances() const {
  std::vector<Eigen::Matrix3d> out(graph_.num_anchors(), Eigen::Matrix3d::Zero());  // P0 fixed: zero
  std::vector<int> free;
  std::vector<std::vector<int>> groups;
  for (int k = 0; k < graph_.num_anchors(); ++k) {
    if (anchor_offset_[k] < 0) continue;
    const int o = anchor_offset_[k];
    free.push_back(k);
    groups.push_back({o, o + 1, o + 2});
  }
  if (groups.empty()) return out;
  SUBSLAM_CHECK(solver_->factor.ready()) << "no factorisation to recover covariances from";
  const std::vector<Eigen::MatrixXd> blocks = solver_->factor.DiagonalInverseBlocks(groups);
  for (size_t g = 0; g < free.size(); ++g) out[free[g]] = blocks[g];
  return out;
}

std::vector<Eigen::Matrix2d> EifJoiner::LandmarkCovariances() const {
  std::vector<std::vector<int>> groups;
  for (int j = 0; j < graph_.num_landmarks(); ++j) groups.push_back({landmark_offset_[j], landmark_offset_[j] + 1});
  std::vector<Eigen::Matrix2d> out;
  if (groups.empty()) return out;
  SUBSLAM_CHECK(solver_->factor.ready()) << "no factorisation to recover covariances from";
  for (const Eigen::MatrixXd& b : solver_->factor.DiagonalInverseBlocks(groups)) out.push_back(b);
  return out;
}

std::vector<Matrix5d> EifJoiner::AnchorLandmarkCovariances(int anchor, const std::vector<int>& landmarks) const {
  std::vector<Matrix5d> out(landmarks.size(), Matrix5d::Zero());
  if (dim_ == 0) return out;
  SUBSLAM_CHECK(solver_->factor.ready()) << "no factorisation to recover covariances from";
  std::vector<int> hub;
  for (int i = 0; i < 3 && anchor_offset_[anchor] >= 0; ++i) hub.push_back(anchor_offset_[anchor] + i);
  std::vector<std::vector<int>> groups;
  for (int j : landmarks) groups.push_back({landmark_offset_[j], landmark_offset_[j] + 1});
  const std::vector<Eigen::MatrixXd> blocks = solver_->factor.InverseStarBlocks(hub, groups);
  const int h = static_cast<int>(hub.size());  // 0 for the fixed P0: zero rows and columns
  for (size_t c = 0; c < landmarks.size(); ++c) out[c].bottomRightCorner(2 + h, 2 + h) = blocks[c];
  return out;
}

std::vector<std::optional<Matrix5d>> EifJoiner::AnchorLandmarkBounds(int anchor,
                                                                    const std::vector<int>& landmarks) const {
  std::vector<std::optional<Matrix5d>> out(landmarks.size());
  if (dim_ == 0) return out;
  SUBSLAM_CHECK(solver_->factor.ready()) << "no factorisation to recover covariances from";
  // The anchor's columns of Λ⁻¹ on its own rows and the bounded landmarks' (a back
  // substitution over their paths to the root only): its marginal and its exact
  // cross-covariance with each landmark (zero for the fixed P0).
  const int o = anchor_offset_[anchor];
  std::vector<int> rows, bounded;
  for (size_t c = 0; c < landmarks.size(); ++c) {
    if (!marginal_bound_[landmarks[c]].allFinite()) continue;
    bounded.push_back(static_cast<int>(c));
    rows.push_back(landmark_offset_[landmarks[c]]);
    rows.push_back(landmark_offset_[landmarks[c]] + 1);
  }
  if (bounded.empty()) return out;
  Eigen::MatrixXd columns = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()) + 3, 3);
  if (o >= 0) {
    rows.insert(rows.end(), {o, o + 1, o + 2});
    columns = solver_->factor.InverseColumnsAt({o, o + 1, o + 2}, rows);
  }
  const Eigen::Matrix3d anchor_block = columns.bottomRows<3>();
  for (size_t b = 0; b < bounded.size(); ++b) {
    const int c = bounded[b];
    const Eigen::Matrix2d& B = marginal_bound_[landmarks[c]];
    // [Σ_PP Σ_PL; Σ_LP B] ⪰ [Σ_PP Σ_PL; Σ_LP Σ_LL] since B ⪰ Σ_LL.
    Matrix5d m;
    m.topLeftCorner<3, 3>() = anchor_block;
    m.bottomLeftCorner<2, 3>() = columns.middleRows<2>(static_cast<Eigen::Index>(2 * b));
    m.topRightCorner<3, 2>() = m.bottomLeftCorner<2, 3>().transpose();
    m.bottomRightCorner<2, 2>() = B;
    out[c] = m;
  }
  return out;
}

absl::Status EifJoiner::Join(const LocalSubmap& s) {
  if (absl::Status v = s.Validate(); !v.ok()) return v;
  if (s.t_start < last_t_end_ - 1e-9) {
    return absl::InvalidArgumentError(absl::StrCat("local map ", s.id, " starts at ", s.t_start,
                                                   " before the previous one ended (", last_t_end_, ")"));
  }
  if (absl::Status st = JoinOne(s); !st.ok()) return st;
  return CheckPendingLoopClosure();
}

EifJoiner::Snapshot EifJoiner::TakeSnapshot() const {
  return Snapshot{graph_, anchor_offset_, landmark_offset_, anchor_theta_, dim_, factors_,
                  eta_, associator_, marginal_bound_, counters_};
}

void EifJoiner::Restore(Snapshot before) {
  graph_ = std::move(before.graph);
  anchor_offset_ = std::move(before.anchor_offset);
  landmark_offset_ = std::move(before.landmark_offset);
  anchor_theta_ = std::move(before.anchor_theta);
  dim_ = before.dim;
  factors_ = std::move(before.factors);
  lambda_factors_ = 0;  // Λ is assembled again from the kept factors when needed
  eta_ = std::move(before.eta);
  associator_ = std::move(before.associator);
  marginal_bound_ = std::move(before.marginal_bound);  // bounds for the smaller Λ
  solver_->stale = true;  // it absorbed the undone factors
  counters_ = before.counters;
  touched_.assign(graph_.num_landmarks(), 1);
}

absl::Status EifJoiner::JoinOne(const LocalSubmap& s) {
  if (!options_.validate_joins) return JoinWith(s, /*associate=*/true);
  // Validated join: keep what a rejected join would have to undo.
  Snapshot before = TakeSnapshot();
  const long associated_before = counters_.associated;
  if (absl::Status st = JoinWith(s, /*associate=*/true); !st.ok()) return st;
  const int matched = static_cast<int>(counters_.associated - associated_before);
  if (matched == 0) return absl::OkStatus();
  // The new factor's normalised residual at the new estimate, against χ² with 2 dof per
  // matched feature (the end pose and new landmarks fit exactly).
  const double d2 = NormalisedResidual(factors_.back());
  const double bound = models::ChiSquareQuantile(options_.validation_probability, 2 * matched);
  if (d2 <= bound) return absl::OkStatus();
  // Rejected: undo, and join the local map again without associations (its odometry
  // still links the chain; its features become new landmarks).
  if (pending_loop_ && pending_loop_->factor >= static_cast<int>(graph_.factors().size()) - 1) {
    pending_loop_.reset();  // the closure was this join's, now undone
  }
  Restore(std::move(before));
  ++counters_.rejected_joins;
  rejected_.push_back(s.id);
  return JoinWith(s, /*associate=*/false);
}

absl::Status EifJoiner::CheckPendingLoopClosure() {
  if (!pending_loop_) return absl::OkStatus();
  const int last = static_cast<int>(graph_.factors().size()) - 1;
  const int closing = pending_loop_->factor;
  if (last <= closing) return absl::OkStatus();  // the closing map itself was just joined
  // Old landmarks the closure did not use: they existed before the closing map, the
  // recent maps before it did not see them, and no map since has seen them.
  const int old_landmarks = pending_loop_->before.graph.num_landmarks();
  std::vector<char> used(old_landmarks, 0);
  const int first = std::max(0, closing - options_.association.recent_maps);
  for (int f = first; f < last; ++f) {
    for (int j : graph_.factors()[f].landmark_of_feature) {
      if (j < old_landmarks) used[j] = 1;
    }
  }
  for (int j : graph_.factors()[last].landmark_of_feature) {
    if (j < old_landmarks && !used[j]) {
      pending_loop_.reset();
      ++counters_.loop_closures_confirmed;
      return absl::OkStatus();
    }
  }
  if (last - closing < options_.loop_confirmation_maps) return absl::OkStatus();
  // Unconfirmed: back to the joiner before the closing map, whose work stays counted,
  // and the maps since joined again, the closing one without loop pairings.
  PendingLoopClosure pending = std::move(*pending_loop_);
  pending_loop_.reset();
  std::vector<LocalSubmap> maps;
  for (int f = closing; f <= last; ++f) maps.push_back(graph_.factors()[f].submap);
  const JoinerCounters work = counters_;
  Restore(std::move(pending.before));
  rejected_.resize(pending.rejected);
  // Decisions (thin, ambiguous, truncated) count those of the joins that stand; work and
  // confirmations count everything done.
  counters_.relinearizations = work.relinearizations;
  counters_.relinearizations_diverged = work.relinearizations_diverged;
  counters_.relinearizations_predicted_converged = work.relinearizations_predicted_converged;
  counters_.relinearized_on_heading = work.relinearized_on_heading;
  counters_.relinearized_on_linearization_error = work.relinearized_on_linearization_error;
  counters_.loop_closures_confirmed = work.loop_closures_confirmed;
  counters_.loop_closures_unconfirmed = work.loop_closures_unconfirmed + 1;
  counters_.associations_replayed = work.associations_replayed;
  counters_.incremental_updates = work.incremental_updates;
  counters_.full_factorizations = work.full_factorizations;
  counters_.nested_dissection_factorizations = work.nested_dissection_factorizations;
  counters_.reused_analyses = work.reused_analyses;
  counters_.failed_updates = work.failed_updates;
  counters_.candidates = work.candidates;
  counters_.candidates_bounded_out = work.candidates_bounded_out;
  counters_.covariance_columns = work.covariance_columns;
  counters_.covariance_reach = work.covariance_reach;
  // The closing map is associated again before any join refactorises: the factor must be
  // the restored Λ's (the restored estimate is already its solution). Counted on top of
  // the work above.
  if (absl::Status st = FullFactorization(); !st.ok()) return st;
  solver_->stale = false;
  for (size_t m = 0; m < maps.size(); ++m) {
    suppress_loop_closure_ = m == 0;
    if (m == 0) replayed_association_ = std::move(pending.association);
    const absl::Status st = JoinOne(maps[m]);
    suppress_loop_closure_ = false;
    replayed_association_.reset();
    if (!st.ok()) return st;
    // A closure made again by a later map waits for its own confirmation; its window
    // cannot end within these maps.
    if (m > 0) {
      if (absl::Status c = CheckPendingLoopClosure(); !c.ok()) return c;
    }
  }
  return absl::OkStatus();
}

void EifJoiner::CountDecisions(const SubmapAssociation& a) {
  if (a.jcbb_truncated) ++counters_.jcbb_truncated;
  if (a.loop_pairings_dropped > 0) ++counters_.loop_closures_thin;
  if (a.loop_ambiguous) ++counters_.loop_closures_ambiguous;
}

SubmapAssociation EifJoiner::AssociateAt(const LocalSubmap& s, int start, bool anchor_prefilter) {
  StageTimer timer(&times_, "association");
  const long columns_before = solver_->factor.columns_solved(), reach_before = solver_->factor.reach_solved();
  // Each recovered landmark marginal is today's, so it bounds every later one (Λ grows).
  const auto pair_covariance = [this](int anchor, const std::vector<int>& landmarks) {
    std::vector<Matrix5d> blocks = AnchorLandmarkCovariances(anchor, landmarks);
    for (size_t c = 0; c < landmarks.size(); ++c) {
      marginal_bound_[landmarks[c]] = blocks[c].bottomRightCorner<2, 2>();
    }
    return blocks;
  };
  const auto bound = [this](int anchor, const std::vector<int>& landmarks) {
    return AnchorLandmarkBounds(anchor, landmarks);
  };
  SubmapAssociation a = associator_.Associate(
      s, start, graph_,
      [this](const std::vector<int>& anchors, const std::vector<int>& landmarks) {
        return JointCovariance(anchors, landmarks);
      },
      anchor_prefilter, pair_covariance,
      options_.bound_candidate_marginals ? SubmapAssociator::PairBoundFn(bound) : nullptr);
  times_["covariance_recovery"] += a.covariance_seconds;
  CountDecisions(a);
  counters_.candidates += a.candidates;
  counters_.candidates_bounded_out += a.candidates_bounded_out;
  counters_.covariance_columns += solver_->factor.columns_solved() - columns_before;
  counters_.covariance_reach += solver_->factor.reach_solved() - reach_before;
  return a;
}

absl::Status EifJoiner::JoinWith(const LocalSubmap& s, bool associate) {
  const int start = graph_.num_anchors() - 1;
  std::vector<int> assoc(s.num_landmarks(), -1);
  // The start anchor's marginal before this join (NaN without one: no bounds then).
  Eigen::Matrix3d start_covariance = Eigen::Matrix3d::Constant(NAN);
  if (associate) {
    const JoinerCounters counters_before = counters_;  // a pending closure's snapshot keeps these
    SubmapAssociation a;
    if (replayed_association_) {
      // Joined again after its loop closure went unconfirmed, from the state it was
      // first associated in: that association, not a second search to the same result.
      a = *std::move(replayed_association_);
      replayed_association_.reset();
      CountDecisions(a);
      ++counters_.associations_replayed;
    } else {
      a = AssociateAt(s, start, /*anchor_prefilter=*/true);
    }
    assoc = a.landmark_of_feature;
    start_covariance = a.start_anchor_covariance;
    if (suppress_loop_closure_) {
      // The closing map of an unconfirmed loop closure: without its loop pairings.
      for (int i : a.uncertain_loop_features) assoc[i] = -1;
    } else if (!a.uncertain_loop_features.empty() && options_.loop_confirmation_maps > 0 &&
               options_.RelinearizesAfterJoins() && !pending_loop_ &&
               3.0 * a.start_position_sigma_m >= options_.loop_confirmation_min_sigma_radius_m) {
      pending_loop_ = PendingLoopClosure{TakeSnapshot(), static_cast<int>(graph_.factors().size()), rejected_.size(),
                                         std::move(a)};
      // Its decisions are counted again on an undo (its work is not): not twice.
      pending_loop_->before.counters = counters_before;
    }
  }
  const int first_new_landmark = graph_.num_landmarks();
  // Initialise the end anchor and the new landmarks through the start anchor.
  const Pose2 P_s(graph_.anchors()[start].x, graph_.anchors()[start].y, anchor_theta_[start]);
  const Pose2 end_local = s.end_pose();
  const Pose2 end = Compose(P_s, end_local);
  const int end_anchor = graph_.AddAnchor(Pose2(end.x, end.y, WrapAngle(end.theta)));
  anchor_theta_.push_back(anchor_theta_[start] + end_local.theta);
  anchor_offset_.push_back(dim_);
  dim_ += 3;
  for (int i = 0; i < s.num_landmarks(); ++i) {
    if (assoc[i] >= 0) {
      ++counters_.associated;
    } else {
      Matrix23d J_frame;
      Eigen::Matrix2d J_point;
      assoc[i] = graph_.AddLandmark(TransformFrom(P_s, s.landmark(i), &J_frame, &J_point));
      landmark_offset_.push_back(dim_);
      dim_ += 2;
      ++counters_.new_landmarks;
      // Its marginal given the data before this join and its own feature alone — the
      // start anchor's marginal carried through the feature — bounds its marginal given
      // everything (in the linearised model, more data never widens a marginal).
      const Eigen::Matrix2d Q = s.covariance.block<2, 2>(3 + 2 * i, 3 + 2 * i);
      marginal_bound_.push_back(J_frame * start_covariance * J_frame.transpose() + J_point * Q * J_point.transpose());
    }
  }
  // A rejected map joined again (associate false) must not redefine its landmarks.
  associator_.Record(s, assoc, first_new_landmark, /*define_truth=*/associate);
  touched_.resize(graph_.num_landmarks(), 1);
  for (int j : assoc) touched_[j] = 1;
  graph_.AddFactor({s, start, end_anchor, assoc});
  Factor f = MakeFactor(static_cast<int>(graph_.factors().size()) - 1);
  {
    StageTimer timer(&times_, "update");
    Linearize(&f, &solver_->last_whitened_jacobian);
  }
  factors_.push_back(std::move(f));
  last_association_ = assoc;
  last_t_end_ = s.t_end;
  ++counters_.joins;
  if (absl::Status st = Rebuild(/*only_last_factor=*/true); !st.ok()) return st;
  bool relinearize = false;
  if (options_.relinearize_every > 0 && counters_.joins % options_.relinearize_every == 0) {
    relinearize = true;
  } else if (options_.relinearize_heading_change > 0 && MaxHeadingDrift() > options_.relinearize_heading_change) {
    ++counters_.relinearized_on_heading;
    relinearize = true;
  } else if (options_.relinearize_linearization_chi2 > 0) {
    StageTimer timer(&times_, "linearization_check");
    relinearize = LinearizationErrorAbove(options_.relinearize_linearization_chi2);
    if (relinearize) ++counters_.relinearized_on_linearization_error;
  }
  if (relinearize) {
    if (absl::Status st = Relinearize(); !st.ok()) return st;
  }
  const int every = options_.revision.every_joins;
  if (associate && (relinearize || (every > 0 && counters_.joins % every == 0))) {
    relinearized_since_revision_ = relinearize;
    return ReviseAssociation(/*full=*/false);
  }
  return absl::OkStatus();
}

std::vector<Matrix5d> EifJoiner::FactorMarginals(int anchor, const std::vector<int>& landmarks) const {
  // [anchor, landmark] is coupled in Λ by the factor that holds both, so its block lies on
  // L's pattern: all of them from one sparse-inverse recursion per factorisation.
  std::vector<std::vector<int>> groups;
  const int o = anchor_offset_[anchor];
  for (int j : landmarks) {
    std::vector<int> g;
    if (o >= 0) g = {o, o + 1, o + 2};
    g.push_back(landmark_offset_[j]);
    g.push_back(landmark_offset_[j] + 1);
    groups.push_back(std::move(g));
  }
  std::vector<Matrix5d> out(landmarks.size(), Matrix5d::Zero());
  if (groups.empty()) return out;
  const std::vector<Eigen::MatrixXd> blocks = solver_->factor.DiagonalInverseBlocks(groups);
  const int h = o >= 0 ? 3 : 0;  // the fixed P0: zero rows and columns
  for (size_t c = 0; c < landmarks.size(); ++c) out[c].bottomRightCorner(2 + h, 2 + h) = blocks[c];
  return out;
}

absl::Status EifJoiner::ReviseAssociation(bool full) {
  // In-run passes test the pairs a join touched (and the splits after a relinearisation);
  // a full pass every pair.
  const bool with_splits = full || relinearized_since_revision_;
  const bool all_pairs = full;
  relinearized_since_revision_ = false;
  if (!options_.revision.enabled() || options_.association.known_association || pending_loop_ || factors_.empty()) {
    return absl::OkStatus();
  }
  ++counters_.revision_passes;
  StageTimer timer(&times_, "revision");
  std::vector<FeatureSplit> splits;
  if (with_splits) {
    splits = FindFeatureSplits(
        graph_, [this](int anchor, const std::vector<int>& landmarks) { return FactorMarginals(anchor, landmarks); },
        options_.revision);
  }
  // The pre-filter's marginals: the bounds association keeps (upper bounds keep it exact),
  // recovered where there is none.
  std::vector<Eigen::Matrix2d> marginals = marginal_bound_;
  int missing = 0;
  for (const Eigen::Matrix2d& m : marginals) missing += m.allFinite() ? 0 : 1;
  if (missing > 0) {
    // A few by their own solves, many (a relinearisation forgot them) all at once.
    constexpr int kBulkFrom = 16;
    std::vector<Eigen::Matrix2d> exact;
    if (missing >= kBulkFrom) exact = LandmarkCovariances();
    for (int j = 0; j < graph_.num_landmarks(); ++j) {
      if (!marginals[j].allFinite()) marginals[j] = exact.empty() ? LandmarkCovariance(j) : exact[j];
    }
    // Today's exact marginals bound every later one until the next relinearisation.
    if (options_.bound_candidate_marginals) marginal_bound_ = marginals;
  }
  touched_.resize(graph_.num_landmarks(), 1);
  std::vector<LandmarkMerge> merges = FindLandmarkMerges(
      graph_, marginals, [this](int a, int b) -> Eigen::Matrix4d { return JointCovariance({}, {a, b}); },
      options_.revision, options_.association.loop_test_min_sigma_radius_m, all_pairs ? std::vector<char>() : touched_);
  touched_.assign(graph_.num_landmarks(), 0);
  // A landmark a split leaves is not merged in the same pass (its estimate will move).
  std::vector<char> split_from(graph_.num_landmarks(), 0);
  for (const FeatureSplit& sp : splits) split_from[graph_.factors()[sp.factor].landmark_of_feature[sp.feature]] = 1;
  std::erase_if(merges, [&](const LandmarkMerge& m) { return split_from[m.keep] || split_from[m.drop]; });
  if (splits.empty() && merges.empty()) return absl::OkStatus();
  StageTimer solve(&times_, "revision_solve");  // (within "revision")
  return ApplyRevisions(splits, merges);
}

absl::Status EifJoiner::MergeLandmarks(int keep, int drop) {
  if (absl::Status st = graph_.ValidateMerge(keep, drop); !st.ok()) return st;
  return ApplyRevisions({}, {LandmarkMerge{std::min(keep, drop), std::max(keep, drop), NAN}});
}

absl::Status EifJoiner::SplitFeature(int factor, int feature) {
  if (absl::Status st = graph_.ValidateSplit(factor, feature); !st.ok()) return st;
  return ApplyRevisions({FeatureSplit{factor, feature, NAN}}, {});
}

absl::Status EifJoiner::ApplyRevisions(const std::vector<FeatureSplit>& splits,
                                       const std::vector<LandmarkMerge>& merges) {
  for (const FeatureSplit& sp : splits) {
    const SubmapFactor& record = graph_.factors()[sp.factor];
    const int from = record.landmark_of_feature[sp.feature];
    const double signature = record.submap.landmarks[sp.feature].signature;
    absl::StatusOr<int> to = graph_.SplitFeature(sp.factor, sp.feature);
    if (!to.ok()) return to.status();
    associator_.SplitFeature(from, *to, signature);
    touched_.resize(graph_.num_landmarks(), 1);
    touched_[from] = touched_[*to] = 1;
    landmark_offset_.push_back(dim_);
    dim_ += 2;
    marginal_bound_.push_back(Eigen::Matrix2d::Constant(NAN));
    ++counters_.features_split;
  }
  for (const LandmarkMerge& m : merges) {
    if (absl::Status st = graph_.MergeLandmarks(m.keep, m.drop); !st.ok()) return st;
    associator_.MergeLandmarks(m.keep, m.drop);
    if (m.drop < static_cast<int>(touched_.size())) touched_.erase(touched_.begin() + m.drop);
    if (m.keep < static_cast<int>(touched_.size())) touched_[m.keep] = 1;
    const int removed = landmark_offset_[m.drop];
    landmark_offset_.erase(landmark_offset_.begin() + m.drop);
    marginal_bound_.erase(marginal_bound_.begin() + m.drop);
    for (int& o : anchor_offset_) o -= o > removed ? 2 : 0;
    for (int& o : landmark_offset_) o -= o > removed ? 2 : 0;
    dim_ -= 2;
    for (int& j : last_association_) j = SubmapGraph::RenumberAfterMerge(j, m.keep, m.drop);
    ++counters_.landmarks_merged;
  }
  // Every factor's variables where they now sit. Its linear model stays valid: the factor
  // is affine in the landmarks (nonlinear only through the start heading), so re-keying a
  // landmark column is exact, and the re-keyed Λ is the revised problem's at the same
  // linearisation. Then Gauss-Newton from there where the joiner relinearises.
  for (Factor& f : factors_) SetLayout(&f);
  lambda_factors_ = 0;
  lambda_full_valid_ = false;
  solver_->stale = true;
  if (absl::Status st = Rebuild(/*only_last_factor=*/false); !st.ok()) return st;
  if (options_.RelinearizesAfterJoins() || options_.relinearize_at_end) return GaussNewton();
  return absl::OkStatus();
}

void EifJoiner::UnwhitenedLinearizationError(const Factor& f, Eigen::VectorXd* e) const {
  // The factor is nonlinear only through the start heading θ: each position row is
  // Rᵀ(θ) v, v the lever from the start anchor to the end anchor or a landmark. Its linear
  // model at (θ₀, v₀) is Rᵀ(θ₀) v + Ṙᵀ(θ₀) v₀ (θ − θ₀), so the error is
  // (Rᵀ(θ) − Rᵀ(θ₀)) v − Ṙᵀ(θ₀) v₀ (θ − θ₀); the heading row is linear.
  const SubmapFactor& record = graph_.factors()[f.index];
  const double theta = anchor_theta_[record.start_anchor], dtheta = theta - f.start_theta;
  const Eigen::Vector2d p_s(graph_.anchors()[record.start_anchor].x, graph_.anchors()[record.start_anchor].y);
  const Eigen::Matrix2d Rt = Pose2(0, 0, theta).rotation().transpose();
  const Eigen::Matrix2d Rt0 = Pose2(0, 0, f.start_theta).rotation().transpose();
  Eigen::Matrix2d dRt0;  // d/dθ Rᵀ(θ) at θ₀
  const double c = std::cos(f.start_theta), s = std::sin(f.start_theta);
  dRt0 << -s, c, -c, -s;
  const int n = static_cast<int>(f.levers.size()) - 1;
  e->setZero(3 + 2 * n);
  const auto error = [&](const Eigen::Vector2d& v, const Eigen::Vector2d& v0) {
    return Eigen::Vector2d((Rt - Rt0) * v - dRt0 * v0 * dtheta);
  };
  e->head<2>() = error(Eigen::Vector2d(graph_.anchors()[record.end_anchor].x, graph_.anchors()[record.end_anchor].y) - p_s,
                       f.levers[0]);
  for (int i = 0; i < n; ++i) {
    e->segment<2>(3 + 2 * i) = error(graph_.landmarks()[record.landmark_of_feature[i]] - p_s, f.levers[i + 1]);
  }
}

double EifJoiner::LinearizationError(const Factor& f) const {
  Eigen::VectorXd e;
  UnwhitenedLinearizationError(f, &e);
  f.covariance_sqrt->triangularView<Eigen::Lower>().solveInPlace(e);
  return e.squaredNorm();
}

double EifJoiner::MaxLinearizationError() const {
  double worst = 0.0;
  for (const Factor& f : factors_) worst = std::max(worst, LinearizationError(f));
  return worst;
}

bool EifJoiner::LinearizationErrorAbove(double chi2) const {
  Eigen::VectorXd e;
  for (const Factor& f : factors_) {
    const SubmapFactor& record = graph_.factors()[f.index];
    if (anchor_theta_[record.start_anchor] == f.start_theta) continue;  // no error at all
    // Whitening scales a vector by at most 1 / √λ_min(Q): the unwhitened error (O(n))
    // settles most factors without the triangular solve (O(n²)).
    UnwhitenedLinearizationError(f, &e);
    if (e.squaredNorm() <= chi2 * f.covariance_min_eigenvalue) continue;
    f.covariance_sqrt->triangularView<Eigen::Lower>().solveInPlace(e);
    if (e.squaredNorm() > chi2) return true;
  }
  return false;
}

double EifJoiner::MaxHeadingDrift() const {
  double drift = 0.0;
  for (const Factor& f : factors_) {
    const SubmapFactor& record = graph_.factors()[f.index];
    drift = std::max({drift, std::abs(anchor_theta_[record.start_anchor] - f.start_theta),
                      std::abs(anchor_theta_[record.end_anchor] - f.end_theta)});
  }
  return drift;
}

absl::Status EifJoiner::AdoptEstimate(const SubmapGraph& solved) {
  if (solved.num_anchors() != graph_.num_anchors() || solved.num_landmarks() != graph_.num_landmarks()) {
    return absl::InvalidArgumentError("AdoptEstimate: not the joiner's graph");
  }
  for (int k = 1; k < graph_.num_anchors(); ++k) {
    const Pose2& p = solved.anchors()[k];
    anchor_theta_[k] += WrapAngle(p.theta - anchor_theta_[k]);  // stay continuous
    graph_.anchor(k) = Pose2(p.x, p.y, WrapAngle(p.theta));
  }
  for (int j = 0; j < graph_.num_landmarks(); ++j) graph_.landmark(j) = solved.landmarks()[j];
  {
    StageTimer timer(&times_, "update");
    for (Factor& f : factors_) Linearize(&f);
  }
  return Rebuild(/*only_last_factor=*/false);
}

absl::Status EifJoiner::Finish() {
  pending_loop_.reset();  // a closure still waiting at the end stands: no more maps to ask
  // No association follows: the marginal bounds are not refreshed.
  if (options_.relinearize_at_end && !factors_.empty()) {
    if (absl::Status st = GaussNewton(); !st.ok()) return st;
  }
  // Revise at the converged estimate (each pass that changes something solves again).
  return ReviseUntilSettled(*this);
}

EifJoiner::EifJoiner(const EifJoiner& other)
    : options_(other.options_),
      graph_(other.graph_),
      anchor_offset_(other.anchor_offset_),
      landmark_offset_(other.landmark_offset_),
      anchor_theta_(other.anchor_theta_),
      dim_(other.dim_),
      factors_(other.factors_),
      eta_(other.eta_),
      solver_(std::make_unique<Solver>()),
      associator_(other.associator_),
      marginal_bound_(other.marginal_bound_),
      last_association_(other.last_association_),
      touched_(other.touched_),
      rejected_(other.rejected_),
      pending_loop_(other.pending_loop_),
      times_(other.times_),
      counters_(other.counters_),
      last_t_end_(other.last_t_end_) {
  // The copy's factor is the original's ordering choice refactorised (an automatic
  // ordering that has switched to nested dissection stays switched).
  solver_->factor.AdoptOrderingChoice(other.solver_->factor);
  if (other.solver_->factor.ready()) {
    SUBSLAM_CHECK(solver_->factor.Factorize(LowerInformation(), 64 + dim_ / 6, options_.ordering).ok())
        << "refactorising a copy failed";
  }
}

std::unique_ptr<MapJoiner> EifJoiner::NewEmpty(const Pose2& initial_pose) const {
  return std::make_unique<EifJoiner>(initial_pose, options_);
}

std::unique_ptr<MapJoiner> EifJoiner::Clone() const { return std::unique_ptr<MapJoiner>(new EifJoiner(*this)); }

absl::Status EifJoiner::JoinMap(const MapJoiner& right_base) {
  const auto* right_ptr = dynamic_cast<const EifJoiner*>(&right_base);
  if (right_ptr == nullptr) return absl::InvalidArgumentError("EIF JoinMap: the right map is not an EIF map");
  const EifJoiner& right = *right_ptr;
  if (right.graph_.factors().empty()) return absl::OkStatus();
  // A loop closure still waiting for confirmation stands: once whole maps are joined the
  // maps after it are no longer a sequence to replay (and right's own is right's).
  pending_loop_.reset();
  absl::StatusOr<LocalSubmap> summary = SummarizeForJoin(right, last_t_end_);
  if (!summary.ok()) return summary.status();
  const int start = graph_.num_anchors() - 1;
  const int n = right.graph_.num_landmarks();
  std::vector<int> assoc(n, -1);
  if (!graph_.factors().empty()) assoc = AssociateAt(*summary, start, /*anchor_prefilter=*/false).landmark_of_feature;
  // Right's anchors and unmatched landmarks, through the last anchor (headings continuous).
  const Pose2 P_s(graph_.anchors()[start].x, graph_.anchors()[start].y, anchor_theta_[start]);
  std::vector<int> anchor_map = {start};
  for (int k = 1; k < right.graph_.num_anchors(); ++k) {
    const Pose2& a = right.graph_.anchors()[k];
    const Pose2 local(a.x, a.y, right.anchor_theta_[k]);
    const Pose2 p = Compose(P_s, local);
    anchor_map.push_back(graph_.AddAnchor(p));
    anchor_theta_.push_back(P_s.theta + local.theta);
    anchor_offset_.push_back(dim_);
    dim_ += 3;
  }
  const int first_new_landmark = graph_.num_landmarks();
  long matched = 0;
  for (int l = 0; l < n; ++l) {
    if (assoc[l] >= 0) {
      ++matched;
      continue;
    }
    assoc[l] = graph_.AddLandmark(TransformFrom(P_s, right.graph_.landmarks()[l]));
    landmark_offset_.push_back(dim_);
    dim_ += 2;
  }
  {
    StageTimer timer(&times_, "update");
    for (const SubmapFactor& f : right.graph_.factors()) {
      std::vector<int> landmarks;
      for (int l : f.landmark_of_feature) landmarks.push_back(assoc[l]);
      graph_.AddFactor({f.submap, anchor_map[f.start_anchor], anchor_map[f.end_anchor], landmarks});
      Factor factor = MakeFactor(static_cast<int>(graph_.factors().size()) - 1);
      Linearize(&factor);
      factors_.push_back(std::move(factor));
    }
  }
  associator_.Record(*summary, assoc, first_new_landmark, /*define_truth=*/true);
  last_association_.clear();
  for (int l : right.last_association_) last_association_.push_back(assoc[l]);
  counters_ += right.counters_;  // its joins, then this join's merges
  counters_.associated += matched;
  counters_.new_landmarks -= matched;
  for (const auto& [stage, seconds] : right.times_) times_[stage] += seconds;
  last_t_end_ = right.last_t_end_;
  if (absl::Status st = Rebuild(/*only_last_factor=*/false); !st.ok()) return st;
  // Right's factors were linearised at an estimate made without this map's information:
  // after a long right map, one step is far from the joint optimum (on combined-2km the
  // tree's anchors were 74 m off, NEES 3,800), so a tree join is iterated to convergence.
  if (absl::Status st = Relinearize(); !st.ok()) return st;
  return ReviseAssociation(/*full=*/true);
}

}  // namespace subslam::backend
