#include "subslam/association/local_map_rotation.h"

#include <Eigen/Geometry>
#include <cmath>

#include "subslam/core/check.h"

namespace subslam::association {

Eigen::VectorXd RotationAboutStart(const LocalSubmap& s) {
  Eigen::VectorXd g(s.mean.size());
  g[0] = -s.mean[1];
  g[1] = s.mean[0];
  g[2] = 1.0;
  for (int i = 0; i < s.num_landmarks(); ++i) {
    g[3 + 2 * i] = -s.mean[4 + 2 * i];
    g[4 + 2 * i] = s.mean[3 + 2 * i];
  }
  return g;
}

LocalSubmap WidenedByRotation(const LocalSubmap& s, double sigma_rad) {
  SUBSLAM_CHECK(sigma_rad >= 0 && std::isfinite(sigma_rad)) << "rotation sigma " << sigma_rad;
  LocalSubmap w = s;
  const Eigen::VectorXd g = RotationAboutStart(s);
  w.covariance.noalias() += (sigma_rad * sigma_rad) * g * g.transpose();
  w.rotation_widening_rad = std::hypot(s.rotation_widening_rad, sigma_rad);
  return w;
}

LocalSubmap WidenedFeaturesByRotation(const LocalSubmap& s, double sigma_rad) {
  SUBSLAM_CHECK(sigma_rad >= 0 && std::isfinite(sigma_rad)) << "rotation sigma " << sigma_rad;
  LocalSubmap w = s;
  Eigen::VectorXd g = RotationAboutStart(s);
  g.head<3>().setZero();
  w.covariance.noalias() += (sigma_rad * sigma_rad) * g * g.transpose();
  w.rotation_spread_rad = std::hypot(s.rotation_spread_rad, sigma_rad);
  return w;
}

LocalSubmap RotatedAboutStart(const LocalSubmap& s, double delta_rad) {
  SUBSLAM_CHECK(std::isfinite(delta_rad)) << "rotation " << delta_rad;
  const int dim = static_cast<int>(s.mean.size());
  const Eigen::Rotation2Dd R(delta_rad);
  const Eigen::Matrix2d Rm = R.toRotationMatrix();
  LocalSubmap r = s;
  r.mean.head<2>() = Rm * s.mean.head<2>();
  r.mean[2] = WrapAngle(s.mean[2] + delta_rad);
  for (int i = 0; i < s.num_landmarks(); ++i) r.mean.segment<2>(3 + 2 * i) = Rm * s.mean.segment<2>(3 + 2 * i);
  // A·Σ·Aᵀ with A block-diagonal: rows, then columns, block by block.
  const auto rotate_rows = [&](Eigen::MatrixXd* m) {
    m->topRows<2>() = Rm * m->topRows<2>();
    for (int i = 0; i < s.num_landmarks(); ++i) m->middleRows<2>(3 + 2 * i) = Rm * m->middleRows<2>(3 + 2 * i);
  };
  Eigen::MatrixXd C = s.covariance;
  rotate_rows(&C);
  C.transposeInPlace();
  rotate_rows(&C);
  r.covariance = 0.5 * (C + C.transpose());
  SUBSLAM_CHECK(r.covariance.rows() == dim);
  return r;
}

}  // namespace subslam::association
