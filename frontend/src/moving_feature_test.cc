#include "subslam/frontend/moving_feature_test.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "subslam/models/gating.h"

namespace subslam::frontend {

namespace {

// The positive part of a symmetric matrix (its negative eigenvalues set to zero).
Eigen::Matrix3d PositivePart(const Eigen::Matrix3d& A) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(0.5 * (A + A.transpose()));
  return eigen.eigenvectors() * eigen.eigenvalues().cwiseMax(0.0).asDiagonal() * eigen.eigenvectors().transpose();
}

}  // namespace

void TrendFit::Add(double t, const Eigen::Vector2d& p, const Eigen::Matrix2d& C) {
  const Eigen::LLT<Eigen::Matrix2d> llt(0.5 * (C + C.transpose()));
  if (llt.info() != Eigen::Success || !p.allFinite() || !std::isfinite(t)) return;
  const Eigen::Matrix2d W = llt.solve(Eigen::Matrix2d::Identity());
  ++n_;
  W_ += W;
  Wt_ += t * W;
  Wtt_ += t * t * W;
  Wp_ += W * p;
  Wtp_ += t * (W * p);
}

TrendFit& TrendFit::operator+=(const TrendFit& o) {
  n_ += o.n_;
  W_ += o.W_;
  Wt_ += o.Wt_;
  Wtt_ += o.Wtt_;
  Wp_ += o.Wp_;
  Wtp_ += o.Wtp_;
  return *this;
}

double TrendFit::Statistic() const {
  if (n_ < 2) return 0.0;
  // χ²_static = Σ pᵀWp − (ΣWp)ᵀ(ΣW)⁻¹(ΣWp); χ²_velocity likewise with the 4 × 4 normal
  // matrix [ΣW ΣWτ; ΣWτ ΣWτ²] and [ΣWp; ΣWτp]. Λ is the difference of the two explained
  // parts (Σ pᵀWp cancels).
  Eigen::Matrix4d M;
  M << W_, Wt_, Wt_, Wtt_;
  Eigen::Vector4d b;
  b << Wp_, Wtp_;
  const Eigen::LDLT<Eigen::Matrix4d> normal(M);
  if (normal.info() != Eigen::Success || !(normal.rcond() > 1e-12)) return 0.0;  // all at one time
  const double explained_velocity = b.dot(normal.solve(b));
  const double explained_static = Wp_.dot(W_.ldlt().solve(Wp_));
  return std::max(0.0, explained_velocity - explained_static);
}

absl::Status MovingFeatureTestOptions::Validate() const {
  if (!(probability >= 0.0 && probability < 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("moving-feature test: probability must be in [0, 1) (0: off), got ", probability));
  }
  if (!(link_probability > 0.0 && link_probability < 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("moving-feature test: link_probability must be in (0, 1), got ", link_probability));
  }
  if (min_detections < 2) {
    return absl::InvalidArgumentError(
        absl::StrCat("moving-feature test: min_detections must be >= 2, got ", min_detections));
  }
  return absl::OkStatus();
}

MovingFeatureTest::MovingFeatureTest(const MovingFeatureTestOptions& options, const models::RangeBearingConfig& sensor)
    : options_(options),
      sensor_(sensor),
      threshold_(options.probability > 0.0 ? models::ChiSquareQuantile(options.probability, 2.0) : 0.0),
      link_gate_(models::ChiSquareQuantile(options.link_probability, 2.0)) {}

void MovingFeatureTest::Reset() {
  has_origin_ = false;
  links_valid_ = false;
  segments_.clear();
  segment_of_feature_.clear();
}

void MovingFeatureTest::AddScan(double t, const Pose2& pose, const Eigen::Matrix3d& pose_covariance,
                                const std::vector<Eigen::Vector2d>& z, const std::vector<int>& features) {
  if (!enabled()) return;
  links_valid_ = false;
  if (!has_origin_) {
    has_origin_ = true;
    origin_ = t;
  }
  const double tau = t - origin_;
  const int earlier = static_cast<int>(segments_.size());  // segments of earlier scans
  for (size_t k = 0; k < z.size() && k < features.size(); ++k) {
    Matrix23d J_pose;
    Eigen::Matrix2d J_z;
    const Eigen::Vector2d p = sensor_.InverseObserve(pose, z[k], &J_pose, &J_z);
    const Eigen::Matrix2d sensor_covariance = J_z * sensor_.NoiseCovariance() * J_z.transpose();
    int key = kNone;
    if (features[k] >= 0) {
      const auto it = segment_of_feature_.find(features[k]);
      if (it != segment_of_feature_.end()) key = it->second;
    }
    if (key == kNone) {  // a new feature, or an unexplained detection: a new segment
      Segment s;
      s.t_first = tau;
      // The segments it may take over from: the earlier ones whose last detection is
      // compatible with this one, the most compatible first.
      for (int q = 0; q < earlier; ++q) {
        const PlacedDetection& last = segments_[q].detections.back();
        const Eigen::Matrix2d C = last.sensor_covariance + sensor_covariance +
                                  J_pose * PositivePart(pose_covariance - last.pose_covariance) * J_pose.transpose();
        const Eigen::Vector2d d = p - last.p;
        const double d2 = d.dot(C.ldlt().solve(d));
        if (d2 <= link_gate_) s.predecessors.emplace_back(d2, q);
      }
      std::sort(s.predecessors.begin(), s.predecessors.end());
      key = static_cast<int>(segments_.size());
      segments_.push_back(s);
      if (features[k] >= 0) segment_of_feature_[features[k]] = key;
    }
    Segment& s = segments_[key];
    s.detections.push_back({tau, p, sensor_covariance, J_pose, pose_covariance});
    s.t_last = tau;
  }
}

void MovingFeatureTest::Link() const {
  if (links_valid_) return;
  // The hand-overs, made in the order the segments began: each takes over from its most
  // compatible earlier segment that was not detected after it began and has not handed
  // over to another yet, so that a track is a chain (a segment has one successor).
  const int n = static_cast<int>(segments_.size());
  predecessor_.assign(n, kNone);
  successor_.assign(n, kNone);
  for (int s = 0; s < n; ++s) {
    for (const auto& [d2, q] : segments_[s].predecessors) {
      if (successor_[q] == kNone && segments_[q].t_last < segments_[s].t_first) {
        predecessor_[s] = q;
        successor_[q] = s;
        break;
      }
    }
  }
  links_valid_ = true;
}

std::vector<int> MovingFeatureTest::Track(int key) const {
  Link();
  std::vector<int> track = {key};
  for (int at = predecessor_[key]; at != kNone; at = predecessor_[at]) track.push_back(at);
  for (int at = successor_[key]; at != kNone; at = successor_[at]) track.push_back(at);
  return track;
}

TrendFit MovingFeatureTest::TrackFit(int feature) const {
  TrendFit fit;
  const auto it = segment_of_feature_.find(feature);
  if (it == segment_of_feature_.end()) return fit;
  const std::vector<int> track = Track(it->second);
  // The pose covariance at the track's first detection (its first segment's): what every
  // detection's pose error shares.
  int first = track[0];
  for (int s : track) first = std::min(first, s);
  const Eigen::Matrix3d& shared = segments_[first].detections.front().pose_covariance;
  for (int s : track) {
    for (const PlacedDetection& d : segments_[s].detections) {
      fit.Add(d.tau, d.p,
              d.sensor_covariance + d.J_pose * PositivePart(d.pose_covariance - shared) * d.J_pose.transpose());
    }
  }
  return fit;
}

int MovingFeatureTest::TrackDetections(int feature) const { return TrackFit(feature).points(); }

double MovingFeatureTest::TrackStatistic(int feature) const { return TrackFit(feature).Statistic(); }

bool MovingFeatureTest::Moving(int feature) const {
  if (!enabled()) return false;
  const TrendFit fit = TrackFit(feature);
  return fit.points() >= options_.min_detections && fit.Statistic() > threshold_;
}

}  // namespace subslam::frontend
