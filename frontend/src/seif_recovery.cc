// SeifSlam: recovery — the mean by amortised relaxation (Gauss-Seidel over the active
// and round-robin landmarks) or exactly, and marginal covariances over a Markov blanket
// or exactly, and the map with its exact marginals.

#include <Eigen/Cholesky>
#include <Eigen/CholmodSupport>
#include <Eigen/LU>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "absl/strings/str_cat.h"
#include "subslam/core/check.h"
#include "subslam/core/stage_timer.h"
#include "subslam/frontend/internal/single_map_common.h"
#include "subslam/frontend/seif_slam.h"
#include "subslam/models/gating.h"

namespace subslam::frontend {

// Ω over the live variables, factorised by CHOLMOD; for exact mean and covariance
// recovery. Column of the pose: 0-2; of landmark i: Column(i), Column(i) + 1.
class SeifSlam::ExactSolver {
 public:
  explicit ExactSolver(const SeifSlam& f) : column_(f.landmarks_.size(), -1) {
    dim_ = 3;
    for (size_t i = 0; i < f.landmarks_.size(); ++i) {
      if (!f.landmarks_[i].alive) continue;
      column_[i] = dim_;
      dim_ += 2;
    }
    std::vector<Eigen::Triplet<double>> t;
    auto add_lower = [&t](int r0, int c0, const auto& block, bool diagonal) {
      for (int c = 0; c < block.cols(); ++c) {
        for (int r = diagonal ? c : 0; r < block.rows(); ++r) t.emplace_back(r0 + r, c0 + c, block(r, c));
      }
    };
    add_lower(0, 0, f.omega_xx_, true);
    for (const auto& [l, block] : f.pose_links_) add_lower(column_[l], 0, block.transpose(), false);
    for (size_t i = 0; i < f.landmarks_.size(); ++i) {
      if (!f.landmarks_[i].alive) continue;
      add_lower(column_[i], column_[i], f.omega_ll_[i], true);
      for (const auto& [j, block] : f.links_[i]) {
        if (static_cast<int>(i) > j) add_lower(column_[i], column_[j], block, false);
      }
    }
    Eigen::SparseMatrix<double> A(dim_, dim_);
    A.setFromTriplets(t.begin(), t.end());
    chol_.compute(A);
    ok_ = chol_.info() == Eigen::Success;
    if (!ok_) ++f.numerical_failures_;  // the information matrix is not positive definite
  }
  int dim() const { return dim_; }
  int Column(int landmark) const { return column_[landmark]; }
  // NaN when the factorisation failed: the estimate becomes non-finite and the run stops.
  Eigen::MatrixXd Solve(const Eigen::MatrixXd& b) const {
    if (!ok_) return Eigen::MatrixXd::Constant(b.rows(), b.cols(), std::numeric_limits<double>::quiet_NaN());
    return chol_.solve(b);
  }

 private:
  std::vector<int> column_;
  bool ok_ = false;
  int dim_ = 3;
  Eigen::CholmodDecomposition<Eigen::SparseMatrix<double>, Eigen::Lower> chol_;
};

void SeifSlam::RelaxPose() {
  Eigen::Vector3d r = xi_.head<3>();
  for (const auto& [l, block] : pose_links_) r.noalias() -= block * mu_.segment<2>(Offset(l));
  mu_.head<3>() = omega_xx_.ldlt().solve(r);
}

void SeifSlam::RelaxLandmark(int l) {
  if (!landmarks_[l].alive) return;  // e.g. observed, then culled in the same scan
  Eigen::Vector2d r = xi_.segment<2>(Offset(l));
  if (auto it = pose_links_.find(l); it != pose_links_.end()) r.noalias() -= it->second.transpose() * mu_.head<3>();
  for (const auto& [w, block] : links_[l]) r.noalias() -= block * mu_.segment<2>(Offset(w));
  mu_.segment<2>(Offset(l)) = omega_ll_[l].ldlt().solve(r);
  UpdateCell(l);
}

void SeifSlam::Relax(const std::vector<int>& landmarks, int sweeps) {
  for (int s = 0; s < sweeps; ++s) {
    RelaxPose();
    for (int l : landmarks) RelaxLandmark(l);
  }
}

void SeifSlam::RecoverMeanExactly() {
  FlushMotion();
  const ExactSolver solver(*this);
  Eigen::VectorXd b(solver.dim());
  b.head<3>() = xi_.head<3>();
  for (size_t i = 0; i < landmarks_.size(); ++i) {
    if (landmarks_[i].alive)
      b.segment<2>(solver.Column(static_cast<int>(i))) = xi_.segment<2>(Offset(static_cast<int>(i)));
  }
  const Eigen::VectorXd x = solver.Solve(b);
  mu_.head<3>() = x.head<3>();
  for (size_t i = 0; i < landmarks_.size(); ++i) {
    if (!landmarks_[i].alive) continue;
    mu_.segment<2>(Offset(static_cast<int>(i))) = x.segment<2>(solver.Column(static_cast<int>(i)));
    UpdateCell(static_cast<int>(i));
  }
  ++counters_.exact_recoveries;
  Invalidate();
}

void SeifSlam::RecoverLocally() {
  StageTimer timer(&times_, "recovery");
  Invalidate();
  if (options_.recovery == MeanRecovery::kExact) {
    RecoverMeanExactly();
  } else {
    Relax(ActiveLandmarks(), options_.relaxation_sweeps);  // the observed landmarks are active
  }
}

void SeifSlam::RecoverAmortised(const std::vector<int>& touched) {
  StageTimer timer(&times_, "recovery");
  Invalidate();
  std::vector<int> set = ActiveLandmarks();
  set.insert(set.end(), touched.begin(), touched.end());
  // A round-robin slice of the whole map, so that every landmark is revisited.
  const size_t slots = landmarks_.size();
  for (int added = 0, visited = 0; added < options_.relaxation_extra_landmarks && visited < static_cast<int>(slots);
       ++visited) {
    round_robin_ = (round_robin_ + 1) % slots;
    if (!landmarks_[round_robin_].alive) continue;
    set.push_back(static_cast<int>(round_robin_));
    ++added;
  }
  std::sort(set.begin(), set.end());
  set.erase(std::unique(set.begin(), set.end()), set.end());
  Relax(set, options_.relaxation_sweeps);
}

SeifSlam::LocalCovariance SeifSlam::Covariance(const std::vector<int>& landmarks, bool exact) const {
  LocalCovariance out;
  const int k = static_cast<int>(landmarks.size());
  for (int a = 0; a < k; ++a) out.offset[landmarks[a]] = 3 + 2 * a;
  if (exact) {
    const ExactSolver solver(*this);
    std::vector<int> rows = {0, 1, 2};
    for (int l : landmarks) {
      rows.push_back(solver.Column(l));
      rows.push_back(solver.Column(l) + 1);
    }
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(solver.dim(), rows.size());
    for (size_t c = 0; c < rows.size(); ++c) rhs(rows[c], c) = 1.0;
    out.sigma = solver.Solve(rhs)(rows, Eigen::all);
    return out;
  }
  // Markov blanket: the requested landmarks, the active ones and as many neighbours of
  // the requested ones as the cap allows; everything else is held at its mean.
  std::vector<int> blanket = landmarks;
  absl::flat_hash_map<int, int> in_blanket;
  for (int a = 0; a < k; ++a) in_blanket[landmarks[a]] = a;
  for (int l : ActiveLandmarks()) {
    if (in_blanket.try_emplace(l, static_cast<int>(blanket.size())).second) blanket.push_back(l);
  }
  for (int a = 0; a < k && static_cast<int>(blanket.size()) < options_.blanket_max_landmarks; ++a) {
    for (const auto& [w, block] : links_[landmarks[a]]) {
      if (static_cast<int>(blanket.size()) >= options_.blanket_max_landmarks) break;
      if (in_blanket.try_emplace(w, static_cast<int>(blanket.size())).second) blanket.push_back(w);
    }
  }
  const Eigen::LLT<Eigen::MatrixXd> llt(Gather(blanket));
  if (llt.info() != Eigen::Success) {  // not positive definite: no covariance (NaN)
    ++numerical_failures_;
    out.sigma = Eigen::MatrixXd::Constant(3 + 2 * k, 3 + 2 * k, std::numeric_limits<double>::quiet_NaN());
    return out;
  }
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(3 + 2 * blanket.size(), 3 + 2 * k);
  rhs.topLeftCorner(3 + 2 * k, 3 + 2 * k).setIdentity();  // the requested variables come first
  out.sigma = llt.solve(rhs).topRows(3 + 2 * k);
  return out;
}

Eigen::Matrix3d SeifSlam::pose_covariance() const {
  // Ω holds the pose at the last flush; the pending motion propagates its marginal
  // exactly (conditioning on passive landmarks commutes with a pose-only motion).
  const Eigen::Matrix3d* at_flush = &exact_pose_cov_;
  if (options_.pose_covariance == CovarianceRecovery::kMarkovBlanket) {
    if (pose_cov_version_ != version_) {
      pose_cov_ = Covariance({}, false).sigma;
      pose_cov_ = 0.5 * (pose_cov_ + pose_cov_.transpose()).eval();
      pose_cov_version_ = version_;
    }
    at_flush = &pose_cov_;
  }
  return pending_A_ * *at_flush * pending_A_.transpose() + pending_Q_;
}

std::vector<LandmarkEstimate> SeifSlam::Map() const {
  std::vector<int> confirmed;
  for (size_t i = 0; i < landmarks_.size(); ++i) {
    if (landmarks_[i].alive && landmarks_[i].confirmed) confirmed.push_back(static_cast<int>(i));
  }
  std::vector<LandmarkEstimate> out;
  if (confirmed.empty()) return out;
  const ExactSolver solver(*this);
  constexpr size_t kBatch = 64;  // landmarks per multi-column solve (bounds the memory)
  for (size_t start = 0; start < confirmed.size(); start += kBatch) {
    const size_t count = std::min(kBatch, confirmed.size() - start);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(solver.dim(), 2 * count);
    for (size_t a = 0; a < count; ++a) {
      const int c = solver.Column(confirmed[start + a]);
      rhs(c, 2 * a) = rhs(c + 1, 2 * a + 1) = 1.0;
    }
    const Eigen::MatrixXd columns = solver.Solve(rhs);
    for (size_t a = 0; a < count; ++a) {
      const int l = confirmed[start + a], c = solver.Column(l);
      Eigen::Matrix2d cov = columns.block<2, 2>(c, 2 * a);
      cov = 0.5 * (cov + cov.transpose()).eval();
      out.push_back({l, mu_.segment<2>(Offset(l)), cov});
    }
  }
  return out;
}

}  // namespace subslam::frontend
