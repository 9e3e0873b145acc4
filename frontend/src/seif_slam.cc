#include "subslam/frontend/seif_slam.h"

#include <Eigen/Cholesky>
#include <Eigen/CholmodSupport>
#include <Eigen/LU>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "absl/strings/str_cat.h"
#include "subslam/frontend/internal/single_map_common.h"
#include "subslam/graph/stage_timer.h"
#include "subslam/graph/check.h"
#include "subslam/models/gating.h"

namespace subslam::frontend {
namespace {

template <typename Derived>
bool IsZero(const Eigen::MatrixBase<Derived>& block) {
  return (block.array() == 0.0).all();
}

}  // namespace

const char* ToString(MeanRecovery recovery) {
  return recovery == MeanRecovery::kExact ? "exact" : "relaxation";
}
const char* ToString(CovarianceRecovery recovery) {
  return recovery == CovarianceRecovery::kExact ? "exact" : "markov-blanket";
}
absl::StatusOr<MeanRecovery> MeanRecoveryFromString(const std::string& name) {
  for (MeanRecovery r : {MeanRecovery::kExact, MeanRecovery::kRelaxation}) {
    if (name == ToString(r)) return r;
  }
  return absl::InvalidArgumentError(
      absl::StrCat("unknown mean recovery \"", name, "\" (expected exact or relaxation)"));
}
absl::StatusOr<CovarianceRecovery> CovarianceRecoveryFromString(const std::string& name) {
  for (CovarianceRecovery r : {CovarianceRecovery::kExact, CovarianceRecovery::kMarkovBlanket}) {
    if (name == ToString(r)) return r;
  }
  return absl::InvalidArgumentError(
      absl::StrCat("unknown covariance recovery \"", name, "\" (expected exact or markov-blanket)"));
}

absl::Status SeifOptions::Validate() const {
  if (absl::Status s = internal::ValidateAssociationAndExistence(
          gate_probability, new_landmark_probability, existence, jcbb_max_nodes,
          expect_range_margin_m, expect_bearing_margin_rad, cull_every_scans);
      !s.ok()) {
    return s;
  }
  if (!(candidate_radius_m > 0)) {
    return absl::InvalidArgumentError(absl::StrCat("candidate_radius_m must be > 0, got ", candidate_radius_m));
  }
  if (max_active_landmarks < 0 || relaxation_sweeps < 1 || relaxation_extra_landmarks < 0 ||
      blanket_max_landmarks < 0) {
    return absl::InvalidArgumentError(
        "max_active_landmarks >= 0, relaxation_sweeps >= 1, relaxation_extra_landmarks >= 0 "
        "and blanket_max_landmarks >= 0 required");
  }
  if (!(initial_pose_sigma.array() > 0).all() || !initial_pose_sigma.allFinite()) {
    return absl::InvalidArgumentError("initial_pose_sigma must be finite and > 0 (SEIF needs a prior)");
  }
  if (iterated.period_scans < 1 || iterated.max_iterations < 1 || !(iterated.stop_change >= 0) ||
      iterated.exact_recoveries < 0) {
    return absl::InvalidArgumentError(
        "iterated: period_scans >= 1, max_iterations >= 1, stop_change >= 0 and exact_recoveries >= 0 "
        "required");
  }
  return absl::OkStatus();
}

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
    SUBSLAM_CHECK(chol_.info() == Eigen::Success) << "SEIF information matrix not positive definite";
  }
  int dim() const { return dim_; }
  int Column(int landmark) const { return column_[landmark]; }
  Eigen::MatrixXd Solve(const Eigen::MatrixXd& b) const { return chol_.solve(b); }

 private:
  std::vector<int> column_;
  int dim_ = 3;
  Eigen::CholmodDecomposition<Eigen::SparseMatrix<double>, Eigen::Lower> chol_;
};

struct SeifSlam::Linearization {
  std::vector<int> landmarks;  // distinct, in the order of D's blocks
  Eigen::MatrixXd D;           // added to Ω over [pose, landmarks]
  Eigen::VectorXd dxi;         // added to ξ
};

SeifSlam::SeifSlam(std::unique_ptr<models::MotionModel> motion,
                   const models::RangeBearingConfig& sensor, const Pose2& initial_pose,
                   const SeifOptions& options)
    : motion_(std::move(motion)), sensor_(sensor), options_(options) {
  SUBSLAM_CHECK(options_.Validate().ok()) << options_.Validate().message();
  gate_d2_ = models::ChiSquareQuantile(options_.gate_probability, 2);
  new_landmark_d2_ = models::ChiSquareQuantile(options_.new_landmark_probability, 2);
  cell_size_m_ = sensor.max_range_m + 10.0;  // the reach of a scan: a 3 × 3 block of cells covers it
  Reserve(64);
  omega_xx_ = options_.initial_pose_sigma.array().square().inverse().matrix().asDiagonal();
  mu_.head<3>() = initial_pose.vector();
  xi_.head<3>() = omega_xx_ * mu_.head<3>();
  exact_pose_cov_ = omega_xx_.inverse();
  for (const char* stage : {"motion", "associate", "measurement", "iteration", "sparsification",
                            "recovery", "map_management"}) {
    times_[stage] = 0;
  }
}

SeifSlam::~SeifSlam() = default;

int64_t SeifSlam::CellCoordinate(double v) const {
  return static_cast<int64_t>(std::floor(v / cell_size_m_));
}

uint64_t SeifSlam::CellKey(int64_t cx, int64_t cy) {
  // Offset binary in 31 bits per axis: never equal to kNoCell (all ones).
  constexpr int64_t kLimit = (int64_t{1} << 30) - 1;
  const uint64_t ux = static_cast<uint64_t>(std::clamp(cx, -kLimit, kLimit) + kLimit);
  const uint64_t uy = static_cast<uint64_t>(std::clamp(cy, -kLimit, kLimit) + kLimit);
  return (ux << 31) | uy;
}

void SeifSlam::RemoveFromCell(int l) {
  if (cell_of_[l] == kNoCell) return;
  std::vector<int>& members = grid_[cell_of_[l]];
  members.erase(std::find(members.begin(), members.end(), l));
  cell_of_[l] = kNoCell;
}

void SeifSlam::UpdateCell(int l) {
  const Eigen::Vector2d m = mu_.segment<2>(Offset(l));
  const uint64_t key = m.allFinite() ? CellKey(CellCoordinate(m.x()), CellCoordinate(m.y())) : kNoCell;
  if (key == cell_of_[l]) return;
  RemoveFromCell(l);
  if (key == kNoCell) return;
  grid_[key].push_back(l);
  cell_of_[l] = key;
}

void SeifSlam::Reserve(int landmarks) {
  const int capacity = (static_cast<int>(xi_.size()) - 3) / 2;
  if (landmarks <= capacity) return;
  const int new_capacity = std::max(landmarks, 2 * capacity);
  const int live = 3 + 2 * static_cast<int>(landmarks_.size());
  Eigen::VectorXd xi = Eigen::VectorXd::Zero(3 + 2 * new_capacity), mu = xi;
  if (xi_.size() > 0) {
    xi.head(live) = xi_.head(live);
    mu.head(live) = mu_.head(live);
  }
  xi_.swap(xi);
  mu_.swap(mu);
}

int SeifSlam::AddLandmarkSlot(const Eigen::Vector2d& mean) {
  const int l = static_cast<int>(landmarks_.size());
  Reserve(l + 1);
  landmarks_.emplace_back();
  omega_ll_.push_back(Eigen::Matrix2d::Zero());
  links_.emplace_back();
  mu_.segment<2>(Offset(l)) = mean;
  cell_of_.push_back(kNoCell);
  UpdateCell(l);
  xi_.segment<2>(Offset(l)).setZero();
  ++live_landmarks_;
  return l;
}

int SeifSlam::num_landmarks() const { return live_landmarks_; }

long SeifSlam::num_landmark_links() const {
  long n = 0;
  for (const auto& l : links_) n += static_cast<long>(l.size());
  return n / 2;
}

std::vector<int> SeifSlam::ActiveLandmarks() const {
  std::vector<int> active;
  active.reserve(pose_links_.size());
  for (const auto& [l, block] : pose_links_) active.push_back(l);
  std::sort(active.begin(), active.end());
  return active;
}

Pose2 SeifSlam::pose() const {
  return Pose2(mu_[0], mu_[1], WrapAngle(mu_[2]));
}

Eigen::MatrixXd SeifSlam::Gather(const std::vector<int>& landmarks) const {
  const int k = static_cast<int>(landmarks.size());
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(3 + 2 * k, 3 + 2 * k);
  absl::flat_hash_map<int, int> position;
  for (int a = 0; a < k; ++a) position[landmarks[a]] = a;
  G.topLeftCorner<3, 3>() = omega_xx_;
  for (int a = 0; a < k; ++a) {
    const int l = landmarks[a], o = 3 + 2 * a;
    if (auto it = pose_links_.find(l); it != pose_links_.end()) {
      G.block<3, 2>(0, o) = it->second;
      G.block<2, 3>(o, 0) = it->second.transpose();
    }
    G.block<2, 2>(o, o) = omega_ll_[l];
    for (const auto& [w, block] : links_[l]) {
      if (auto it = position.find(w); it != position.end()) G.block<2, 2>(o, 3 + 2 * it->second) = block;
    }
  }
  return G;
}

Eigen::VectorXd SeifSlam::GatherXi(const std::vector<int>& landmarks) const {
  Eigen::VectorXd v(3 + 2 * landmarks.size());
  v.head<3>() = xi_.head<3>();
  for (size_t a = 0; a < landmarks.size(); ++a) v.segment<2>(3 + 2 * a) = xi_.segment<2>(Offset(landmarks[a]));
  return v;
}

Eigen::VectorXd SeifSlam::GatherMean(const std::vector<int>& landmarks) const {
  Eigen::VectorXd v(3 + 2 * landmarks.size());
  v.head<3>() = mu_.head<3>();
  for (size_t a = 0; a < landmarks.size(); ++a) v.segment<2>(3 + 2 * a) = mu_.segment<2>(Offset(landmarks[a]));
  return v;
}

void SeifSlam::ScatterAdd(const std::vector<int>& landmarks, const Eigen::MatrixXd& D) {
  const int k = static_cast<int>(landmarks.size());
  omega_xx_ += D.topLeftCorner<3, 3>();
  for (int a = 0; a < k; ++a) {
    const int l = landmarks[a], o = 3 + 2 * a;
    const Matrix32d xl = D.block<3, 2>(0, o);
    if (!IsZero(xl)) {
      auto [it, inserted] = pose_links_.try_emplace(l, Matrix32d::Zero());
      it->second += xl;
      if (IsZero(it->second)) pose_links_.erase(it);
    }
    omega_ll_[l] += D.block<2, 2>(o, o);
    for (int b = a + 1; b < k; ++b) {
      const Eigen::Matrix2d lw = D.block<2, 2>(o, 3 + 2 * b);
      if (IsZero(lw)) continue;
      const int w = landmarks[b];
      auto [it, inserted] = links_[l].try_emplace(w, Eigen::Matrix2d::Zero());
      it->second += lw;
      if (IsZero(it->second)) {
        links_[l].erase(it);
        links_[w].erase(l);
      } else {
        links_[w][l] = it->second.transpose();
      }
    }
  }
}

void SeifSlam::AddXi(const std::vector<int>& landmarks, const Eigen::VectorXd& d) {
  xi_.head<3>() += d.head<3>();
  for (size_t a = 0; a < landmarks.size(); ++a) xi_.segment<2>(Offset(landmarks[a])) += d.segment<2>(3 + 2 * a);
}

void SeifSlam::WrapHeading() {
  // Shifting the heading coordinate by s keeps the Gaussian: ξ += s Ω e_θ.
  const double wrapped = WrapAngle(mu_[2]);
  const double s = wrapped - mu_[2];
  if (s == 0.0) return;
  mu_[2] = wrapped;
  xi_.head<3>() += s * omega_xx_.col(2);
  for (const auto& [l, block] : pose_links_) xi_.segment<2>(Offset(l)) += s * block.row(2).transpose();
}

void SeifSlam::Predict(const Eigen::Vector2d& u, double dt) {
  if (dt <= 0.0) return;
  StageTimer timer(&times_, "motion");
  Eigen::Matrix3d A;
  Matrix32d G;
  const Eigen::Vector3d mx = mu_.head<3>();
  if (!motion_pending_) flushed_pose_ = mx;  // the chain starts at the current estimate
  Eigen::Vector3d fx = motion_->Predict(pose(), u, dt, &A, &G).vector();
  fx[2] = mx[2] + WrapAngle(fx[2] - mx[2]);  // keep μ_θ continuous until the flush
  // Compose with the pending motion: x_now ≈ A_p (x_flushed − μ_flushed) + μ_now + w,
  // w ~ N(0, Q_p). A chain of pose-only linear-Gaussian steps is one such step.
  pending_A_ = A * pending_A_;
  pending_Q_ = A * pending_Q_ * A.transpose() + G * motion_->noise().Covariance(u) * G.transpose();
  mu_.head<3>() = fx;
  motion_pending_ = true;
}

void SeifSlam::FlushMotion() {
  if (!motion_pending_) return;
  StageTimer timer(&times_, "motion");
  Invalidate();
  const Eigen::Matrix3d& A = pending_A_;
  const Eigen::Matrix3d& Q = pending_Q_;
  const Eigen::Vector3d c = mu_.head<3>() - A * flushed_pose_;

  const std::vector<int> active = ActiveLandmarks();
  const Eigen::MatrixXd omega = Gather(active);
  const Eigen::Matrix3d A_inv = A.inverse();
  // Φ = T⁻ᵀ Ω T⁻¹ with T = diag(A, I): only the pose rows and columns change.
  Eigen::MatrixXd phi = omega;
  phi.topRows<3>() = A_inv.transpose() * phi.topRows<3>();
  phi.leftCols<3>() = phi.leftCols<3>() * A_inv;
  Eigen::VectorXd xi = GatherXi(active);
  xi.head<3>() = A_inv.transpose() * xi.head<3>();
  xi += phi.leftCols<3>() * c;
  // M = (Q⁻¹ + Φ_xx)⁻¹ = Q (I + Φ_xx Q)⁻¹, defined for a singular Q.
  Eigen::Matrix3d M = Q * (Eigen::Matrix3d::Identity() + phi.topLeftCorner<3, 3>() * Q).inverse();
  M = 0.5 * (M + M.transpose()).eval();
  const Eigen::MatrixXd phi_x = phi.leftCols<3>();
  const Eigen::Vector3d xi_x = xi.head<3>();
  Eigen::MatrixXd updated = phi;
  updated.noalias() -= phi_x * M * phi_x.transpose();
  xi.noalias() -= phi_x * (M * xi_x);
  ScatterAdd(active, updated - omega);
  AddXi(active, xi - GatherXi(active));
  pending_A_.setIdentity();
  pending_Q_.setZero();
  motion_pending_ = false;
  WrapHeading();
}

SeifSlam::Linearization SeifSlam::ApplyMeasurements(
    const std::vector<std::pair<int, Eigen::Vector2d>>& pairs) {
  Linearization lin;
  absl::flat_hash_map<int, int> position;
  for (const auto& [l, z] : pairs) {
    if (position.try_emplace(l, static_cast<int>(lin.landmarks.size())).second) lin.landmarks.push_back(l);
  }
  const int m = static_cast<int>(pairs.size());
  const int dim = 3 + 2 * static_cast<int>(lin.landmarks.size());
  const Pose2 p = pose();
  const Eigen::Vector2d r_inv = sensor_.NoiseCovariance().diagonal().cwiseInverse();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(2 * m, dim);
  Eigen::VectorXd nu(2 * m);
  for (int a = 0; a < m; ++a) {
    const auto& [l, z] = pairs[a];
    Matrix23d H_pose;
    Eigen::Matrix2d H_landmark;
    const Eigen::Vector2d z_hat = sensor_.Observe(p, mu_.segment<2>(Offset(l)), &H_pose, &H_landmark);
    J.block<2, 3>(2 * a, 0) = H_pose;
    J.block<2, 2>(2 * a, 3 + 2 * position[l]) = H_landmark;
    nu.segment<2>(2 * a) = models::RangeBearingModel::Difference(z, z_hat);
  }
  Eigen::MatrixXd JtRinv = J.transpose();
  for (int a = 0; a < m; ++a) JtRinv.middleCols<2>(2 * a) *= r_inv.asDiagonal();
  lin.D.noalias() = JtRinv * J;
  lin.dxi.noalias() = JtRinv * (nu + J * GatherMean(lin.landmarks));
  ScatterAdd(lin.landmarks, lin.D);
  AddXi(lin.landmarks, lin.dxi);
  return lin;
}

void SeifSlam::Retract(const Linearization& lin) {
  ScatterAdd(lin.landmarks, -lin.D);
  AddXi(lin.landmarks, -lin.dxi);
}

void SeifSlam::Sparsify() {
  const int bound = options_.max_active_landmarks;
  if (bound == 0 || num_active_landmarks() <= bound) return;
  StageTimer timer(&times_, "sparsification");
  // m⁺: the `bound` most recently seen active landmarks; m⁰: the rest.
  std::vector<int> active = ActiveLandmarks();
  std::sort(active.begin(), active.end(), [this](int a, int b) {
    const long sa = landmarks_[a].last_seen_scan, sb = landmarks_[b].last_seen_scan;
    return sa != sb ? sa > sb : a > b;
  });
  const std::vector<int> passive(active.begin() + bound, active.end());
  const int k = static_cast<int>(active.size());
  const Eigen::MatrixXd omega0 = Gather(active);  // Ω restricted to {x, m⁺, m⁰}: conditioned on m⁻ = μ⁻
  std::vector<int> m0_index, x_m0_index = {0, 1, 2}, x_index = {0, 1, 2};
  for (int a = bound; a < k; ++a) {
    for (int d = 0; d < 2; ++d) {
      m0_index.push_back(3 + 2 * a + d);
      x_m0_index.push_back(3 + 2 * a + d);
    }
  }
  auto schur_term = [&omega0](const std::vector<int>& idx) -> Eigen::MatrixXd {
    const Eigen::MatrixXd cols = omega0(Eigen::all, idx);
    return cols * Eigen::MatrixXd(omega0(idx, idx)).ldlt().solve(cols.transpose());
  };
  // Thrun Table 12.7: Ω̃ = Ω − [Ω⁰ marg. m⁰] + [Ω⁰ marg. x, m⁰] − [Ω marg. x] terms.
  Eigen::MatrixXd D = -schur_term(m0_index) + schur_term(x_m0_index) - schur_term(x_index);
  // The x–m⁰ blocks of Ω̃ are zero in exact arithmetic: make them exactly zero.
  for (int a = bound; a < k; ++a) {
    D.block<3, 2>(0, 3 + 2 * a) = -omega0.block<3, 2>(0, 3 + 2 * a);
    D.block<2, 3>(3 + 2 * a, 0) = -omega0.block<2, 3>(3 + 2 * a, 0);
  }
  D = 0.5 * (D + D.transpose()).eval();
  const Eigen::VectorXd dxi = D * GatherMean(active);  // ξ̃ = ξ + (Ω̃ − Ω) μ
  ScatterAdd(active, D);
  AddXi(active, dxi);
  for (int l : passive) pose_links_.erase(l);  // already exactly zero: ScatterAdd erased them
  ++counters_.sparsifications;
  counters_.deactivated_landmarks += static_cast<long>(passive.size());
}

void SeifSlam::Marginalize(int landmark) {
  std::vector<int> blanket;
  for (const auto& [w, block] : links_[landmark]) blanket.push_back(w);
  std::sort(blanket.begin(), blanket.end());
  std::vector<int> with_landmark = blanket;
  with_landmark.push_back(landmark);
  const Eigen::MatrixXd omega = Gather(with_landmark);
  const int o = static_cast<int>(omega.rows()) - 2;  // l's rows, after the pose and the blanket
  const Eigen::LDLT<Eigen::Matrix2d> ll(omega.block<2, 2>(o, o));
  const Eigen::MatrixXd cross = omega.block(0, o, o, 2);  // Ω_{rest, l}
  ScatterAdd(blanket, -cross * ll.solve(cross.transpose()));
  AddXi(blanket, -cross * ll.solve(xi_.segment<2>(Offset(landmark))));
  for (int w : blanket) links_[w].erase(landmark);
  links_[landmark].clear();
  pose_links_.erase(landmark);
  omega_ll_[landmark].setZero();
  xi_.segment<2>(Offset(landmark)).setZero();
  landmarks_[landmark].alive = false;
  RemoveFromCell(landmark);
  if (landmarks_[landmark].truth_id >= 0) landmark_of_truth_.erase(landmarks_[landmark].truth_id);
  --live_landmarks_;
}

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
    if (landmarks_[i].alive) b.segment<2>(solver.Column(static_cast<int>(i))) = xi_.segment<2>(Offset(static_cast<int>(i)));
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
  for (int added = 0, visited = 0; added < options_.relaxation_extra_landmarks &&
                                   visited < static_cast<int>(slots); ++visited) {
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
  SUBSLAM_CHECK(llt.info() == Eigen::Success) << "SEIF Markov-blanket information not positive definite";
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

void SeifSlam::UpdateExistence(LandmarkInfo* info, bool detected) const {
  info->existence = options_.existence.Update(info->existence, detected);
  if (options_.existence.Confirms(info->existence)) info->confirmed = true;
}

void SeifSlam::Update(const Scan& scan) {
  FlushMotion();
  ++counters_.scans;
  Invalidate();
  const Pose2 p = pose();
  const models::RangeBearingConfig& rb = sensor_.config();
  const Eigen::Matrix2d R = sensor_.NoiseCovariance();

  const internal::UsableDetections usable = internal::DetectionsInRange(scan, rb);
  const std::vector<Eigen::Vector2d>& z = usable.z;
  const std::vector<int>& detection_index = usable.index;
  scan_features_.assign(scan.detections.size(), -1);
  counters_.detections += static_cast<long>(z.size());
  const int m = static_cast<int>(z.size());

  // 1. Association.
  std::vector<int> landmark_of_detection(m, -1);
  std::vector<bool> creates(m, false);
  absl::flat_hash_map<int, bool> gated;  // landmarks within reach → gated with a detection
  std::vector<int> in_reach;
  {
    StageTimer timer(&times_, "associate");
    const double reach = cell_size_m_;
    const int64_t cx = CellCoordinate(p.x), cy = CellCoordinate(p.y);
    for (int64_t dx = -1; dx <= 1; ++dx) {
      for (int64_t dy = -1; dy <= 1; ++dy) {
        auto it = grid_.find(CellKey(cx + dx, cy + dy));
        if (it == grid_.end()) continue;
        for (int l : it->second) {
          if ((mu_.segment<2>(Offset(l)) - p.translation()).squaredNorm() <= reach * reach) in_reach.push_back(l);
        }
      }
    }
    std::sort(in_reach.begin(), in_reach.end());
    for (int l : in_reach) gated[l] = false;
    if (options_.known_association) {
      for (int j = 0; j < m; ++j) {
        const int truth = scan.detections[detection_index[j]].truth_id;
        if (truth < 0) continue;  // a false alarm: no true landmark to associate with
        if (auto it = landmark_of_truth_.find(truth); it != landmark_of_truth_.end()) {
          landmark_of_detection[j] = it->second;
          if (auto g = gated.find(it->second); g != gated.end()) g->second = true;
        } else {
          creates[j] = true;
        }
      }
    } else {
      std::vector<Eigen::Vector2d> points(m);
      for (int j = 0; j < m; ++j) points[j] = sensor_.InverseObserve(p, z[j]);
      const double r2 = options_.candidate_radius_m * options_.candidate_radius_m;
      std::vector<int> candidates;
      for (int l : in_reach) {
        for (int j = 0; j < m; ++j) {
          if ((mu_.segment<2>(Offset(l)) - points[j]).squaredNorm() <= r2) {
            candidates.push_back(l);
            break;
          }
        }
      }
      const LocalCovariance cov =
          Covariance(candidates, options_.covariance == CovarianceRecovery::kExact);
      struct Prediction {
        Eigen::Vector2d z;
        Eigen::Matrix<double, 2, 5> H;
        Eigen::Matrix2d S;
      };
      absl::flat_hash_map<int, Prediction> prediction;
      auto joint = [&cov](int a, int b) -> Eigen::Matrix<double, 5, 5> {
        // Σ over [x, l_a] × [x, l_b].
        const int oa = cov.offset.at(a), ob = cov.offset.at(b);
        Eigen::Matrix<double, 5, 5> s;
        s.topLeftCorner<3, 3>() = cov.sigma.topLeftCorner<3, 3>();
        s.topRightCorner<3, 2>() = cov.sigma.block<3, 2>(0, ob);
        s.bottomLeftCorner<2, 3>() = cov.sigma.block<2, 3>(oa, 0);
        s.bottomRightCorner<2, 2>() = cov.sigma.block<2, 2>(oa, ob);
        return s;
      };
      for (int l : candidates) {
        Prediction pr;
        Matrix23d H_pose;
        Eigen::Matrix2d H_landmark;
        pr.z = sensor_.Observe(p, mu_.segment<2>(Offset(l)), &H_pose, &H_landmark);
        pr.H << H_pose, H_landmark;
        pr.S = pr.H * joint(l, l) * pr.H.transpose() + R;
        pr.S = 0.5 * (pr.S + pr.S.transpose()).eval();
        prediction[l] = pr;
      }
      association::AssociationProblem problem;
      problem.candidates.resize(m);
      std::vector<double> min_d2(m, INFINITY);
      for (int j = 0; j < m; ++j) {
        for (int l : candidates) {
          const Prediction& pr = prediction[l];
          const Eigen::Vector2d nu = models::RangeBearingModel::Difference(z[j], pr.z);
          const std::optional<double> d2 = models::MahalanobisSquared2(nu, pr.S);
          SUBSLAM_CHECK(d2.has_value()) << "innovation covariance not positive definite";
          min_d2[j] = std::min(min_d2[j], *d2);
          if (*d2 < new_landmark_d2_) gated[l] = true;
          if (*d2 < gate_d2_) problem.candidates[j].push_back({l, *d2, nu});
        }
        std::sort(problem.candidates[j].begin(), problem.candidates[j].end(),
                  [](const association::AssociationCandidate& a, const association::AssociationCandidate& b) { return a.d2 < b.d2; });
      }
      association::AssociationResult association;
      if (options_.association == association::AssociationMethod::kJointCompatibility) {
        problem.covariance_block = [&](int, int a, int, int b) -> Eigen::Matrix2d {
          if (a == b) return prediction[a].S;
          return prediction[a].H * joint(a, b) * prediction[b].H.transpose();
        };
        association = association::JointCompatibility(problem, options_.gate_probability, options_.jcbb_max_nodes);
        if (association.truncated) ++counters_.jcbb_truncated;
      } else {
        association = association::NearestNeighbour(problem);
      }
      for (int j = 0; j < m; ++j) {
        landmark_of_detection[j] = association.landmark_of_detection[j];
        if (landmark_of_detection[j] < 0) {
          if (min_d2[j] > new_landmark_d2_) {
            creates[j] = true;
          } else {
            ++counters_.ambiguous;
          }
        }
      }
    }
  }

  // 2. Measurement update of the associations; ISEIF relinearises it to convergence.
  std::vector<std::pair<int, Eigen::Vector2d>> pairs;
  std::vector<int> touched;
  for (int j = 0; j < m; ++j) {
    if (landmark_of_detection[j] < 0) continue;
    pairs.push_back({landmark_of_detection[j], z[j]});
    touched.push_back(landmark_of_detection[j]);
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  if (!pairs.empty()) {
    const bool iterate = options_.iterated.enabled && options_.iterated.max_iterations > 1 &&
                         counters_.scans % options_.iterated.period_scans == 0;
    // μ⁰, the prediction, over the pose and the observed landmarks (Eq. 28's g).
    Eigen::VectorXd previous = GatherMean(touched);
    Linearization lin;
    for (int i = 1;; ++i) {
      // Eqs. 14-19: linearise at the latest estimate μⁱ⁻¹, starting from the prediction;
      // the first pass is the SEIF update.
      {
        StageTimer timer(&times_, i == 1 ? "measurement" : "iteration");
        if (i > 1) Retract(lin);
        lin = ApplyMeasurements(pairs);
      }
      if (!iterate) {
        RecoverLocally();  // the pose the new landmarks are initialised from
        break;
      }
      StageTimer timer(&times_, "iteration");
      ++counters_.iterations;
      if (i <= options_.iterated.exact_recoveries) {
        RecoverMeanExactly();
      } else {
        Relax(ActiveLandmarks(), options_.relaxation_sweeps);
      }
      const Eigen::VectorXd current = GatherMean(touched);
      Eigen::VectorXd change = current - previous;
      change[2] = WrapAngle(change[2]);
      previous = current;
      if (change.cwiseAbs().maxCoeff() < options_.iterated.stop_change ||
          i == options_.iterated.max_iterations) {
        ++counters_.iterated_updates;
        break;
      }
    }
    counters_.associated += static_cast<long>(pairs.size());
  }

  // 3. Existence, new landmarks, deletion of false alarms.
  std::vector<int> created;
  {
    StageTimer timer(&times_, "map_management");
    for (int j = 0; j < m; ++j) {
      const int l = landmark_of_detection[j];
      if (l < 0) continue;
      UpdateExistence(&landmarks_[l], true);
      landmarks_[l].last_seen_scan = counters_.scans;
      scan_features_[detection_index[j]] = l;
    }
    for (int l : in_reach) {
      if (gated[l]) continue;
      const Eigen::Vector2d z_hat = sensor_.Observe(p, mu_.segment<2>(Offset(l)));
      if (sensor_.IsVisible(z_hat, options_.expect_range_margin_m, options_.expect_bearing_margin_rad)) {
        UpdateExistence(&landmarks_[l], false);
      }
    }
    std::vector<std::pair<int, Eigen::Vector2d>> new_pairs;
    const Pose2 updated = pose();
    for (int j = 0; j < m; ++j) {
      if (!creates[j]) continue;
      const int l = AddLandmarkSlot(sensor_.InverseObserve(updated, z[j]));
      LandmarkInfo& info = landmarks_[l];
      info.existence = options_.existence.Initial();
      info.confirmed = options_.existence.Confirms(info.existence);
      info.last_seen_scan = counters_.scans;
      if (options_.known_association) {
        info.truth_id = scan.detections[detection_index[j]].truth_id;
        landmark_of_truth_[info.truth_id] = l;
      }
      scan_features_[detection_index[j]] = l;
      new_pairs.push_back({l, z[j]});
      created.push_back(l);
      ++counters_.new_landmarks;
    }
    // The first detection's information: ν = 0 at μ_l = g(μ_x, z), so the mean holds.
    if (!new_pairs.empty()) ApplyMeasurements(new_pairs);
    if (counters_.scans % options_.cull_every_scans == 0) {
      for (size_t i = 0; i < landmarks_.size(); ++i) {
        LandmarkInfo& info = landmarks_[i];
        if (info.alive && options_.existence.Deletes(info.existence, info.confirmed)) {
          Marginalize(static_cast<int>(i));
          ++counters_.deleted_landmarks;
        }
      }
    }
  }
  counters_.max_active = std::max<long>(counters_.max_active, num_active_landmarks());

  // 4. Sparsification, then the amortised recovery (exact recovery needs none: the
  // new landmarks, the marginalisation and sparsification all keep Ω μ = ξ).
  Sparsify();
  if (options_.recovery == MeanRecovery::kRelaxation) {
    touched.insert(touched.end(), created.begin(), created.end());
    RecoverAmortised(touched);
  }
  // Only here and after the motion update: an iterated update must not see its
  // coordinates shift between applying a linearisation and taking it back.
  WrapHeading();
  if (options_.pose_covariance == CovarianceRecovery::kExact) {
    StageTimer timer(&times_, "pose_covariance");
    const Eigen::Matrix3d sigma = Covariance({}, true).sigma;
    exact_pose_cov_ = 0.5 * (sigma + sigma.transpose());
  }
}

std::vector<int> SeifSlam::LiveLandmarkIds() const {
  std::vector<int> ids;
  for (size_t i = 0; i < landmarks_.size(); ++i) {
    if (landmarks_[i].alive) ids.push_back(static_cast<int>(i));
  }
  return ids;
}

Eigen::MatrixXd SeifSlam::DenseInformation() {
  FlushMotion();
  return Gather(LiveLandmarkIds());
}
Eigen::VectorXd SeifSlam::DenseInformationVector() {
  FlushMotion();
  return GatherXi(LiveLandmarkIds());
}
Eigen::VectorXd SeifSlam::DenseMean() const { return GatherMean(LiveLandmarkIds()); }

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

std::map<std::string, double> SeifSlam::Counters() const {
  int confirmed = 0;
  for (const LandmarkInfo& l : landmarks_) confirmed += l.alive && l.confirmed ? 1 : 0;
  return {{"scans", counters_.scans},
          {"detections", counters_.detections},
          {"associated", counters_.associated},
          {"new_landmarks", counters_.new_landmarks},
          {"ambiguous_detections", counters_.ambiguous},
          {"deleted_landmarks", counters_.deleted_landmarks},
          {"jcbb_truncated_scans", counters_.jcbb_truncated},
          {"sparsifications", counters_.sparsifications},
          {"deactivated_landmarks", counters_.deactivated_landmarks},
          {"max_active_landmarks", counters_.max_active},
          {"iterated_updates", counters_.iterated_updates},
          {"iterations", counters_.iterations},
          {"mean_iterations_per_iterated_update",
           counters_.iterated_updates > 0
               ? static_cast<double>(counters_.iterations) / counters_.iterated_updates : 0.0},
          {"exact_recoveries", counters_.exact_recoveries},
          {"landmark_links", num_landmark_links()},
          {"landmarks_in_state", num_landmarks()},
          {"confirmed_landmarks", confirmed}};
}

}  // namespace subslam::frontend
