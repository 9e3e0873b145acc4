#include "subslam/frontend/local_mapper.h"

#include "absl/time/clock.h"
#include "subslam/graph/internal/check.h"

namespace subslam::frontend {

LocalMapper::LocalMapper(const SubmapPolicyOptions& policy,
                         const models::RangeBearingConfig& sensor, double t_start)
    : policy_(policy, sensor.sigma_range_m, sensor.sigma_bearing_rad),
      t_(t_start),
      t_map_start_(t_start) {}

void LocalMapper::Predict(const Eigen::Vector2d& u, double dt) {
  if (dt <= 0.0) return;
  t_ += dt;
  FilterPredict(u, dt);
}

void LocalMapper::Update(const io::Scan& scan) {
  t_ = scan.t;
  FilterUpdate(scan);
  ++scans_in_map_;
  SubmapStatus status = FilterStatus();
  status.elapsed_s = t_ - t_map_start_;
  status.delayed_for_s = delayed_since_ < 0 ? 0.0 : t_ - delayed_since_;
  const SubmapDecision decision = policy_.Decide(status);
  if (decision.delayed && delayed_since_ < 0) delayed_since_ = t_;
  if (decision.reason != CloseReason::kKeepOpen) Close(decision.reason);
}

void LocalMapper::Finish() {
  if (scans_in_map_ > 0) Close(CloseReason::kEndOfRun);
}

void LocalMapper::Close(CloseReason reason) {
  const absl::Time start = absl::Now();
  const MomentMatchedGaussian g = Export();
  ClosedLocalMap closed;
  closed.reason = reason;
  LocalSubmap& s = closed.submap;
  s.id = map_id_;
  s.t_start = t_map_start_;
  s.t_end = t_;
  s.mean = g.mean;
  s.covariance = g.covariance;
  s.covariance_repairs = g.covariance_repairs;
  for (size_t k = 0; k < g.features.size(); ++k) {
    LocalSubmapLandmark l;
    l.local_id = g.features[k];
    l.signature = g.signature[k];
    l.existence = g.existence[k];
    if (k < g.truth_id.size() && g.truth_id[k] >= 0) l.truth_id = g.truth_id[k];  // known association
    s.landmarks.push_back(l);
  }
  const absl::Status valid = s.Validate();
  SUBSLAM_CHECK(valid.ok()) << "exported local map is invalid: " << valid.message();
  repairs_ += g.covariance_repairs;
  ++closes_by_reason_[ToString(reason)];
  closed_.push_back(std::move(closed));
  FilterReset();
  ++map_id_;
  t_map_start_ = t_;
  scans_in_map_ = 0;
  delayed_since_ = -1.0;
  export_seconds_ += absl::ToDoubleSeconds(absl::Now() - start);
}

std::vector<ClosedLocalMap> LocalMapper::TakeClosed() {
  std::vector<ClosedLocalMap> out;
  out.swap(closed_);
  return out;
}

StageTimes LocalMapper::stage_times() const {
  StageTimes times = FilterStageTimes();
  times["export"] = export_seconds_;
  return times;
}

std::map<std::string, double> LocalMapper::Counters() const {
  std::map<std::string, double> out = {{"local_maps_closed", map_id_},
                                       {"covariance_repairs", repairs_}};
  for (const auto& [reason, count] : closes_by_reason_) out["closed_by_" + reason] = count;
  for (const auto& [name, value] : FilterCounters()) out[name] = value;
  return out;
}

RbpfLocalMapper::RbpfLocalMapper(std::unique_ptr<models::MotionModel> motion,
                                 const models::RangeBearingConfig& sensor,
                                 const FastSlamOptions& fastslam,
                                 const SubmapPolicyOptions& policy, double t_start)
    : LocalMapper(policy, sensor, t_start), filter_(std::move(motion), sensor, Pose2(), fastslam) {}

SubmapStatus RbpfLocalMapper::FilterStatus() const {
  SubmapStatus s;
  s.pose_covariance = filter_.pose_covariance();
  s.ess_ratio = filter_.last_scan_ess_ratio();
  s.lineage_diversity = filter_.LineageDiversity();
  const FastSlam::FeatureCounts counts = filter_.ConfirmedFeatureCounts();
  s.confirmed_features = counts.total;
  s.visible_features = counts.within_range;
  s.disagreement = filter_.last_scan_disagreement();
  return s;
}

}  // namespace subslam::frontend
