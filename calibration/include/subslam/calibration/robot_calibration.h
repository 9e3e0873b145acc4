// A robot's odometry and range-bearing sensor calibrated from its own data: the way a user
// brings a new robot (`subslam calibrate`).
//
// Usage:
//   calibration::CalibrationStart start{scan_poses, scan_pose_covariances, map};  // a SLAM run's
//   absl::StatusOr<calibration::RobotCalibration> c = calibration::CalibrateRobot(dataset, start, {});
//   // c->control_scale, c->control_noise[0].value, c->sigma_range_m.value, c->detection_by_range …
//
// Model — the filters' own (io/dataset.h, models/motion_model.h, odometry_interval.h):
//  - between consecutive scans, the recorded controls corrected by (s₀, s₁, o₁) and
//    integrated by the motion model predict the relative pose, with the steps' control noise
//    propagated as covariance: Σ_odo = Σ_k θ_k T_k, θ = (σ₀², k₀², σ₁², k₁²);
//  - each paired detection z = h(x_scan, l) + n, n ~ N(0, diag(σ_r², σ_b²)).
// Estimation, alternating until every σ moves by less than `relative_tolerance` (or a tenth
// of its standard error):
//  1. for fixed variances, Gauss-Newton (Ceres) over the scan poses (the first step's pose
//     held at the data set's initial pose), the landmarks and (s₀, s₁, o₁), the scales
//     with a weak prior (CalibrationOptions::scale_prior_sigma), refitted without the
//     paired detections whose residual fails the outlier test (step 3);
//  2. the six variance components by restricted maximum likelihood in Förstner's iterated
//     form (W. Förstner, "Ein Verfahren zur Schätzung von Varianz- und Kovarianzkomponenten",
//     Allgemeine Vermessungs-Nachrichten 86, 1979; K.-R. Koch, "Parameter Estimation and
//     Hypothesis Testing in Linear Models", Springer, 1999, §3.6):
//        θ_k ← θ_k · vᵀ W T_k W v / tr(W T_k W Q_vv),
//     W = Σ⁻¹ and Q_vv = Σ − J H⁻¹ Jᵀ the residuals' covariance: each component's weighted
//     square sum is matched to its expectation given its share of the redundancy. (Residuals
//     of a fit are smaller than the noise — they absorb the parameters — so their plain RMS
//     would understate σ.) The blocks of H⁻¹ it needs come from Ceres' covariance estimation.
//     A component the data set's noise model does not have (zero in its manifest) stays zero:
//     the form of the noise model is the user's, its magnitudes are the data's.
//  3. pairing: known association pairs detections by their true ids; otherwise each round
//     pairs each detection with the landmark that passes the individual χ²₂ gate at the
//     smallest Mahalanobis distance (current pose and landmark marginals plus the sensor
//     noise), and a detection whose normalised residual exceeds χ²₂(outlier_probability) is
//     left out of the next round (moving objects, misreadings).
// Intervals that span a control gap get their own component: their odometry covariance is
// λ Σ_k θ_k T_k, λ estimated from them alone, so that a stale control neither inflates the
// four control-noise components nor pulls the fit.
// Then, from the final estimate: the field of view and range limits as the extremes of the
// paired detections' predicted range and bearing (the estimate's, not the noisy measured
// ones, whose extremes overshoot the limits by a few σ), and the detection probability by range inside them: in each
// range bin, the scans at which a landmark was predicted in view against those that detected it, corrected for the
// scans a data set does not record (those that detected nothing) by the zero-truncated maximum likelihood, with a 95 %
// interval: Jeffreys' (Beta(k + ½, n − k + ½) quantiles) for the binomial of the same information, n = p(1 − p) /
// var(p), var(p) from the truncated likelihood's observed information.
//
// Units: metres, radians, seconds; poses in the data set's world frame.
#ifndef SUBSLAM_CALIBRATION_ROBOT_CALIBRATION_H_
#define SUBSLAM_CALIBRATION_ROBOT_CALIBRATION_H_

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/core/pose2.h"
#include "subslam/io/dataset.h"

namespace subslam::calibration {

struct CalibrationOptions {
  // true: detections are paired by their true ids (the data set must have them); false:
  // by the gate each round, against CalibrationStart::landmarks.
  bool known_association = false;
  double gate_probability = 0.99;      // P(χ²₂ ≤ gate) for pairing
  double outlier_probability = 0.999;  // P(χ²₂ ≤ bound) for keeping a paired detection
  int max_rounds = 30;                 // estimate, then variances: at most this many times
  // Stop once every σ moves by less than this fraction of itself or a tenth of its
  // standard error.
  double relative_tolerance = 0.01;
  int max_solver_iterations = 50;  // Gauss-Newton iterations per round
  double detection_bin_m = 0.5;    // width of the detection curve's range bins [m]
  // σ of a Gaussian prior on each odometry scale about the data set's own (0: none). Weak
  // against data that turn and drive enough to show a scale (standard errors of 1–3 % on
  // the camera robots), it keeps a scale the data cannot see — a robot that hardly turns —
  // near its manifest value instead of wherever the noise terms pull it.
  double scale_prior_sigma = 0.1;

  absl::Status Validate() const;
};

// Where the estimate starts: typically a SLAM run's final trajectory and map.
struct CalibrationStart {
  std::vector<Pose2> scan_poses;                      // one per dataset.scans
  std::vector<Eigen::Matrix3d> scan_covariances;      // optional (first pairing's gate)
  std::vector<Eigen::Vector2d> landmarks;             // unknown association: the map to pair with
  std::vector<Eigen::Matrix2d> landmark_covariances;  // optional, one per landmark (first gate)
};

// A value with its standard error (NaN: not estimated; 0 with a value of 0: held at zero).
struct Estimated {
  double value = 0.0;
  double standard_error = std::nan("");
};

// One range bin of the detection curve, over the recorded scans that detected at least
// one landmark (a data set records no scan that detected nothing; see `probability`).
struct DetectionBin {
  double range_min_m = 0.0, range_max_m = 0.0;
  int predicted = 0;                 // landmark-scan pairs predicted in view
  int detected = 0;                  // of those, detected
  double expected_unrecorded = 0.0;  // trials in the scans that detected nothing (EM)
  // The maximum-likelihood probability under that truncation:
  // detected / (predicted + expected_unrecorded).
  double probability = std::nan("");
  double lower = 0.0, upper = 1.0;  // 95 % interval (robot_calibration.h, above)
};

struct RobotCalibration {
  // σ₀ [m/s], k₀ (fraction of |u₀|), σ₁ [rad/s or rad], k₁: models::ControlNoise's fields.
  std::array<Estimated, 4> control_noise;
  Estimated sigma_range_m, sigma_bearing_rad;
  // √λ: how much worse the odometry is over an interval that spans a control gap (a time
  // between control lines over three nominal periods, when the held control is stale)
  // than its noise model says; such intervals are weighted by it and left out of the four
  // control-noise components. 1 with NaN error when the data have no gap.
  Estimated gap_noise_factor{1.0, std::nan("")};
  int gap_intervals = 0;
  // The correction every estimator is to apply (io::MotionConfig::Corrected): the data
  // set's own composed with the one estimated here.
  Eigen::Vector2d control_scale = Eigen::Vector2d::Ones();
  Eigen::Vector2d control_offset = Eigen::Vector2d::Zero();
  Eigen::Vector3d correction_standard_error = Eigen::Vector3d::Constant(std::nan(""));  // s₀, s₁, o₁
  double min_range_m = 0.0, max_range_m = 0.0, fov_min_rad = 0.0, fov_max_rad = 0.0;
  std::vector<DetectionBin> detection_by_range;
  int detections = 0;           // in the data set
  int detections_paired = 0;    // used in the last round
  int detections_outliers = 0;  // paired, then left out by the residual test
  int landmarks = 0;            // estimated (paired at least once)
  double redundancy = 0.0;      // observations − unknowns in the last round
  int rounds = 0;
  bool converged = false;
  std::vector<Pose2> scan_poses;
  std::vector<Eigen::Vector2d> landmark_positions;
};

absl::StatusOr<RobotCalibration> CalibrateRobot(const io::Dataset& dataset, const CalibrationStart& start,
                                                const CalibrationOptions& options);

}  // namespace subslam::calibration

#endif  // SUBSLAM_CALIBRATION_ROBOT_CALIBRATION_H_
