// Objects that move are not landmarks: a likelihood-ratio test of a track of detections
// against a static point.
//
// Each detection, placed in the local map's frame through the filter's pose at its scan, is
// a point p_k with covariance C_k = J_z R J_zᵀ + J_x D_k J_xᵀ: the sensor's R, and D_k the
// pose covariance gained since the first detection of the track it belongs to (the
// positive part of Σ_x(t_k) − Σ_x(t_1); nothing where re-observed landmarks shrank it),
// through the inverse sensor model's Jacobians. The pose error the detections share
// is an offset of the whole track, which the fitted position absorbs. Two models explain
// the points of a track:
//   static             p_k = m + e_k,
//   constant velocity  p_k = m + v (t_k − t_0) + e_k,      e_k ~ N(0, C_k) independent.
// Weighted least squares gives each its χ² of residuals; their difference
//   Λ = χ²_static − χ²_velocity
// is χ² with 2 degrees of freedom for a static point (the velocity model has two more
// parameters) and grows with the square of the distance an object drove between its
// detections. A track moves when Λ exceeds the χ²₂ quantile at `probability` (the
// probability that a static track passes).
//
// Tracks. A filter follows an object that drives through its view (another robot carrying
// a landmark's marker) with a chain of features: each new one is paired with the object's
// next few detections until the object leaves its gate, which shrinks as the feature is
// re-observed, and the filter starts the next feature where the object went (or leaves a
// detection between its gates unexplained). One feature's few detections rarely show the
// motion; the chain's do. So a feature (or an unexplained detection) hands over to the one
// whose first detection is compatible with its last detection — the difference of the two
// points inside χ²₂(link_probability) under their summed covariances — provided it is
// never detected again after the hand-over; a static landmark keeps being detected, and so
// hands over to nothing. Each hands over to one at most (the first to begin that takes
// it), and each takes over from its most compatible candidate still free. The track of a
// feature is its chain of hand-overs, and the feature moves when its track does.
//
// The pose errors of a track's detections are positively correlated (each holds the
// drift of the ones before), so treating them as independent overstates the noise of a
// difference between two detections: for a consistent filter the test is conservative.
// A filter whose sensor noise is set too small makes static features look like moving
// ones; `subslam calibrate` estimates it. The test's power is what a track allows: an
// object seen two or three times over a second moves by about the sensor's noise and
// passes, so short tracks (an object far away, or seen just before a map closes) are
// still exported.
//
// The local mappers apply it to each map's features at its close (local_mapper.h); the
// single-map filters do not.
//
// Units: metres, seconds. Frame: the local map's.
#ifndef SUBSLAM_FRONTEND_MOVING_FEATURE_TEST_H_
#define SUBSLAM_FRONTEND_MOVING_FEATURE_TEST_H_

#include <Eigen/Core>
#include <map>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "subslam/core/pose2.h"
#include "subslam/models/range_bearing_model.h"

namespace subslam::frontend {

// The weighted least-squares fits of a static point and of a point at constant velocity to
// points p_k with covariances C_k at times t_k, kept as sufficient statistics (W_k = C_k⁻¹,
// τ_k = t_k − origin: Σ W, Σ W τ, Σ W τ², Σ W p, Σ W τ p), so that fits of parts add up.
class TrendFit {
 public:
  // A point p at time t with covariance C; a C that is not positive definite, or a p that
  // is not finite, is ignored.
  void Add(double t, const Eigen::Vector2d& p, const Eigen::Matrix2d& C);
  TrendFit& operator+=(const TrendFit& other);
  int points() const { return n_; }
  // Λ = χ²_static − χ²_velocity ≥ 0 (0 with fewer than two points, or all at one time).
  double Statistic() const;

 private:
  int n_ = 0;
  Eigen::Matrix2d W_ = Eigen::Matrix2d::Zero(), Wt_ = Eigen::Matrix2d::Zero(), Wtt_ = Eigen::Matrix2d::Zero();
  Eigen::Vector2d Wp_ = Eigen::Vector2d::Zero(), Wtp_ = Eigen::Vector2d::Zero();
};

struct MovingFeatureTestOptions {
  // P(χ²₂ ≤ threshold): the probability that a static track passes. 0: off (every feature
  // is exported).
  double probability = 0.999;
  // Tracks with fewer detections are not tested.
  int min_detections = 3;
  // The hand-over gate, P(χ²₂ ≤ gate) for the difference of two detections' points.
  double link_probability = 0.99;

  absl::Status Validate() const;
};

class MovingFeatureTest {
 public:
  MovingFeatureTest(const MovingFeatureTestOptions& options, const models::RangeBearingConfig& sensor);

  bool enabled() const { return options_.probability > 0.0; }
  // Forgets every track (a new local map).
  void Reset();
  // One scan at time t: its detections z = (range, bearing), the filter's feature of each
  // (−1: none, an unexplained detection), seen from `pose` with covariance
  // `pose_covariance` (the filter's estimate after the scan).
  void AddScan(double t, const Pose2& pose, const Eigen::Matrix3d& pose_covariance,
               const std::vector<Eigen::Vector2d>& z, const std::vector<int>& features);

  // The track of a feature seen in this map: its detections and Λ (0 for one never seen).
  int TrackDetections(int feature) const;
  double TrackStatistic(int feature) const;
  // Whether the feature is taken to move: its track has at least min_detections and Λ
  // above the bound.
  bool Moving(int feature) const;

 private:
  // One detection placed in the map: τ, its point, the point's covariance from the sensor,
  // its Jacobian in the pose, and the pose covariance at its scan.
  struct PlacedDetection {
    double tau = 0.0;
    Eigen::Vector2d p;
    Eigen::Matrix2d sensor_covariance;
    Matrix23d J_pose;
    Eigen::Matrix3d pose_covariance;
  };
  // The detections of one feature (or one unexplained detection) in this map.
  struct Segment {
    std::vector<PlacedDetection> detections;
    double t_first = 0.0, t_last = 0.0;
    // (d², segment) of the earlier segments it may take over from, by increasing d².
    std::vector<std::pair<double, int>> predecessors;
  };
  static constexpr int kNone = -1;
  // The hand-overs between the segments (predecessor_, successor_), made once per change.
  void Link() const;
  // The segments of the track holding segment `key`: the chain of hand-overs through it.
  std::vector<int> Track(int key) const;
  TrendFit TrackFit(int feature) const;

  MovingFeatureTestOptions options_;
  models::RangeBearingModel sensor_;
  double threshold_ = 0.0, link_gate_ = 0.0;
  bool has_origin_ = false;
  double origin_ = 0.0;  // τ's origin: the map's first detection
  std::vector<Segment> segments_;
  std::map<int, int> segment_of_feature_;
  mutable bool links_valid_ = false;
  mutable std::vector<int> predecessor_, successor_;  // kNone: none
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_MOVING_FEATURE_TEST_H_
