// FastSlam: the odometry calibration carried per particle (fastslam.h,
// odometry_calibration.h).
#include <Eigen/Cholesky>
#include <cmath>

#include "subslam/frontend/fastslam.h"

namespace subslam::frontend {

void FastSlam::PredictCalibrated(const Eigen::Vector2d& u, double dt) {
  // r ← f(r, u'(ĉ)), D ← F D + G ∂u'/∂c: the motion since the scan at ĉ and its Jacobian.
  Eigen::Matrix<double, 2, 3> du_dc;
  const Eigen::Vector2d u_calibrated = CalibratedControl(u, calibration_linearized_, &du_dc);
  Eigen::Matrix3d F;
  Matrix32d G;
  motion_since_scan_ = motion_->Predict(motion_since_scan_, u_calibrated, dt, &F, &G);
  motion_covariance_ =
      F * motion_covariance_ * F.transpose() + G * motion_->noise().Covariance(u_calibrated) * G.transpose();
  motion_calibration_jacobian_ = (F * motion_calibration_jacobian_ + G * du_dc).eval();
}

void FastSlam::UpdateCalibration(Particle* p, const Pose2& previous) const {
  // The motion the sampled pose implies, ρ = previous⁻¹ ∘ pose, is r̂ + D(c − ĉ) + w with
  // w ~ N(0, Σ_r): a linear observation of c, folded into N(m_p, P_p) by a Kalman step.
  const Eigen::Matrix3d& D = motion_calibration_jacobian_;
  if (D.isZero(0.0)) return;  // no motion since the last scan
  const double c = std::cos(previous.theta), s = std::sin(previous.theta);
  const double dx = p->pose.x - previous.x, dy = p->pose.y - previous.y;
  const Eigen::Vector3d rho(c * dx + s * dy, -s * dx + c * dy, WrapAngle(p->pose.theta - previous.theta));
  Eigen::Vector3d innovation = rho - motion_since_scan_.vector() - D * (p->calibration - calibration_linearized_);
  innovation.z() = WrapAngle(innovation.z());
  const Eigen::Matrix3d PDt = p->calibration_covariance * D.transpose();
  const Eigen::LLT<Eigen::Matrix3d> llt(motion_covariance_ + D * PDt);
  if (llt.info() != Eigen::Success) return;                             // no motion noise to weigh it by
  const Eigen::Matrix3d gain = llt.solve(PDt.transpose()).transpose();  // P Dᵀ S⁻¹
  p->calibration += gain * innovation;
  const Eigen::Matrix3d updated = p->calibration_covariance - gain * PDt.transpose();
  p->calibration_covariance = 0.5 * (updated + updated.transpose());
}

OdometryCalibrationEstimate FastSlam::odometry_calibration() const {
  OdometryCalibrationEstimate e;
  if (!options_.odometry.enabled()) return e;
  if (particles_.empty()) {
    e.value = options_.odometry.PriorMean();
    e.covariance = options_.odometry.PriorCovariance();
    return e;
  }
  // The weighted mixture's mean and covariance.
  e.value.setZero();
  for (const Particle& p : particles_) e.value += std::exp(p.log_weight) * p.calibration;
  e.covariance.setZero();
  for (const Particle& p : particles_) {
    const Eigen::Vector3d d = p.calibration - e.value;
    e.covariance += std::exp(p.log_weight) * (p.calibration_covariance + d * d.transpose());
  }
  return e;
}

void FastSlam::RecentreCalibration() {
  const OdometryCalibrationEstimate e = odometry_calibration();
  calibration_linearized_ = e.value;
  calibration_spread_ = e.covariance;
  motion_calibration_jacobian_.setZero();
}

}  // namespace subslam::frontend
