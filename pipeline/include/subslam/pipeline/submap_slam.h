// The whole submap pipeline behind the OnlineEstimator interface: a local mapper (RBPF or
// EKF-SLAM local maps) and a back-end that joins each closed local map into the global map.
//
// Back-ends:
//  * kNone  — no joining: each map's start anchor is the previous anchor composed with the
//    previous map's end pose (first-order covariance); no fusion, no loop closure;
//  * kEif   — the exactly sparse EIF joiner (backend/eif_joiner.h);
//  * kEkf   — dense EKF map joining in covariance form (backend/ekf_joiner.h), the
//    baseline; it associates with the same module and options as the EIF;
//  * kTreeEkf, kTreeEif — binary-tree joining (backend/tree_joiner.h) over dense EKF or
//    sparse EIF nodes; the online anchor is chained over the tree's pending nodes;
//  * kCeres — the Ceres back-end (backend/ceres_joiner.h): the EIF associates and gives
//    the online estimate, and every `ceres_every` joins and at Finish() Ceres solves the
//    whole graph and the EIF adopts the solution;
//  * kTreeCeres — the same Ceres nodes joined by the binary tree (EIF tree joins), Ceres
//    solving the whole graph at Finish() from the tree's estimate.
//
// Every closed map goes through the online sensor-yaw calibration
// (backend/sensor_yaw_calibration.h; BackendOptions::sensor_yaw) before it is joined; when
// the calibration's warm-up ends with a turn, the joiner is replaced by an empty one of its
// kind (MapJoiner::NewEmpty) and the warm-up's maps are joined again, turned. local_maps()
// keeps the maps as the front-end built them.
//
// pose() is the current start anchor composed with the local map's pose; its covariance
// adds the anchor's marginal and the local pose's covariance (their correlation is
// ignored). The start anchor is the joiner's MapJoiner::LastAnchor(), which leaves out a
// loop closure still waiting for confirmation (eif, ceres).
//
// Background joins (BackendOptions::background; the tool's default): each closed local map is
// joined on a thread of its own while the front-end goes on with the next map, and while
// a join runs the local mapper leaves it a core (LocalMapper::SetSpareCores). The front-end waits
// only when a join outlasts the next map: map k's join must be done before map k + 1
// closes. The online pose is one join behind, and deterministic: while map k + 1 is
// built, its start anchor is map k's start anchor as joined so far composed with map k's
// end pose (covariance to first order). The final trajectory, the map and the marginals
// are those of the synchronous run. The joiner-backed accessors wait for a pending join;
// what joiner() returns is valid until the next Update() or Finish().
//
// After Finish(), FinalTrajectory() re-expresses every recorded step with the final
// anchors, and Map() is the global map (kNone: every local map's features through its
// anchor, id = map · 10⁶ + feature, duplicates included).
//
// Threads: call every method from one thread (the one that calls Update). The background
// join thread is the object's own: pose() and pose_covariance() never wait for it (they
// read the anchor cached when the last join was handed over), join_failed() may be read
// from any thread, and the joiner-backed accessors wait for the join in progress. A
// caller that reads the pose on another thread while Update runs must lock around both.
#ifndef SUBSLAM_PIPELINE_SUBMAP_SLAM_H_
#define SUBSLAM_PIPELINE_SUBMAP_SLAM_H_

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "subslam/backend/ceres_joiner.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/ekf_joiner.h"
#include "subslam/backend/map_joiner.h"
#include "subslam/backend/sensor_yaw_calibration.h"
#include "subslam/backend/tree_joiner.h"
#include "subslam/frontend/innovation_monitor.h"
#include "subslam/frontend/local_mapper.h"
#include "subslam/frontend/online_estimator.h"

namespace subslam::pipeline {

enum class Backend { kNone, kEif, kCeres, kEkf, kTreeEkf, kTreeEif, kTreeCeres };
const char* ToString(Backend backend);  // none, eif, ceres, ekf, tree-ekf, tree-eif, tree-ceres
absl::StatusOr<Backend> BackendFromString(const std::string& name);

struct BackendOptions {
  // The incremental EIF by default: local maps chained without joining (kNone) drift
  // and duplicate every landmark seen twice, which only a study of the front-end wants.
  Backend kind = Backend::kEif;
  backend::EifJoinerOptions eif;     // eif, ceres, tree-eif
  backend::EkfJoinerOptions ekf;     // ekf, tree-ekf (tree-ekf keeps every anchor)
  backend::TreeJoinerOptions tree;   // tree-ekf, tree-eif
  backend::CeresSolveOptions ceres;  // ceres
  int ceres_every = 0;               // ceres: also solve every K joins (0: at the end only)
  // Every back-end that joins (not kNone) gets the local maps with the sensor's yaw
  // calibrated online from consecutive maps (backend/sensor_yaw_calibration.h); the maps
  // kept in local_maps() and written to submaps.jsonl are the front-end's, and `subslam
  // join` calibrates them the same way.
  backend::SensorYawCalibrationOptions sensor_yaw;
  // Join on a background thread, the online pose one join behind (see SubmapSlam);
  // false (the default: a library starts no thread unless asked): each closed map is
  // joined inside the Update() that closed it, and the online pose uses its joined
  // anchor at once. The tool asks for it (`--join_in_background`, default true).
  bool background = false;
  // The local maps against the map (the run's health): each join's pairings' joint d²
  // (backend::JoinSummary::association_d2) is χ² with their dof for consistent maps. The
  // run is taken to diverge when the sum over all joins exceeds the χ² quantile of the
  // summed dof at 1 − divergence_level (the joins taken as independent; the joint gate
  // truncates each d² from above, so a consistent run fails less often than the level);
  // windows of `window_scans` joins with pairings, tested at `probability`, say when.
  frontend::InnovationTestOptions map_test = {.window_scans = 10};
  double divergence_level = 0.001;

  absl::Status Validate() const;
};

// Whether the back-end's EIF runs Gauss-Newton at Finish(): eif.relinearize_at_end, except
// for kCeres and kTreeCeres, where Ceres solves there instead.
bool EifRelinearizesAtEnd(const BackendOptions& options);

// The joiner of a back-end (nullptr for kNone).
std::unique_ptr<backend::MapJoiner> MakeJoiner(const BackendOptions& options, const Pose2& initial_pose);

class SubmapSlam final : public frontend::OnlineEstimator {
 public:
  // `backend` must be valid (BackendOptions::Validate).
  SubmapSlam(std::unique_ptr<frontend::LocalMapper> mapper, const Pose2& initial_pose, const BackendOptions& backend);
  ~SubmapSlam() override;
  // With a joiner of the caller's (nullptr: the local maps are chained by their end poses),
  // joined on a background thread if `background`; `backend_name` (default: the joiner's
  // Name()) names it in Name(). The yaw calibration is off for a joiner that cannot make an
  // empty one of its kind (NewEmpty() null).
  SubmapSlam(std::unique_ptr<frontend::LocalMapper> mapper, const Pose2& initial_pose,
             std::unique_ptr<backend::MapJoiner> joiner, bool background, std::string backend_name = "",
             const backend::SensorYawCalibrationOptions& sensor_yaw = {});
  SubmapSlam(const SubmapSlam&) = delete;
  SubmapSlam& operator=(const SubmapSlam&) = delete;

  std::string Name() const override;
  void Predict(const Eigen::Vector2d& u, double dt) override { mapper_->Predict(u, dt); }
  absl::Status Update(const Scan& scan) override;
  Pose2 pose() const override;
  Eigen::Matrix3d pose_covariance() const override;
  std::vector<LandmarkEstimate> Map() const override;
  StageTimes stage_times() const override;
  std::map<std::string, double> Counters() const override;

  // Remembers the current step (its map and local pose) for FinalTrajectory().
  void RecordStep(double t);
  // Closes and joins the open local map (and relinearises, if the joiner is set to).
  // Returns the first error any join met.
  absl::Status Finish();
  // Whether a join has failed (readable at any time, also while a background join runs).
  // The joiner is left as it was before that join, nothing more is joined, and Finish()
  // returns the error: the run cannot go on, but everything up to the failed map stands.
  // A failure in the joiner's own Finish() (its last relinearisation or revision passes)
  // counts too; the joiner may then be half-made, and its estimate must not be used.
  bool join_failed() const { return join_failed_.load(std::memory_order_acquire); }
  // Whether the local mapper could not export a local map (a broken filter estimate):
  // nothing after it is joined either, and Finish() returns the mapper's error.
  bool export_failed() const { return !mapper_->status().ok(); }
  // Every recorded step re-expressed with the final anchors — after a failed join, the
  // steps of the local maps that have a start anchor (those joined, and the failed one),
  // which holds for a joiner that a failure leaves as it was (RunPipeline does not rely on
  // it: a join may fail part-way).
  Trajectory FinalTrajectory() const;

  const std::vector<frontend::ClosedLocalMap>& local_maps() const { return closed_; }
  // Moves the closed local maps out (local_maps() is empty afterwards), for a caller that
  // keeps them once the run is over. Map() without a back-end chains them: ask it first.
  std::vector<frontend::ClosedLocalMap> TakeLocalMaps();
  int last_scan_map_id() const { return last_scan_map_id_; }
  const std::vector<int>& last_scan_features() const { return mapper_->last_scan_features(); }
  // The back-end's joiner (nullptr for kNone).
  const backend::MapJoiner* joiner() const {
    WaitForJoins();
    return joiner_.get();
  }
  // What each join did, in join order (empty for kNone).
  const std::vector<backend::JoinSummary>& joins() const {
    WaitForJoins();
    return joins_;
  }
  static constexpr int kFeatureIdStride = 1000000;

 private:
  void JoinClosed();
  // Joins one map: on the background thread (setting the online anchor one join behind),
  // or at once.
  void Submit(const LocalSubmap& s);
  // An empty joiner of the same kind in place of the current one (the yaw calibration's
  // warm-up ended with a turn: its maps are joined again, turned).
  void RestartJoiner();
  // Joins one local map; records the first error.
  void JoinOne(const LocalSubmap& s);
  // Background joins: until the join in progress, if any, is done.
  void WaitForJoins() const;
  void JoinWorker();
  // The start anchor of local map k and its marginal covariance.
  Pose2 Anchor(int k) const;
  Eigen::Matrix3d AnchorCovariance(int k) const;

  std::unique_ptr<frontend::LocalMapper> mapper_;
  std::string backend_name_;  // empty: no back-end
  std::unique_ptr<backend::MapJoiner> joiner_;
  std::vector<frontend::ClosedLocalMap> closed_;
  backend::SensorYawCalibration yaw_calibration_;  // applied to the maps handed to the joiner
  // kNone: the chained anchors (index k = start of map k) and covariances; the joiners
  // keep their own.
  std::vector<Pose2> chain_;
  std::vector<Eigen::Matrix3d> chain_covariance_;
  Pose2 initial_pose_;
  // The current start anchor, cached after each join.
  Pose2 anchor_;
  Eigen::Matrix3d anchor_covariance_ = Eigen::Matrix3d::Zero();
  struct StepRecord {
    double t;
    int map;
    Pose2 local;
    Eigen::Matrix3d local_covariance;
  };
  std::vector<StepRecord> steps_;
  int last_scan_map_id_ = 0;
  std::vector<backend::JoinSummary> joins_;  // written by the joining thread, as status_
  frontend::InnovationTestOptions map_test_ = BackendOptions().map_test;
  double divergence_level_ = BackendOptions().divergence_level;
  absl::Status status_;  // written by the joining thread while a join is pending
  // Background joins: the map being joined (set until its join is done), guarded by
  // join_mutex_; the joiner and status_ belong to the joining thread while it is set.
  bool background_ = false;
  mutable std::mutex join_mutex_;
  mutable std::condition_variable join_done_;
  std::condition_variable join_wanted_;
  std::optional<LocalSubmap> joining_;
  std::atomic<bool> join_busy_{false};    // joining_ is set (read without the lock)
  std::atomic<bool> join_failed_{false};  // status_ holds a join's error
  bool join_stop_ = false;
  std::thread join_thread_;
};

}  // namespace subslam::pipeline

#endif  // SUBSLAM_PIPELINE_SUBMAP_SLAM_H_
