#include "subslam/backend/landmark_persistence.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "absl/strings/str_cat.h"
#include "subslam/models/gating.h"

namespace subslam::backend {

absl::Status LandmarkPersistenceOptions::Validate() const {
  if (!(gate_probability > 0.0 && gate_probability < 1.0)) {
    return absl::InvalidArgumentError(absl::StrCat("gate_probability must be in (0, 1), got ", gate_probability));
  }
  if (!(expect_range_margin_m >= 0.0 && expect_bearing_margin_rad >= 0.0)) {
    return absl::InvalidArgumentError("expect margins must be >= 0");
  }
  if (!(confirm_probability > 0.0 && confirm_probability < 1.0)) {
    return absl::InvalidArgumentError(absl::StrCat("confirm_probability must be in (0, 1), got ", confirm_probability));
  }
  if (range_bins < 1) return absl::InvalidArgumentError(absl::StrCat("range_bins must be >= 1, got ", range_bins));
  if (max_iterations < 1) return absl::InvalidArgumentError("max_iterations must be >= 1");
  return absl::OkStatus();
}

namespace {

// Sightings of each landmark by range bin: n (expected) and k (detected while expected).
struct Sightings {
  std::vector<std::vector<int>> expected, detected;  // [landmark][bin]
};

const PoseEstimate* PoseAt(const Trajectory& trajectory, double t) {
  const auto it = std::lower_bound(trajectory.begin(), trajectory.end(), t - 1e-9,
                                   [](const PoseEstimate& p, double time) { return p.t < time; });
  if (it == trajectory.end() || std::abs(it->t - t) > 1e-9) return nullptr;
  return &*it;
}

struct Candidate {
  double d2;
  int detection, landmark;
};

// One scan against the map: which landmarks were expected, and which of them a detection
// paired with (one to one, smallest d² first).
class ScanCounter {
 public:
  ScanCounter(const models::RangeBearingConfig& sensor, const LandmarkPersistenceOptions& options, int bins)
      : sensor_(sensor),
        options_(options),
        bins_(bins),
        bin_m_(sensor.max_range_m / bins),
        gate_d2_(models::ChiSquareQuantile(options.gate_probability, 2)),
        R_inv_(sensor_.NoiseCovariance().inverse()) {}

  void Count(const std::vector<LandmarkEstimate>& map, const Pose2& x, const Scan& scan, Sightings* s) {
    const double reach = sensor_.config().max_range_m + 5.0;
    candidates_.clear();
    expected_bin_.assign(map.size(), -1);
    for (size_t i = 0; i < map.size(); ++i) {
      if ((map[i].position - x.translation()).squaredNorm() > reach * reach) continue;
      const Eigen::Vector2d z = sensor_.Observe(x, map[i].position);
      if (sensor_.IsVisible(z, options_.expect_range_margin_m, options_.expect_bearing_margin_rad)) {
        expected_bin_[i] = std::min(bins_ - 1, static_cast<int>(z[0] / bin_m_));
      }
      for (size_t j = 0; j < scan.detections.size(); ++j) {
        const Eigen::Vector2d nu = models::RangeBearingModel::Difference(scan.detections[j].z(), z);
        const double d2 = nu.dot(R_inv_ * nu);
        if (d2 < gate_d2_) candidates_.push_back({d2, static_cast<int>(j), static_cast<int>(i)});
      }
    }
    std::sort(candidates_.begin(), candidates_.end(),
              [](const Candidate& a, const Candidate& b) { return a.d2 < b.d2; });
    detection_used_.assign(scan.detections.size(), false);
    landmark_detected_.assign(map.size(), false);
    for (const Candidate& c : candidates_) {
      if (detection_used_[c.detection] || landmark_detected_[c.landmark]) continue;
      detection_used_[c.detection] = true;
      landmark_detected_[c.landmark] = true;
    }
    for (size_t i = 0; i < map.size(); ++i) {
      const int b = expected_bin_[i];
      if (b < 0) continue;
      ++s->expected[i][b];
      if (landmark_detected_[i]) ++s->detected[i][b];
    }
  }

  // The gate's area in measurement space (m·rad): π γ √det R for the χ²₂ quantile γ.
  double GateArea() const { return std::numbers::pi * gate_d2_ / std::sqrt(R_inv_.determinant()); }

 private:
  models::RangeBearingModel sensor_;
  LandmarkPersistenceOptions options_;
  int bins_;
  double bin_m_;
  double gate_d2_;
  Eigen::Matrix2d R_inv_;
  std::vector<Candidate> candidates_;
  std::vector<int> expected_bin_;
  std::vector<bool> detection_used_, landmark_detected_;
};

// P(K ≥ k) for K ~ Poisson(μ): P(χ²_{2k} ≤ 2μ).
double PoissonUpperTail(int k, double mu) { return k <= 0 ? 1.0 : models::ChiSquareCdf(2.0 * mu, 2.0 * k); }

// Which landmarks the scans detect more often than chance pairings would, with λ the
// density of the detections no confirmed landmark explains, in turn.
void TestAgainstChance(long detections, double measurement_area, double gate_area,
                       const LandmarkPersistenceOptions& options, LandmarkPersistence* out) {
  const size_t n = out->expected.size();
  out->confirmed.assign(n, true);
  out->chance_expected.assign(n, 0.0);
  out->p_value.assign(n, 0.0);
  for (int round = 1; round <= options.max_iterations; ++round) {
    out->iterations = round;
    long explained = 0;
    for (size_t i = 0; i < n; ++i) explained += out->confirmed[i] ? out->detected[i] : 0;
    out->chance_pairing_density = static_cast<double>(std::max(1L, detections - explained)) / measurement_area;
    out->chance_pairing_probability = -std::expm1(-out->chance_pairing_density * gate_area);
    bool changed = false;
    for (size_t i = 0; i < n; ++i) {
      out->chance_expected[i] = out->chance_pairing_probability * out->expected[i];
      out->p_value[i] = out->expected[i] == 0 ? 0.0 : PoissonUpperTail(out->detected[i], out->chance_expected[i]);
      const bool confirmed = out->p_value[i] < 1.0 - options.confirm_probability;
      changed = changed || confirmed != out->confirmed[i];
      out->confirmed[i] = confirmed;
    }
    if (!changed) break;
  }
}

// P_D by range over the confirmed landmarks' sightings.
std::vector<DetectionRate> DetectionCurve(const Sightings& s, const std::vector<bool>& confirmed, int bins,
                                          double bin_m) {
  std::vector<DetectionRate> out(bins);
  for (int b = 0; b < bins; ++b) {
    DetectionRate& r = out[b];
    r.range_min_m = b * bin_m;
    r.range_max_m = (b + 1) * bin_m;
    for (size_t i = 0; i < confirmed.size(); ++i) {
      if (!confirmed[i]) continue;
      r.expected += s.expected[i][b];
      r.detected += s.detected[i][b];
    }
    r.probability = r.expected > 0 ? static_cast<double>(r.detected) / static_cast<double>(r.expected) : NAN;
  }
  return out;
}

}  // namespace

LandmarkPersistence AssessLandmarkPersistence(const std::vector<LandmarkEstimate>& map, const Trajectory& trajectory,
                                              const std::vector<Scan>& scans, const models::RangeBearingConfig& sensor,
                                              const LandmarkPersistenceOptions& options) {
  const int bins = options.range_bins;
  Sightings s;
  s.expected.assign(map.size(), std::vector<int>(bins, 0));
  s.detected.assign(map.size(), std::vector<int>(bins, 0));
  LandmarkPersistence out;
  ScanCounter counter(sensor, options, bins);
  long detections = 0;
  for (const Scan& scan : scans) {
    const PoseEstimate* x = PoseAt(trajectory, scan.t);
    if (x == nullptr) continue;
    ++out.scans_used;
    detections += static_cast<long>(scan.detections.size());
    counter.Count(map, x->pose, scan, &s);
  }
  out.expected.assign(map.size(), 0);
  out.detected.assign(map.size(), 0);
  for (size_t i = 0; i < map.size(); ++i) {
    for (int b = 0; b < bins; ++b) {
      out.expected[i] += s.expected[i][b];
      out.detected[i] += s.detected[i][b];
    }
  }
  // The measurement space the scans cover: range × field of view, per scan.
  const double scan_area = (sensor.max_range_m - sensor.min_range_m) * (sensor.fov_max_rad - sensor.fov_min_rad);
  TestAgainstChance(detections, scan_area * static_cast<double>(std::max(1L, out.scans_used)), counter.GateArea(),
                    options, &out);
  for (bool c : out.confirmed) out.num_confirmed += c ? 1 : 0;
  out.detection_probability = DetectionCurve(s, out.confirmed, bins, sensor.max_range_m / bins);
  return out;
}

}  // namespace subslam::backend
