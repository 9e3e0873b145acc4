#include "subslam/backend/sensor_yaw_calibration.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "subslam/models/gating.h"

namespace subslam::backend {
namespace {

Eigen::Matrix2d Rotation(double a) { return Eigen::Rotation2Dd(a).toRotationMatrix(); }

// dR(a)/da = R(a) · [0 −1; 1 0].
Eigen::Matrix2d RotationDerivative(double a) {
  Eigen::Matrix2d quarter_turn;
  quarter_turn << 0.0, -1.0, 1.0, 0.0;
  return Rotation(a) * quarter_turn;
}

Eigen::Vector2d PathCentre(const LocalSubmap& map) { return 0.5 * map.mean.head<2>(); }

}  // namespace

absl::Status SensorYawCalibrationOptions::Validate() const {
  if (!(std::isfinite(prior_sigma_rad) && prior_sigma_rad > 0.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("sensor yaw calibration: prior_sigma_rad must be finite and > 0, got ", prior_sigma_rad));
  }
  if (!(significance > 0.0 && significance < 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("sensor yaw calibration: significance must be in (0, 1), got ", significance));
  }
  if (!(std::isfinite(settled_sigma_rad) && settled_sigma_rad >= 0.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("sensor yaw calibration: settled_sigma_rad must be finite and >= 0, got ", settled_sigma_rad));
  }
  if (warm_up_maps < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("sensor yaw calibration: warm_up_maps must be >= 0, got ", warm_up_maps));
  }
  if (!(gate_probability > 0.0 && gate_probability < 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("sensor yaw calibration: gate_probability must be in (0, 1), got ", gate_probability));
  }
  return absl::OkStatus();
}

YawPairDifference PairDifference(const LocalSubmap& earlier, int i, const LocalSubmap& later, int j, double yaw) {
  const Eigen::Matrix2d R = Rotation(yaw);
  const Eigen::Matrix2d dR = RotationDerivative(yaw);
  const Pose2 end = earlier.end_pose();
  const Eigen::Matrix2d R_end = end.rotation();
  const Eigen::Vector2d c1 = PathCentre(earlier);
  const Eigen::Vector2d c2 = PathCentre(later);
  const Eigen::Vector2d u1 = earlier.landmark(i) - c1;
  const Eigen::Vector2d u2 = later.landmark(j) - c2;
  const Eigen::Vector2d m = c2 + R * u2;  // the later feature turned, in the later map's frame
  const Eigen::Vector2d m_parent = R_end * m;
  YawPairDifference out;
  out.d = c1 + R * u1 - (end.translation() + m_parent);
  out.d_yaw = dR * u1 - R_end * dR * u2;
  const Eigen::Matrix2d I = Eigen::Matrix2d::Identity();
  out.d_earlier.leftCols<2>() = R;
  out.d_earlier.block<2, 2>(0, 2) = 0.5 * (I - R) - I;
  out.d_earlier.col(4) = Eigen::Vector2d(m_parent.y(), -m_parent.x());  // −∂(R_end m)/∂θ
  out.d_later.leftCols<2>() = -R_end * R;
  out.d_later.rightCols<2>() = -R_end * 0.5 * (I - R);
  return out;
}

LocalSubmap SensorYawCalibration::Rotated(const LocalSubmap& map, double yaw) {
  LocalSubmap out = map;
  const int n = map.num_landmarks();
  if (n == 0 || yaw == 0.0) return out;
  const int dim = 3 + 2 * n;
  const Eigen::Matrix2d R = Rotation(yaw);
  const Eigen::Vector2d c = PathCentre(map);
  Eigen::MatrixXd G = Eigen::MatrixXd::Identity(dim, dim);  // ∂out.mean/∂map.mean
  for (int k = 0; k < n; ++k) {
    const int o = 3 + 2 * k;
    out.mean.segment<2>(o) = c + R * (map.landmark(k) - c);
    G.block<2, 2>(o, o) = R;
    G.block<2, 2>(o, 0) = 0.5 * (Eigen::Matrix2d::Identity() - R);
  }
  out.covariance = G * map.covariance * G.transpose();
  out.covariance = (0.5 * (out.covariance + out.covariance.transpose())).eval();
  return out;
}

SensorYawCalibration::SensorYawCalibration(const SensorYawCalibrationOptions& options)
    : options_(options),
      gate_(models::ChiSquareQuantile(options.gate_probability, 2)),
      significant_(models::ChiSquareQuantile(options.significance, 1)) {}

double SensorYawCalibration::estimate() const {
  return projected_ / (information_ + 1.0 / (options_.prior_sigma_rad * options_.prior_sigma_rad));
}

double SensorYawCalibration::sigma() const {
  return 1.0 / std::sqrt(information_ + 1.0 / (options_.prior_sigma_rad * options_.prior_sigma_rad));
}

void SensorYawCalibration::AddPairs(const LocalSubmap& earlier, const LocalSubmap& later) {
  const int n1 = earlier.num_landmarks();
  const int n2 = later.num_landmarks();
  if (n1 == 0 || n2 == 0) return;
  const double yaw = estimate();
  const double yaw_variance = sigma() * sigma();
  struct Candidate {
    double d2;
    int i, j;
    YawPairDifference difference;
  };
  std::vector<Candidate> candidates;
  Eigen::Matrix<double, 5, 5> C1;
  Eigen::Matrix4d C2;
  for (int i = 0; i < n1; ++i) {
    const int rows1[5] = {3 + 2 * i, 4 + 2 * i, 0, 1, 2};
    for (int r = 0; r < 5; ++r) {
      for (int s = 0; s < 5; ++s) C1(r, s) = earlier.covariance(rows1[r], rows1[s]);
    }
    for (int j = 0; j < n2; ++j) {
      const int rows2[4] = {3 + 2 * j, 4 + 2 * j, 0, 1};
      for (int r = 0; r < 4; ++r) {
        for (int s = 0; s < 4; ++s) C2(r, s) = later.covariance(rows2[r], rows2[s]);
      }
      const YawPairDifference p = PairDifference(earlier, i, later, j, yaw);
      const Eigen::Matrix2d S = p.d_earlier * C1 * p.d_earlier.transpose() + p.d_later * C2 * p.d_later.transpose();
      const Eigen::Matrix2d S_gate = S + yaw_variance * p.d_yaw * p.d_yaw.transpose();
      const Eigen::LLT<Eigen::Matrix2d> llt(S_gate);
      if (llt.info() != Eigen::Success) continue;
      const double d2 = p.d.dot(llt.solve(p.d));
      if (d2 < gate_) candidates.push_back({d2, i, j, p});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    return x.d2 != y.d2 ? x.d2 < y.d2 : (x.i != y.i ? x.i < y.i : x.j < y.j);
  });
  std::vector<bool> used1(n1, false), used2(n2, false);
  std::vector<const Candidate*> pairs;
  for (const Candidate& c : candidates) {
    if (used1[c.i] || used2[c.j]) continue;
    used1[c.i] = used2[c.j] = true;
    pairs.push_back(&c);
  }
  if (pairs.empty()) return;
  // The pairs' differences stacked, with their joint covariance: they share the earlier
  // map's end pose and each map's correlations, so they are not independent (a heading error
  // of the end pose turns every later feature alike, as a yaw would).
  const int m = static_cast<int>(pairs.size());
  std::vector<int> rows1 = {0, 1, 2}, rows2 = {0, 1};
  for (const Candidate* c : pairs) {
    rows1.insert(rows1.end(), {3 + 2 * c->i, 4 + 2 * c->i});
    rows2.insert(rows2.end(), {3 + 2 * c->j, 4 + 2 * c->j});
  }
  Eigen::VectorXd D(2 * m), a(2 * m);
  Eigen::MatrixXd A1 = Eigen::MatrixXd::Zero(2 * m, rows1.size());
  Eigen::MatrixXd A2 = Eigen::MatrixXd::Zero(2 * m, rows2.size());
  for (int k = 0; k < m; ++k) {
    const YawPairDifference& p = pairs[k]->difference;
    D.segment<2>(2 * k) = p.d;
    a.segment<2>(2 * k) = p.d_yaw;
    A1.block<2, 3>(2 * k, 0) = p.d_earlier.rightCols<3>();
    A1.block<2, 2>(2 * k, 3 + 2 * k) = p.d_earlier.leftCols<2>();
    A2.block<2, 2>(2 * k, 0) = p.d_later.rightCols<2>();
    A2.block<2, 2>(2 * k, 2 + 2 * k) = p.d_later.leftCols<2>();
  }
  const Eigen::MatrixXd S =
      A1 * earlier.covariance(rows1, rows1) * A1.transpose() + A2 * later.covariance(rows2, rows2) * A2.transpose();
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(S);
  if (ldlt.info() != Eigen::Success) return;
  const Eigen::VectorXd Sa = ldlt.solve(a);
  // D(δ) ≈ D + a (δ − yaw): its normal equations.
  information_ += a.dot(Sa);
  projected_ += Sa.dot(a * yaw - D);
  pairs_ += m;
}

bool SensorYawCalibration::Significant() const {
  const double z = estimate() / sigma();
  return z * z > significant_;
}

LocalSubmap SensorYawCalibration::Corrected(const LocalSubmap& built) {
  if (!Significant()) return built;
  ++maps_turned_;
  return Rotated(built, estimate());
}

SensorYawCalibration::Ready SensorYawCalibration::Add(const LocalSubmap& built) {
  Ready out;
  if (!options_.enabled) {
    out.maps.push_back(built);
    return out;
  }
  if (have_previous_) AddPairs(previous_, built);
  previous_ = built;
  have_previous_ = true;
  if (warmed_up_) {
    out.maps.push_back(Corrected(built));
    return out;
  }
  warm_up_.push_back(built);
  if (Significant()) {  // the maps joined as built so far are to be joined again, turned
    warmed_up_ = true;
    out.restart = true;
    ++restarts_;
    for (const LocalSubmap& m : warm_up_) out.maps.push_back(Corrected(m));
    warm_up_.clear();
    return out;
  }
  if (sigma() <= options_.settled_sigma_rad || static_cast<int>(warm_up_.size()) >= options_.warm_up_maps) {
    warmed_up_ = true;  // no misalignment shown: the maps stay as joined
    warm_up_.clear();
  }
  out.maps.push_back(built);
  return out;
}

std::map<std::string, double> SensorYawCalibration::Counters() const {
  if (!options_.enabled) return {};
  return {{"sensor_yaw_correction", estimate()},
          {"sensor_yaw_correction_sigma", sigma()},
          {"sensor_yaw_pairs", static_cast<double>(pairs_)},
          {"sensor_yaw_maps_turned", static_cast<double>(maps_turned_)},
          {"sensor_yaw_joiner_restarts", static_cast<double>(restarts_)}};
}

}  // namespace subslam::backend
