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
#include "subslam/core/check.h"
#include "subslam/core/enum_names.h"
#include "subslam/core/stage_timer.h"
#include "subslam/frontend/internal/single_map_common.h"
#include "subslam/models/gating.h"

namespace subslam::frontend {

namespace {

template <typename Derived>
bool IsZero(const Eigen::MatrixBase<Derived>& block) {
  return (block.array() == 0.0).all();
}

}  // namespace

namespace {
constexpr EnumName<MeanRecovery> kMeanRecoveryNames[] = {{MeanRecovery::kExact, "exact"},
                                                         {MeanRecovery::kRelaxation, "relaxation"}};
constexpr EnumName<CovarianceRecovery> kCovarianceRecoveryNames[] = {
    {CovarianceRecovery::kExact, "exact"}, {CovarianceRecovery::kMarkovBlanket, "markov-blanket"}};
}  // namespace

const char* ToString(MeanRecovery recovery) { return NameOf(kMeanRecoveryNames, recovery); }
const char* ToString(CovarianceRecovery recovery) { return NameOf(kCovarianceRecoveryNames, recovery); }

absl::StatusOr<MeanRecovery> MeanRecoveryFromString(const std::string& name) {
  return ParseEnum(kMeanRecoveryNames, name, "mean recovery");
}

absl::StatusOr<CovarianceRecovery> CovarianceRecoveryFromString(const std::string& name) {
  return ParseEnum(kCovarianceRecoveryNames, name, "covariance recovery");
}

absl::Status SeifOptions::Validate() const {
  if (jcbb_max_nodes < 1) return absl::InvalidArgumentError("jcbb_max_nodes must be >= 1");
  if (absl::Status s = landmarks.Validate(); !s.ok()) return s;
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

SeifSlam::SeifSlam(std::unique_ptr<models::MotionModel> motion, const models::RangeBearingConfig& sensor,
                   const Pose2& initial_pose, const SeifOptions& options)
    : motion_(std::move(motion)), sensor_(sensor), options_(options) {
  SUBSLAM_CHECK(options_.Validate().ok()) << options_.Validate().message();
  gate_d2_ = models::ChiSquareQuantile(options_.landmarks.gate_probability, 2);
  new_landmark_d2_ = models::ChiSquareQuantile(options_.landmarks.new_landmark_probability, 2);
  cell_size_m_ = sensor.max_range_m + 10.0;  // the reach of a scan: a 3 × 3 block of cells covers it
  Reserve(64);
  omega_xx_ = options_.initial_pose_sigma.array().square().inverse().matrix().asDiagonal();
  mu_.head<3>() = initial_pose.vector();
  xi_.head<3>() = omega_xx_ * mu_.head<3>();
  exact_pose_cov_ = omega_xx_.inverse();
  for (const char* stage :
       {"motion", "associate", "measurement", "iteration", "sparsification", "recovery", "map_management"}) {
    times_[stage] = 0;
  }
}

SeifSlam::~SeifSlam() = default;

int64_t SeifSlam::CellCoordinate(double v) const { return static_cast<int64_t>(std::floor(v / cell_size_m_)); }

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

Pose2 SeifSlam::pose() const { return Pose2(mu_[0], mu_[1], WrapAngle(mu_[2])); }

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

SeifSlam::Linearization SeifSlam::ApplyMeasurements(const std::vector<std::pair<int, Eigen::Vector2d>>& pairs) {
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

std::map<std::string, double> SeifSlam::Counters() const {
  int confirmed = 0;
  for (const LandmarkInfo& l : landmarks_) confirmed += l.alive && l.confirmed ? 1 : 0;
  return {
      {"scans", counters_.scans},
      {"numerical_failures", numerical_failures_},
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
       counters_.iterated_updates > 0 ? static_cast<double>(counters_.iterations) / counters_.iterated_updates : 0.0},
      {"exact_recoveries", counters_.exact_recoveries},
      {"landmark_links", num_landmark_links()},
      {"landmarks_in_state", num_landmarks()},
      {"confirmed_landmarks", confirmed}};
}

}  // namespace subslam::frontend
