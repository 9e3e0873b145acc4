// The odometry's systematic error, learned by the filters from their own data.
//
// A robot's odometry is rarely what it records: commanded rather than measured rates,
// worn wheels, a steering gain. The model: a recorded control u stands for
//   u' = (s0·u0, s1·u1 + b),   c = (s0, s1, b),
// the control the motion model is given (its noise taken at u'), with c constant over the
// run. The filters carry c with its uncertainty and learn it from what the landmarks say
// about the motion:
//  * EKF-SLAM (and the EKF local mapper) as part of its state: the augmented Kalman filter
//    of odometry self-calibration (A. Martinelli, N. Tomatis and R. Siegwart,
//    "Simultaneous localization and odometry self calibration for mobile robot",
//    Autonomous Robots 22(1):75–85, 2007);
//  * the particle filters as a Gaussian per particle, updated from the particle's own pose
//    samples — conditional on its path, c has a Gaussian posterior to first order, so it
//    is Rao-Blackwellised like the landmarks: G. Storvik, "Particle filters for
//    state-space models with the presence of unknown static parameters", IEEE
//    Transactions on Signal Processing 50(2):281–289, 2002.
// A new local map starts with the calibration the last one ended with (its estimate and
// covariance): the maps share one calibration that each refines.
#ifndef SUBSLAM_FRONTEND_ODOMETRY_CALIBRATION_H_
#define SUBSLAM_FRONTEND_ODOMETRY_CALIBRATION_H_

#include <Eigen/Core>
#include <map>
#include <string>

#include "absl/status/status.h"

namespace subslam::frontend {

// Priors: each scale ~ N(1, scale_prior_sigma²), the channel-1 offset b ~ N(0,
// offset_prior_sigma²) in channel 1's unit (rad/s for the unicycle, rad of steering for
// the Ackermann model).
struct OdometryCalibrationOptions {
  // 0: off (the controls are taken as they are recorded). 0.05: the robot's odometry is
  // believed to within about 5 % (commanded rates, wheel radii, a steering gain).
  double scale_prior_sigma = 0.0;
  // 0 with the scales on: no offset is estimated.
  double offset_prior_sigma = 0.0;

  bool enabled() const { return scale_prior_sigma > 0.0; }
  absl::Status Validate() const;
  // The prior of c = (s0, s1, b).
  Eigen::Vector3d PriorMean() const { return Eigen::Vector3d(1.0, 1.0, 0.0); }
  Eigen::Matrix3d PriorCovariance() const;
};

// The control a recorded u stands for under the calibration c = (s0, s1, b):
// u' = (s0·u0, s1·u1 + b), and its Jacobian ∂u'/∂c.
Eigen::Vector2d CalibratedControl(const Eigen::Vector2d& u, const Eigen::Vector3d& c,
                                  Eigen::Matrix<double, 2, 3>* J_c = nullptr);

// A filter's estimate of c and its covariance (value (1, 1, 0) and zero covariance when
// the calibration is off).
struct OdometryCalibrationEstimate {
  Eigen::Vector3d value = Eigen::Vector3d(1.0, 1.0, 0.0);
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();

  // Under report.json's names: odometry_scale_0, odometry_scale_1, odometry_offset_1 and
  // each with _sigma.
  void AddCounters(std::map<std::string, double>* out) const;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_ODOMETRY_CALIBRATION_H_
