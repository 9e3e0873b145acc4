#include "subslam/frontend/local_mapper.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "subslam/core/check.h"

namespace subslam::frontend {

namespace {

// Marginalises out every feature but those listed: the kept rows and columns of the Gaussian.
void KeepFeaturesOf(const std::vector<int>& keep, MomentMatchedGaussian* g) {
  std::vector<int> rows = {0, 1, 2};
  for (int k : keep) rows.insert(rows.end(), {3 + 2 * k, 4 + 2 * k});
  const Eigen::VectorXd mean = g->mean(rows);
  const Eigen::MatrixXd covariance = g->covariance(rows, rows);
  g->mean = mean;
  g->covariance = covariance;
  const auto select = [&keep](auto* values) {
    if (values->empty()) return;
    std::remove_reference_t<decltype(*values)> kept;
    for (int k : keep) kept.push_back((*values)[k]);
    *values = std::move(kept);
  };
  select(&g->features);
  select(&g->existence);
  select(&g->signature);
  select(&g->truth_id);
}

}  // namespace

LocalMapper::LocalMapper(const SubmapPolicyOptions& policy, const models::RangeBearingConfig& sensor, double t_start)
    : policy_(policy, sensor.sigma_range_m, sensor.sigma_bearing_rad),
      t_(t_start),
      t_map_start_(t_start),
      max_feature_sigma_m_(policy.max_feature_sigma_ratio *
                           std::max(sensor.sigma_range_m, sensor.sigma_bearing_rad * sensor.max_range_m)),
      moving_test_(policy.moving_features, sensor) {}

void LocalMapper::Predict(const Eigen::Vector2d& u, double dt) {
  if (dt <= 0.0) return;
  t_ += dt;
  FilterPredict(u, dt);
}

absl::Status LocalMapper::Update(const Scan& scan) {
  if (absl::Status st = CheckScan(scan); !st.ok()) return st;
  t_ = scan.t;
  if (absl::Status st = FilterUpdate(scan); !st.ok()) return st;
  ++scans_in_map_;
  if (moving_test_.enabled()) {
    std::vector<Eigen::Vector2d> z;
    for (const Detection& d : scan.detections) z.push_back(d.z());
    moving_test_.AddScan(scan.t, FilterPose(), FilterPoseCovariance(), z, last_scan_features());
  }
  SubmapStatus status = FilterStatus();
  status.elapsed_s = t_ - t_map_start_;
  status.delayed_for_s = delayed_since_ < 0 ? 0.0 : t_ - delayed_since_;
  const SubmapDecision decision = policy_.Decide(status);
  if (decision.delayed && delayed_since_ < 0) delayed_since_ = t_;
  if (decision.reason != CloseReason::kKeepOpen) Close(decision.reason);
  return absl::OkStatus();
}

void LocalMapper::Finish() {
  if (scans_in_map_ > 0) Close(CloseReason::kEndOfRun);
}

void LocalMapper::Close(CloseReason reason) {
  if (!status_.ok()) return;  // a map failed before: nothing more is closed
  const absl::Time start = absl::Now();
  MomentMatchedGaussian g = Export();
  DropMovingFeatures(&g);
  DropUncertainFeatures(&g);
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
  // A map over almost no motion (a vehicle standing still) is nearly rigid: regularised by
  // the documented rule and counted, as the reader does with one from elsewhere.
  s.RegularizeDegenerateCovariance();
  if (const absl::Status valid = s.Validate(); !valid.ok()) {
    status_ = absl::InternalError(
        absl::StrCat("the filter's estimate could not be exported as local map ", map_id_, ": ", valid.message()));
    return;
  }
  repairs_ += s.covariance_repairs;
  ++closes_by_reason_[ToString(reason)];
  closed_.push_back(std::move(closed));
  FilterReset();
  moving_test_.Reset();
  ++map_id_;
  t_map_start_ = t_;
  scans_in_map_ = 0;
  delayed_since_ = -1.0;
  export_seconds_ += absl::ToDoubleSeconds(absl::Now() - start);
}

void LocalMapper::DropUncertainFeatures(MomentMatchedGaussian* g) {
  if (max_feature_sigma_m_ <= 0.0) return;
  const int n = static_cast<int>(g->features.size());
  // Each feature's covariance given the end pose, P_ff − P_fp P_pp⁺ P_pf: what the map
  // says about the feature relative to the vehicle, without the drift they share (a
  // feature mapped late in a long map is uncertain in the start frame, not relative to
  // the end pose). P_pp may be singular (a map of one step): its pseudo-inverse.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> pose(g->covariance.topLeftCorner<3, 3>());
  const Eigen::Vector3d lambda = pose.eigenvalues();
  Eigen::Vector3d inverse_lambda = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i) {
    if (lambda[i] > 1e-12 * std::max(lambda.maxCoeff(), 1e-300)) inverse_lambda[i] = 1.0 / lambda[i];
  }
  const Eigen::Matrix3d pose_pinv = pose.eigenvectors() * inverse_lambda.asDiagonal() * pose.eigenvectors().transpose();
  std::vector<int> keep;
  for (int k = 0; k < n; ++k) {
    const Eigen::Matrix<double, 2, 3> P_fp = g->covariance.block<2, 3>(3 + 2 * k, 0);
    const Eigen::Matrix2d P = g->covariance.block<2, 2>(3 + 2 * k, 3 + 2 * k) - P_fp * pose_pinv * P_fp.transpose();
    const double widest =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(0.5 * (P + P.transpose()), Eigen::EigenvaluesOnly)
            .eigenvalues()(1);
    if (std::sqrt(std::max(0.0, widest)) <= max_feature_sigma_m_) keep.push_back(k);
  }
  if (static_cast<int>(keep.size()) == n) return;
  features_too_uncertain_ += n - static_cast<long>(keep.size());
  KeepFeaturesOf(keep, g);
}

void LocalMapper::DropMovingFeatures(MomentMatchedGaussian* g) {
  if (!moving_test_.enabled()) return;
  std::vector<int> keep;
  for (int k = 0; k < static_cast<int>(g->features.size()); ++k) {
    if (!moving_test_.Moving(g->features[k])) keep.push_back(k);
  }
  if (keep.size() == g->features.size()) return;
  moving_features_ += static_cast<long>(g->features.size() - keep.size());
  KeepFeaturesOf(keep, g);
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
                                       {"covariance_repairs", repairs_},
                                       {"features_too_uncertain_to_export", features_too_uncertain_},
                                       {"moving_features_not_exported", moving_features_}};
  for (const auto& [reason, count] : closes_by_reason_) out["closed_by_" + reason] = count;
  for (const auto& [name, value] : FilterCounters()) out[name] = value;
  return out;
}

RbpfLocalMapper::RbpfLocalMapper(std::unique_ptr<models::MotionModel> motion, const models::RangeBearingConfig& sensor,
                                 const FastSlamOptions& fastslam, const SubmapPolicyOptions& policy, double t_start)
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
