#include "subslam/pipeline/submap_slam.h"

#include <algorithm>
#include <exception>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "subslam/core/check.h"
#include "subslam/core/enum_names.h"
#include "subslam/models/gating.h"

namespace subslam::pipeline {

namespace {
constexpr EnumName<Backend> kBackendNames[] = {{Backend::kNone, "none"},           {Backend::kEif, "eif"},
                                               {Backend::kCeres, "ceres"},         {Backend::kEkf, "ekf"},
                                               {Backend::kTreeEkf, "tree-ekf"},    {Backend::kTreeEif, "tree-eif"},
                                               {Backend::kTreeCeres, "tree-ceres"}};
}  // namespace

const char* ToString(Backend backend) { return NameOf(kBackendNames, backend); }

absl::StatusOr<Backend> BackendFromString(const std::string& name) {
  return ParseEnum(kBackendNames, name, "back-end");
}

absl::Status BackendOptions::Validate() const {
  if (absl::Status st = eif.Validate(); !st.ok()) return st;
  if (absl::Status st = ekf.Validate(); !st.ok()) return st;
  if (absl::Status st = ceres.Validate(); !st.ok()) return st;
  if (ceres_every < 0) return absl::InvalidArgumentError("ceres_every must be >= 0");
  if (absl::Status st = sensor_yaw.Validate(); !st.ok()) return st;
  if (absl::Status st = map_test.Validate(); !st.ok()) return st;
  if (!(divergence_level > 0.0 && divergence_level < 1.0)) {
    return absl::InvalidArgumentError(absl::StrCat("divergence_level must be in (0, 1), got ", divergence_level));
  }
  return absl::OkStatus();
}

bool EifRelinearizesAtEnd(const BackendOptions& options) {
  return options.eif.relinearize_at_end && options.kind != Backend::kCeres && options.kind != Backend::kTreeCeres;
}

std::unique_ptr<backend::MapJoiner> MakeJoiner(const BackendOptions& options, const Pose2& initial_pose) {
  switch (options.kind) {
    case Backend::kNone:
      return nullptr;
    case Backend::kEif:
      return std::make_unique<backend::EifJoiner>(initial_pose, options.eif);
    case Backend::kCeres:
      return std::make_unique<backend::CeresJoiner>(
          initial_pose,
          backend::CeresJoinerOptions{.eif = options.eif, .solve = options.ceres, .solve_every = options.ceres_every});
    case Backend::kTreeCeres:
      return std::make_unique<backend::TreeJoiner>(
          std::make_unique<backend::CeresJoiner>(
              initial_pose,
              backend::CeresJoinerOptions{
                  .eif = options.eif.ForTreeNode(), .solve = options.ceres, .solve_every = options.ceres_every}),
          options.tree);
    case Backend::kEkf:
      return std::make_unique<backend::EkfJoiner>(initial_pose, options.ekf);
    case Backend::kTreeEkf: {
      backend::EkfJoinerOptions ekf = options.ekf;
      ekf.keep_anchors = true;  // tree joins need every node's anchors
      return std::make_unique<backend::TreeJoiner>(std::make_unique<backend::EkfJoiner>(initial_pose, ekf),
                                                   options.tree);
    }
    case Backend::kTreeEif:
      return std::make_unique<backend::TreeJoiner>(
          std::make_unique<backend::EifJoiner>(initial_pose, options.eif.ForTreeNode()), options.tree);
  }
  return nullptr;
}

SubmapSlam::SubmapSlam(std::unique_ptr<frontend::LocalMapper> mapper, const Pose2& initial_pose,
                       const BackendOptions& backend)
    : SubmapSlam(std::move(mapper), initial_pose, MakeJoiner(backend, initial_pose), backend.background,
                 ToString(backend.kind), backend.sensor_yaw) {
  SUBSLAM_CHECK(backend.Validate().ok()) << backend.Validate().message();
  map_test_ = backend.map_test;
  divergence_level_ = backend.divergence_level;
}

SubmapSlam::SubmapSlam(std::unique_ptr<frontend::LocalMapper> mapper, const Pose2& initial_pose,
                       std::unique_ptr<backend::MapJoiner> joiner, bool background, std::string backend_name,
                       const backend::SensorYawCalibrationOptions& sensor_yaw)
    : mapper_(std::move(mapper)),
      backend_name_(joiner == nullptr      ? ""
                    : backend_name.empty() ? joiner->Name()
                                           : std::move(backend_name)),
      joiner_(std::move(joiner)),
      yaw_calibration_(sensor_yaw),
      initial_pose_(initial_pose),
      anchor_(initial_pose) {
  // The yaw calibration may ask to join its warm-up's maps again into an empty joiner.
  if (joiner_ && joiner_->NewEmpty(initial_pose) == nullptr) {
    yaw_calibration_ = backend::SensorYawCalibration(backend::SensorYawCalibrationOptions{.enabled = false});
  }
  chain_.push_back(initial_pose);
  chain_covariance_.push_back(Eigen::Matrix3d::Zero());
  background_ = background && joiner_ != nullptr;
  if (background_) join_thread_ = std::thread([this] { JoinWorker(); });
}

SubmapSlam::~SubmapSlam() {
  if (!join_thread_.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(join_mutex_);
    join_stop_ = true;
  }
  join_wanted_.notify_one();
  join_thread_.join();
}

void SubmapSlam::JoinWorker() {
  std::unique_lock<std::mutex> lock(join_mutex_);
  while (true) {
    join_wanted_.wait(lock, [this] { return join_stop_ || joining_.has_value(); });
    if (!joining_.has_value()) return;  // stopped, nothing pending
    lock.unlock();
    try {
      JoinOne(*joining_);                // joining_ is not touched by anyone else while it is set
    } catch (const std::exception& e) {  // e.g. out of memory: reported by Finish()
      status_ = absl::InternalError(absl::StrCat("joining local map ", joining_->id, ": ", e.what()));
      join_failed_.store(true, std::memory_order_release);
    }
    lock.lock();
    joining_.reset();
    join_busy_.store(false, std::memory_order_relaxed);
    join_done_.notify_all();
  }
}

void SubmapSlam::WaitForJoins() const {
  if (!background_) return;
  std::unique_lock<std::mutex> lock(join_mutex_);
  join_done_.wait(lock, [this] { return !joining_.has_value(); });
}

std::string SubmapSlam::Name() const {
  return backend_name_.empty() ? mapper_->Name() : absl::StrCat(mapper_->Name(), "+", backend_name_);
}

absl::Status SubmapSlam::Update(const Scan& scan) {
  // While a join runs, its thread has a core of its own.
  if (background_) mapper_->SetSpareCores(join_busy_.load(std::memory_order_relaxed) ? 1 : 0);
  const int map_id = mapper_->current_map_id();  // the map the scan goes into
  // The mapper refuses a malformed scan (CheckScan) before it changes anything.
  if (absl::Status st = mapper_->Update(scan); !st.ok()) return st;
  last_scan_map_id_ = map_id;
  JoinClosed();
  if (!mapper_->status().ok()) return mapper_->status();
  // A failed join stops the joining thread before it raises the flag: status_ is then
  // settled and safe to read here.
  if (join_failed()) return status_;
  return absl::OkStatus();
}

void SubmapSlam::JoinClosed() {
  std::vector<frontend::ClosedLocalMap> newly_closed = mapper_->TakeClosed();
  if (newly_closed.empty()) return;  // the anchor changes only when a map closes
  for (frontend::ClosedLocalMap& c : newly_closed) {
    if (joiner_) {
      backend::SensorYawCalibration::Ready ready = yaw_calibration_.Add(c.submap);
      if (ready.restart) RestartJoiner();
      for (const LocalSubmap& s : ready.maps) Submit(s);
    } else {
      Eigen::Matrix3d covariance;
      chain_.push_back(ComposeWithCovariance(chain_.back(), chain_covariance_.back(), c.submap.end_pose(),
                                             c.submap.covariance.topLeftCorner<3, 3>(), &covariance));
      chain_covariance_.push_back(covariance);
    }
    closed_.push_back(std::move(c));
  }
  if (joiner_) {
    if (background_ || !status_.ok()) return;  // set by Submit, or the last one joined stays
    anchor_ = joiner_->LastAnchor();           // the tree joiner answers without folding its nodes
    anchor_covariance_ = joiner_->LastAnchorCovariance();
  } else {
    anchor_ = chain_.back();
    anchor_covariance_ = chain_covariance_.back();
  }
}

void SubmapSlam::Submit(const LocalSubmap& s) {
  if (!background_) {
    JoinOne(s);
    return;
  }
  WaitForJoins();  // the previous map's join
  if (!status_.ok()) return;
  // One join behind: s's start anchor as joined so far, through s's end pose.
  anchor_ = ComposeWithCovariance(joiner_->LastAnchor(), joiner_->LastAnchorCovariance(), s.end_pose(),
                                  s.covariance.topLeftCorner<3, 3>(), &anchor_covariance_);
  {
    std::lock_guard<std::mutex> lock(join_mutex_);
    joining_ = s;
    join_busy_.store(true, std::memory_order_relaxed);
  }
  join_wanted_.notify_one();
}

void SubmapSlam::RestartJoiner() {
  WaitForJoins();
  if (!status_.ok()) return;
  joiner_ = joiner_->NewEmpty(initial_pose_);  // non-null: checked at construction
  joins_.clear();
}

void SubmapSlam::JoinOne(const LocalSubmap& s) {
  // After a failed join the joiner is left as it was (or without a factor): nothing
  // more is joined or asked of it, and Finish() reports the error.
  if (!status_.ok()) return;
  if (absl::Status st = joiner_->Join(s); !st.ok()) {
    // Name the map unless the message does (LocalSubmap::Validate's do).
    const std::string map = absl::StrCat("local map ", s.id);
    status_ = absl::StrContains(st.message(), map)
                  ? st
                  : absl::Status(st.code(), absl::StrCat("joining ", map, ": ", st.message()));
    join_failed_.store(true, std::memory_order_release);
    return;
  }
  joins_.push_back(joiner_->last_join());
}

std::vector<frontend::ClosedLocalMap> SubmapSlam::TakeLocalMaps() {
  WaitForJoins();
  return std::exchange(closed_, {});
}

Pose2 SubmapSlam::Anchor(int k) const { return joiner_ ? joiner_->anchor(k) : chain_[k]; }

Eigen::Matrix3d SubmapSlam::AnchorCovariance(int k) const {
  return joiner_ ? joiner_->AnchorCovariance(k) : chain_covariance_[k];
}

Pose2 SubmapSlam::pose() const { return Compose(anchor_, mapper_->local_pose()); }

Eigen::Matrix3d SubmapSlam::pose_covariance() const {
  Eigen::Matrix3d covariance;
  ComposeWithCovariance(anchor_, anchor_covariance_, mapper_->local_pose(), mapper_->local_pose_covariance(),
                        &covariance);
  return covariance;
}

void SubmapSlam::RecordStep(double t) {
  steps_.push_back({t, mapper_->current_map_id(), mapper_->local_pose(), mapper_->local_pose_covariance()});
}

absl::Status SubmapSlam::Finish() {
  mapper_->Finish();
  JoinClosed();
  WaitForJoins();
  if (!mapper_->status().ok()) return mapper_->status();
  if (joiner_ && status_.ok()) {
    // The joiner's own last work (relinearisation, the final revision passes) can fail as
    // a join can, and leaves the joiner as half-made: its estimate is not used either.
    if (absl::Status st = joiner_->Finish(); !st.ok()) {
      status_ = absl::Status(st.code(), absl::StrCat("finishing the joins: ", st.message()));
      join_failed_.store(true, std::memory_order_release);
    }
  }
  if (joiner_ && status_.ok()) {  // the online pose after the run: on the final estimate
    anchor_ = Anchor(mapper_->current_map_id());
    anchor_covariance_ = AnchorCovariance(mapper_->current_map_id());
  }
  return status_;
}

Trajectory SubmapSlam::FinalTrajectory() const {
  WaitForJoins();
  Trajectory out;
  out.reserve(steps_.size());
  if (steps_.empty()) return out;
  // Every anchor's marginal at once (the joiner's bulk recovery).
  const std::vector<Eigen::Matrix3d> anchor_covariances = joiner_ ? joiner_->AnchorCovariances() : chain_covariance_;
  int cached = -1;
  Pose2 anchor;
  Eigen::Matrix3d anchor_cov;
  for (const StepRecord& r : steps_) {
    if (r.map >= static_cast<int>(anchor_covariances.size())) break;  // after a failed join
    if (r.map != cached) {
      anchor = Anchor(r.map);
      anchor_cov = anchor_covariances.at(r.map);
      cached = r.map;
    }
    Eigen::Matrix3d covariance;
    const Pose2 p = ComposeWithCovariance(anchor, anchor_cov, r.local, r.local_covariance, &covariance);
    out.push_back({r.t, p, covariance});
  }
  return out;
}

std::vector<LandmarkEstimate> SubmapSlam::Map() const {
  WaitForJoins();
  std::vector<LandmarkEstimate> out;
  if (joiner_) {
    const std::vector<Eigen::Matrix2d> covariances = joiner_->LandmarkCovariances();
    for (int j = 0; j < joiner_->num_landmarks(); ++j) out.push_back({j, joiner_->landmark(j), covariances[j]});
    return out;
  }
  for (size_t k = 0; k < closed_.size(); ++k) {
    const LocalSubmap& s = closed_[k].submap;
    for (int i = 0; i < s.num_landmarks(); ++i) {
      Matrix23d J_pose;
      Eigen::Matrix2d J_point;
      const Eigen::Vector2d p = TransformFrom(chain_[k], s.landmark(i), &J_pose, &J_point);
      out.push_back({s.id * kFeatureIdStride + s.landmarks[i].local_id, p,
                     J_pose * chain_covariance_[k] * J_pose.transpose() +
                         J_point * s.landmark_covariance(i) * J_point.transpose()});
    }
  }
  return out;
}

StageTimes SubmapSlam::stage_times() const {
  WaitForJoins();
  StageTimes times = mapper_->stage_times();
  if (joiner_) {
    for (const auto& [stage, seconds] : joiner_->stage_times()) times["join_" + stage] = seconds;
  }
  return times;
}

namespace {

// The local maps against the map (BackendOptions::map_test): each join's pairings summed
// over the run against their χ² quantile, and over windows of joins.
void AddMapTestCounters(const std::vector<backend::JoinSummary>& joins, const frontend::InnovationTestOptions& options,
                        double divergence_level, std::map<std::string, double>* out) {
  frontend::InnovationMonitor windows(options);
  double d2 = 0.0;
  long dof = 0;
  for (const backend::JoinSummary& j : joins) {
    if (j.association_dof <= 0) continue;
    windows.Add(j.association_d2, static_cast<int>(j.association_dof));
    d2 += j.association_d2;
    dof += j.association_dof;
  }
  if (dof == 0) return;
  (*out)["map_test_d2_per_dof"] = d2 / static_cast<double>(dof);
  (*out)["map_test_dof"] = static_cast<double>(dof);
  (*out)["map_test_windows_tested"] = windows.windows_tested();
  (*out)["map_test_windows_failed"] = windows.windows_failed();
  (*out)["map_test_longest_episode_joins"] = windows.longest_episode_scans();
  (*out)["map_test_diverged"] =
      d2 > models::ChiSquareQuantile(1.0 - divergence_level, static_cast<double>(dof)) ? 1.0 : 0.0;
}

}  // namespace

std::map<std::string, double> SubmapSlam::Counters() const {
  WaitForJoins();
  std::map<std::string, double> out = mapper_->Counters();
  if (joiner_) {
    const backend::JoinerCounters& counters = joiner_->counters();
    for (const backend::JoinerCounters::Field& f : backend::JoinerCounters::Fields()) {
      out[std::string("join_") + f.name] = counters.*f.member;
    }
    out["global_landmarks"] = joiner_->num_landmarks();
    AddMapTestCounters(joins_, map_test_, divergence_level_, &out);
    out.merge(yaw_calibration_.Counters());
    for (const auto& [name, value] : joiner_->Extras().figures) out[name] = value;
  }
  return out;
}

}  // namespace subslam::pipeline
