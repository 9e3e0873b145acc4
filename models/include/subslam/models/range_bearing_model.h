// Range-bearing sensor model, its inverse (landmark initialisation) and Jacobians.
//
// A landmark l = (lx, ly) seen from sensor pose p = (x, y, θ) gives
//   z = h(p, l) = ( ‖l − p.xy‖ , wrap(atan2(ly − y, lx − x) − θ) ),
// measured with independent Gaussian noise R = diag(σ_r², σ_b²). The inverse model is
//   l = g(p, z) = p.xy + r·(cos(θ + b), sin(θ + b)).
// Units: metres and radians; bearing counter-clockwise from the sensor's x axis
// (conventions.h). The object is immutable and thread-safe.
#ifndef SUBSLAM_MODELS_RANGE_BEARING_MODEL_H_
#define SUBSLAM_MODELS_RANGE_BEARING_MODEL_H_

#include <Eigen/Core>

#include "absl/status/status.h"
#include "subslam/core/pose2.h"

namespace subslam::models {

struct RangeBearingConfig {
  double sigma_range_m = 0.5;       // σ_r
  double sigma_bearing_rad = 0.02;  // σ_b
  double min_range_m = 0.0;         // detections closer than this are ignored
  double max_range_m = 30.0;        // sensor range
  double fov_min_rad = -kPi;        // field of view [fov_min, fov_max] in the sensor frame
  double fov_max_rad = kPi;

  absl::Status Validate() const;
};

class RangeBearingModel {
 public:
  explicit RangeBearingModel(const RangeBearingConfig& config) : config_(config) {}

  // z = h(p, l). J_z_pose is 2×3, J_z_landmark 2×2. The landmark must not coincide
  // with the sensor position (range > 0), a contract violation.
  Eigen::Vector2d Observe(const Pose2& sensor_pose, const Eigen::Vector2d& landmark, Matrix23d* J_z_pose = nullptr,
                          Eigen::Matrix2d* J_z_landmark = nullptr) const;

  // Observe in two parts, for callers that need the bearing (one atan2) for few
  // landmarks only: the range with both Jacobians, and the bearing alone.
  double ObserveRange(const Pose2& sensor_pose, const Eigen::Vector2d& landmark, Matrix23d* J_z_pose = nullptr,
                      Eigen::Matrix2d* J_z_landmark = nullptr) const;
  static double Bearing(const Pose2& sensor_pose, const Eigen::Vector2d& landmark);

  // l = g(p, z), the inverse of Observe.
  Eigen::Vector2d InverseObserve(const Pose2& sensor_pose, const Eigen::Vector2d& z,
                                 Matrix23d* J_landmark_pose = nullptr, Eigen::Matrix2d* J_landmark_z = nullptr) const;

  // R = diag(σ_r², σ_b²).
  Eigen::Matrix2d NoiseCovariance() const;

  // Whether a (noise-free) measurement lies inside the sensor's range and field of
  // view, shrunk inwards by the given margins (use margins > 0 to ask "surely visible").
  bool IsVisible(const Eigen::Vector2d& z, double range_margin_m = 0.0, double bearing_margin_rad = 0.0) const;

  // a − b with the bearing difference wrapped.
  static Eigen::Vector2d Difference(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return {a[0] - b[0], WrapAngle(a[1] - b[1])};
  }

  const RangeBearingConfig& config() const { return config_; }

 private:
  RangeBearingConfig config_;
};

}  // namespace subslam::models

#endif  // SUBSLAM_MODELS_RANGE_BEARING_MODEL_H_
