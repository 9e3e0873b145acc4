// Online calibration of the sensor's yaw on the vehicle from consecutive local maps, before
// they are joined (no GPS, no ground truth).
//
// A sensor turned by δ against the vehicle's axis adds δ to every bearing. Within one local
// map the error is consistent — every sighting of a tree is rotated alike — so the map
// holds it as a rotation of its features about the places they were seen from, which the
// map's covariance does not carry. Consecutive maps see the same trees from places a few
// metres apart, and there the rotations disagree: a map's features turned by δ about its
// own path differ from the next map's turned about its path by about δ times the distance
// between the two paths. Joined as they are, those disagreements exceed the maps'
// covariances, association leaves the trees apart and the maps hang on their end poses
// alone (docs/limits.md).
//
// The model: a correction δ (relative to the yaw the front-end used) moves feature l of a
// local map to  c + R(δ)(l − c),  c the midpoint of the map's start and end positions (its
// path's centre, in the map's frame); the end pose does not move. Each closed map is paired
// with the one before it: the features of the two (in the earlier map's frame, through its
// end pose) are paired greedily by the smallest Mahalanobis distance of their difference,
// one to one, within the χ²₂ gate at `gate_probability`. The pairs' differences, stacked
// with their joint covariance (both maps' covariances: the pairs share the earlier map's
// end pose, whose heading error turns every later feature alike, as a yaw would), add
// their linearised term to the normal equations of the least squares in δ, with a
// zero-mean Gaussian prior of `prior_sigma_rad`; the estimate is the recursive
// least-squares solution over all pairs so far.
//
// Which maps are turned: the error of a map joined with the wrong turn is not undone by
// the maps after it — joined with the true correction from the first map on, a simulated
// 1° misalignment gives the aligned sensor's error; from the sixth map on, several times
// that (docs/design/association.md). So the run starts with a warm-up: its maps are joined as built, and
// if the estimate comes to differ from zero at `significance` (δ̂²/σ² above the χ²₁
// quantile) before it is known to `settled_sigma_rad` or `warm_up_maps` maps have passed,
// every map of the warm-up is handed on again, turned by that estimate, to be joined into
// a new joiner from the start (Ready::restart). After the warm-up each map is handed on
// turned by the estimate of its time if that differs from zero at `significance`, and as
// built otherwise. A map's covariance is not widened by the estimate's uncertainty: that
// error is one and the same for every map, where a widening would treat it as independent
// per map and take from each the heading information its features carry.
//
// On data without a misalignment the estimate stays within its uncertainty of zero and
// the maps are joined as built. What δ̂ estimates is the rotation of this model, which
// absorbs more than the bearing offset (the vehicle's path within a map was also
// estimated from biased bearings), so it need not equal an offline calibration of the
// bearings (the measurements: docs/design/association.md).
// Not thread-safe.
#ifndef SUBSLAM_BACKEND_SENSOR_YAW_CALIBRATION_H_
#define SUBSLAM_BACKEND_SENSOR_YAW_CALIBRATION_H_

#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "subslam/core/local_submap.h"

namespace subslam::backend {

struct SensorYawCalibrationOptions {
  bool enabled = true;
  // The correction's prior: zero mean, this sigma [rad] (about a degree: a sensor mounted
  // by eye). It weighs only until the first pairs.
  double prior_sigma_rad = 0.02;
  // The χ²₂ gate for pairing the features of consecutive maps.
  double gate_probability = 0.99;
  // A map is turned only while the estimate differs from zero at this level.
  double significance = 0.999;
  // The warm-up (see above) ends without a turn once the estimate's sigma is below this
  // [rad] (0.002: a feature 20 m away moves 4 cm) or after this many maps.
  double settled_sigma_rad = 0.002;
  int warm_up_maps = 50;

  absl::Status Validate() const;
};

// The difference between feature i of a map and feature j of the next, both turned by
// `yaw` about their maps' path centres, in the earlier map's frame:
//   d = f(l_i) − end ⊕ f'(l_j),   f(l) = c + R(yaw)(l − c),  c = end.xy / 2,
// with its Jacobians (analytic; tested numerically).
struct YawPairDifference {
  Eigen::Vector2d d;
  Eigen::Vector2d d_yaw;                  // ∂d/∂yaw
  Eigen::Matrix<double, 2, 5> d_earlier;  // ∂d/∂[l_i, earlier end pose (x, y, θ)]
  Eigen::Matrix<double, 2, 4> d_later;    // ∂d/∂[l_j, later end position (x, y)]
};
YawPairDifference PairDifference(const LocalSubmap& earlier, int i, const LocalSubmap& later, int j, double yaw);

class SensorYawCalibration {
 public:
  explicit SensorYawCalibration(const SensorYawCalibrationOptions& options);

  // What to join: `maps` in order, into the joiner as it is, or — `restart` — into a new
  // joiner, from the first map of the run (the warm-up's maps, turned).
  struct Ready {
    std::vector<LocalSubmap> maps;
    bool restart = false;
  };
  // Takes the next local map as the front-end built it (maps in run order, each valid).
  Ready Add(const LocalSubmap& built);

  double estimate() const;               // δ̂ [rad], to be added to the sensor's yaw
  double sigma() const;                  // its standard deviation [rad] (the least squares')
  long pairs() const { return pairs_; }  // feature pairs used so far
  bool enabled() const { return options_.enabled; }
  long maps_turned() const { return maps_turned_; }  // maps passed on with a correction
  int restarts() const { return restarts_; }         // Ready::restart handed out (0 or 1)
  // The figures above under their report.json names (sensor_yaw_correction, _sigma,
  // _pairs, _maps_turned, _joiner_restarts); none when off.
  std::map<std::string, double> Counters() const;

  // `map` with its features turned by `yaw` about its path's centre and its covariance
  // transformed to first order (the end pose, which the centre follows, unchanged).
  static LocalSubmap Rotated(const LocalSubmap& map, double yaw);

 private:
  void AddPairs(const LocalSubmap& earlier, const LocalSubmap& later);
  bool Significant() const;
  LocalSubmap Corrected(const LocalSubmap& built);

  SensorYawCalibrationOptions options_;
  double gate_ = 0.0;
  double significant_ = 0.0;  // the χ²₁ quantile at options_.significance
  double information_ = 0.0;  // Σ aᵀ S⁻¹ a over the pairs (the prior not included)
  double projected_ = 0.0;    // Σ aᵀ S⁻¹ (a δ_linearised − d)
  long pairs_ = 0;
  long maps_turned_ = 0;
  int restarts_ = 0;
  bool have_previous_ = false;
  LocalSubmap previous_;
  bool warmed_up_ = false;
  std::vector<LocalSubmap> warm_up_;  // the warm-up's maps as built
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_SENSOR_YAW_CALIBRATION_H_
