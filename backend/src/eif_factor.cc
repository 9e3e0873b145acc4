// EifFactor: one local map's factor — its linearisation at the current estimate, its
// information blocks, and how far its linear model is from the estimate (the
// relinearisation triggers).

#include "eif_factor.h"

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
double Square(double v) { return v * v; }

// Q⁻¹ = L⁻ᵀ L⁻¹ from Q = L Lᵀ (L lower triangular), symmetric to the bit.
std::shared_ptr<const Eigen::MatrixXd> InverseFromLowerSqrt(const Eigen::MatrixXd& L) {
  Eigen::MatrixXd L_inv = Eigen::MatrixXd::Identity(L.rows(), L.rows());
  L.triangularView<Eigen::Lower>().solveInPlace(L_inv);
  const Eigen::MatrixXd information = L_inv.transpose() * L_inv;
  return std::make_shared<const Eigen::MatrixXd>(0.5 * (information + information.transpose()));
}
}  // namespace

EifFactor EifFactor::Make(const EifEstimate& estimate, int index, bool screened) {
  const SubmapFactor& record = estimate.graph.factors()[index];
  EifFactor f;
  f.index = index;
  const Eigen::LLT<Eigen::MatrixXd> llt(record.submap.covariance);
  SUBSLAM_CHECK(llt.info() == Eigen::Success) << "local map covariance not positive definite";
  f.covariance_sqrt_ = std::make_shared<const Eigen::MatrixXd>(llt.matrixL());
  if (screened) {  // LinearizationErrorAbove's screen
    f.covariance_min_eigenvalue_ =
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(record.submap.covariance, Eigen::EigenvaluesOnly)
            .eigenvalues()
            .minCoeff();
  }
  f.SetLayout(estimate);
  return f;
}

void EifFactor::SetLayout(const EifEstimate& estimate) {
  const SubmapFactor& record = estimate.graph.factors()[index];
  offsets.clear();
  sizes.clear();
  if (record.start_anchor != 0) {
    offsets.push_back(estimate.anchor_offset[record.start_anchor]);
    sizes.push_back(3);
  }
  offsets.push_back(estimate.anchor_offset[record.end_anchor]);
  sizes.push_back(3);
  for (int j : record.landmark_of_feature) {
    offsets.push_back(estimate.landmark_offset[j]);
    sizes.push_back(2);
  }
}

void EifFactor::RecordLinearizationPoint(const EifEstimate& estimate, const Pose2& start, const Pose2& end) {
  const SubmapFactor& record = estimate.graph.factors()[index];
  start_theta = start.theta;
  end_theta = end.theta;
  const Eigen::Vector2d p_s(start.x, start.y);
  levers_.resize(record.landmark_of_feature.size() + 1);
  levers_[0] = Eigen::Vector2d(end.x, end.y) - p_s;
  for (size_t i = 0; i < record.landmark_of_feature.size(); ++i) {
    levers_[i + 1] = estimate.graph.landmarks()[record.landmark_of_feature[i]] - p_s;
  }
}

void EifFactor::Linearize(const EifEstimate& estimate, Eigen::MatrixXd* whitened_jacobian) {
  if (whitened_jacobian == nullptr) {
    LinearizeStructured(estimate);
    return;
  }
  const SubmapFactor& record = estimate.graph.factors()[index];
  const LocalSubmap& s = record.submap;
  const Pose2 start = estimate.AnchorPose(record.start_anchor), end = estimate.AnchorPose(record.end_anchor);
  const std::vector<Eigen::Vector2d> landmarks = estimate.FactorLandmarks(record);
  const SubmapFactorLinearization lin = LinearizeSubmapFactor(s, start, end, landmarks);
  RecordLinearizationPoint(estimate, start, end);

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
  const auto L = covariance_sqrt_->triangularView<Eigen::Lower>();
  Eigen::MatrixXd A = J;
  L.solveInPlace(A);
  Eigen::VectorXd e = J * x - lin.residual;
  L.solveInPlace(e);
  H = A.transpose() * A;
  b = A.transpose() * e;
  Eigen::VectorXd whitened_residual = lin.residual;
  L.solveInPlace(whitened_residual);
  cost = whitened_residual.squaredNorm();
  *whitened_jacobian = std::move(A);
}

// H = Jᵀ Q⁻¹ J and b = Jᵀ Q⁻¹ (J x̂ − r) from J's structure, without whitening: J's
// anchor columns J_a (start and end, 6) hold the relative pose's A_0 = [J_s J_e] in the
// first three rows and [J_frame,i 0] in feature i's rows, and its landmark columns one
// 2 × 2 block R_i = ∂r_i/∂L_i in feature i's rows only. With W = Q⁻¹ (kept per factor) in
// blocks W_pq over the rows (the relative pose p = 0, feature i ≥ 1):
//   (W J_a)_p = W_p0 A_0 + Σ_k W_pk [J_frame,k 0],  w_p = Σ_q W_pq (J x̂ − r)_q,
//   H_aa = J_aᵀ W J_a,  H_a,i = (W J_a)_iᵀ R_i,  H_i,k = R_iᵀ W_ik R_k,
//   b_a = J_aᵀ w,  b_i = R_iᵀ w_i,
// O(n² · 6) in fixed-size blocks instead of the O(m³) triangular solve and product
// (m = 3 + 2n). A fixed start anchor (P0) has no columns: its J_s and J_frame are zero.
void EifFactor::LinearizeStructured(const EifEstimate& estimate) {
  const SubmapFactor& record = estimate.graph.factors()[index];
  const LocalSubmap& s = record.submap;
  const Pose2 start = estimate.AnchorPose(record.start_anchor), end = estimate.AnchorPose(record.end_anchor);
  RecordLinearizationPoint(estimate, start, end);
  const int n = s.num_landmarks();
  const bool start_fixed = record.start_anchor == 0;
  using Matrix26 = Eigen::Matrix<double, 2, 6, Eigen::DontAlign>;
  using Vector2 = Eigen::Matrix<double, 2, 1, Eigen::DontAlign>;
  struct Feature {
    Eigen::Matrix<double, 2, 2, Eigen::DontAlign> R;
    Eigen::Matrix<double, 2, 3, Eigen::DontAlign> J_frame;
    Vector2 r, d, Wr, w;  // residual, J x̂ − r, and their products with W's rows
    Matrix26 WJ;          // (W J_a)_i
  };
  thread_local std::vector<Feature> features;  // reused: no allocation per call
  features.resize(static_cast<size_t>(n));
  Eigen::Matrix3d J_s, J_e;
  const Pose2 relative = Between(start, end, &J_s, &J_e);
  if (start_fixed) J_s.setZero();
  Eigen::Vector3d r0 = relative.vector() - s.mean.head<3>();
  r0[2] = WrapAngle(r0[2]);
  Eigen::Matrix<double, 3, 6> A0;
  A0 << J_s, J_e;
  Eigen::Matrix<double, 6, 1> x_a;
  x_a << start.vector(), end.vector();
  const Eigen::Vector3d d0 = A0 * x_a - r0;
  for (int i = 0; i < n; ++i) {
    Feature& fi = features[i];
    const Eigen::Vector2d landmark = estimate.graph.landmarks()[record.landmark_of_feature[i]];
    Matrix23d J_frame;
    Eigen::Matrix2d R;
    fi.r = TransformTo(start, landmark, &J_frame, &R) - s.landmark(i);
    if (start_fixed) J_frame.setZero();
    fi.J_frame = J_frame;
    fi.R = R;
    fi.d = J_frame * start.vector() + R * landmark - fi.r;
  }
  if (information_ == nullptr) information_ = InverseFromLowerSqrt(*covariance_sqrt_);  // once per factor
  const Eigen::MatrixXd& W = *information_;
  // Row block 0 (the relative pose) and each feature's row block of W J_a, W r and w.
  const Eigen::Matrix3d W00 = W.topLeftCorner<3, 3>();
  Eigen::Matrix<double, 3, 6> WJ0 = W00 * A0;
  Eigen::Vector3d Wr0 = W00 * r0, w0 = W00 * d0;
  for (int k = 0; k < n; ++k) {
    const Feature& fk = features[k];
    const Eigen::Matrix<double, 3, 2> W0k = W.block<3, 2>(0, 3 + 2 * k);
    WJ0.leftCols<3>() += W0k * fk.J_frame;
    Wr0 += W0k * fk.r;
    w0 += W0k * fk.d;
  }
  for (int i = 0; i < n; ++i) {
    Feature& fi = features[i];
    const Eigen::Matrix<double, 2, 3> Wi0 = W.block<2, 3>(3 + 2 * i, 0);
    fi.WJ = Wi0 * A0;
    fi.Wr = Wi0 * r0;
    fi.w = Wi0 * d0;
    for (int k = 0; k < n; ++k) {
      const Feature& fk = features[k];
      const Eigen::Matrix2d Wik = W.block<2, 2>(3 + 2 * i, 3 + 2 * k);
      fi.WJ.leftCols<3>() += Wik * fk.J_frame;
      fi.Wr += Wik * fk.r;
      fi.w += Wik * fk.d;
    }
  }
  double total = r0.dot(Wr0);
  Eigen::Matrix<double, 6, 6> H_aa = A0.transpose() * WJ0;
  Eigen::Matrix<double, 6, 1> b_a = A0.transpose() * w0;
  for (int i = 0; i < n; ++i) {
    const Feature& fi = features[i];
    total += fi.r.dot(fi.Wr);
    H_aa.topRows<3>() += fi.J_frame.transpose() * fi.WJ;
    b_a.head<3>() += fi.J_frame.transpose() * fi.w;
  }
  H_aa = (0.5 * (H_aa + H_aa.transpose())).eval();
  cost = total;
  // The anchor columns kept: both, or the end anchor's alone after a fixed start.
  const int na = start_fixed ? 3 : 6;
  const int cols = na + 2 * n;
  H.resize(cols, cols);
  b.resize(cols);
  H.topLeftCorner(na, na) = H_aa.bottomRightCorner(na, na);
  b.head(na) = b_a.tail(na);
  for (int i = 0; i < n; ++i) {
    const Feature& fi = features[i];
    const Eigen::Matrix<double, 6, 2> cross = fi.WJ.transpose() * fi.R;  // H_a,i
    H.block(0, na + 2 * i, na, 2) = cross.bottomRows(na);
    H.block(na + 2 * i, 0, 2, na) = cross.bottomRows(na).transpose();
    b.segment<2>(na + 2 * i) = fi.R.transpose() * fi.w;
    for (int k = 0; k <= i; ++k) {  // H symmetric to the bit
      const Feature& fk = features[k];
      H.block<2, 2>(na + 2 * i, na + 2 * k) = fi.R.transpose() * W.block<2, 2>(3 + 2 * i, 3 + 2 * k) * fk.R;
      if (k < i) H.block<2, 2>(na + 2 * k, na + 2 * i) = H.block<2, 2>(na + 2 * i, na + 2 * k).transpose();
    }
  }
}

void EifFactor::AddInformationTimes(const Eigen::VectorXd& x, Eigen::VectorXd* y) const {
  Eigen::VectorXd local(H.rows());
  int row = 0;
  for (size_t a = 0; a < offsets.size(); ++a) {
    local.segment(row, sizes[a]) = x.segment(offsets[a], sizes[a]);
    row += sizes[a];
  }
  const Eigen::VectorXd product = H * local;
  row = 0;
  for (size_t a = 0; a < offsets.size(); ++a) {
    y->segment(offsets[a], sizes[a]) += product.segment(row, sizes[a]);
    row += sizes[a];
  }
}

void EifFactor::AddToEta(Eigen::VectorXd* eta) const {
  int row = 0;
  for (size_t a = 0; a < offsets.size(); ++a) {
    eta->segment(offsets[a], sizes[a]) += b.segment(row, sizes[a]);
    row += sizes[a];
  }
}

double EifFactor::NormalizedResidual(const EifEstimate& estimate) const {
  const SubmapFactor& record = estimate.graph.factors()[index];
  Eigen::VectorXd r = SubmapResidual(record.submap, estimate.AnchorPose(record.start_anchor),
                                     estimate.AnchorPose(record.end_anchor), estimate.FactorLandmarks(record));
  covariance_sqrt_->triangularView<Eigen::Lower>().solveInPlace(r);  // rᵀ Q⁻¹ r = |L⁻¹ r|²
  return r.squaredNorm();
}

void EifFactor::SwapLinearization(Linearization* l) {
  H.swap(l->H);
  b.swap(l->b);
  std::swap(start_theta, l->start_theta);
  std::swap(end_theta, l->end_theta);
  levers_.swap(l->levers);
  std::swap(cost, l->cost);
}

void EifFactor::UnwhitenedLinearizationError(const EifEstimate& estimate, Eigen::VectorXd* e) const {
  // The factor is nonlinear only through the start heading θ: each position row is
  // Rᵀ(θ) v, v the lever from the start anchor to the end anchor or a landmark. Its linear
  // model at (θ₀, v₀) is Rᵀ(θ₀) v + Ṙᵀ(θ₀) v₀ (θ − θ₀), so the error is
  // (Rᵀ(θ) − Rᵀ(θ₀)) v − Ṙᵀ(θ₀) v₀ (θ − θ₀); the heading row is linear.
  const SubmapFactor& record = estimate.graph.factors()[index];
  const double theta = estimate.anchor_theta[record.start_anchor], dtheta = theta - start_theta;
  const Eigen::Vector2d p_s(estimate.graph.anchors()[record.start_anchor].x,
                            estimate.graph.anchors()[record.start_anchor].y);
  const Eigen::Matrix2d Rt = Pose2(0, 0, theta).rotation().transpose();
  const Eigen::Matrix2d Rt0 = Pose2(0, 0, start_theta).rotation().transpose();
  Eigen::Matrix2d dRt0;  // d/dθ Rᵀ(θ) at θ₀
  const double c = std::cos(start_theta), s = std::sin(start_theta);
  dRt0 << -s, c, -c, -s;
  const int n = static_cast<int>(levers_.size()) - 1;
  e->setZero(3 + 2 * n);
  const auto error = [&](const Eigen::Vector2d& v, const Eigen::Vector2d& v0) {
    return Eigen::Vector2d((Rt - Rt0) * v - dRt0 * v0 * dtheta);
  };
  e->head<2>() = error(
      Eigen::Vector2d(estimate.graph.anchors()[record.end_anchor].x, estimate.graph.anchors()[record.end_anchor].y) -
          p_s,
      levers_[0]);
  for (int i = 0; i < n; ++i) {
    e->segment<2>(3 + 2 * i) = error(estimate.graph.landmarks()[record.landmark_of_feature[i]] - p_s, levers_[i + 1]);
  }
}

double EifFactor::LinearizationError(const EifEstimate& estimate) const {
  Eigen::VectorXd e;
  UnwhitenedLinearizationError(estimate, &e);
  covariance_sqrt_->triangularView<Eigen::Lower>().solveInPlace(e);
  return e.squaredNorm();
}

EifFactor EifFactor::WithTermsOf(const EifFactor& other, const EifEstimate& estimate, int index) {
  EifFactor f;
  f.index = index;
  f.covariance_sqrt_ = other.covariance_sqrt_;
  f.information_ = other.information_;
  f.covariance_min_eigenvalue_ = other.covariance_min_eigenvalue_;
  f.SetLayout(estimate);
  return f;
}

bool EifFactor::LinearizationErrorAbove(const EifEstimate& estimate, double chi2, Eigen::VectorXd* scratch) const {
  const SubmapFactor& record = estimate.graph.factors()[index];
  const double dtheta = estimate.anchor_theta[record.start_anchor] - start_theta;
  if (dtheta == 0.0) return false;  // no error at all
  // A bound without trigonometry: the error of lever v (v₀ at the linearisation) is
  // (Rᵀ(θ) − Rᵀ(θ₀) − dRᵀ(θ₀)·Δθ) v + dRᵀ(θ₀)(v − v₀) Δθ, of norm at most
  // ½Δθ²‖v‖ + |Δθ|‖v − v₀‖ (‖d²Rᵀ/dθ²‖ = ‖dRᵀ/dθ‖ = 1); whitening scales a vector by at
  // most 1 / √λ_min(Q). Most factors are settled here.
  const Pose2& start = estimate.graph.anchors()[record.start_anchor];
  const Eigen::Vector2d p_s(start.x, start.y);
  const auto lever_bound = [&](const Eigen::Vector2d& v, const Eigen::Vector2d& v0) {
    return 0.5 * dtheta * dtheta * v.norm() + std::abs(dtheta) * (v - v0).norm();
  };
  const Pose2& end = estimate.graph.anchors()[record.end_anchor];
  double bound = Square(lever_bound(Eigen::Vector2d(end.x, end.y) - p_s, levers_[0]));
  for (size_t i = 0; i < record.landmark_of_feature.size(); ++i) {
    bound += Square(lever_bound(estimate.graph.landmarks()[record.landmark_of_feature[i]] - p_s, levers_[i + 1]));
  }
  if (bound <= chi2 * covariance_min_eigenvalue_) return false;
  // Then the unwhitened error (O(n)) before the triangular solve (O(n²)).
  Eigen::VectorXd& e = *scratch;
  UnwhitenedLinearizationError(estimate, &e);
  if (e.squaredNorm() <= chi2 * covariance_min_eigenvalue_) return false;
  covariance_sqrt_->triangularView<Eigen::Lower>().solveInPlace(e);
  return e.squaredNorm() > chi2;
}

double EifFactor::HeadingDrift(const EifEstimate& estimate) const {
  const SubmapFactor& record = estimate.graph.factors()[index];
  return std::max(std::abs(estimate.anchor_theta[record.start_anchor] - start_theta),
                  std::abs(estimate.anchor_theta[record.end_anchor] - end_theta));
}

}  // namespace subslam::backend
