// Seeded simulator: drives the true vehicle with its guidance law, records noisy
// controls, true poses and range-bearing detections with missed detections (α) and
// false alarms (β), and returns it all as an io::Dataset.
//
// Timing: control u_k is commanded at t_k = k / control_rate and held until t_{k+1};
// it is what the odometry reports. The vehicle actually moves with u_k + w_k,
// w_k ~ N(0, M(u_k)) (models::ControlNoise), so the true pose at t_{k+1} is
// f(x_k, u_k + w_k, dt) — the estimator's noise model, evaluated at the reported
// control, is exactly the truth's (HybridSLAM §5 states the noise in terms of the
// commanded velocities). A scan is taken
// at t_{k+1} whenever (k + 1) is a multiple of observation_every. Each visible true
// landmark (inside range and field of view) is detected with probability α, with
// Gaussian range-bearing noise; each visible landmark also triggers, with probability
// β, a false alarm uniform in range [min_range, max_range] and bearing over the field
// of view (HybridSLAM §5). Detections in a scan are shuffled; each carries its true
// landmark id (−1 for a false alarm) for evaluation only.
//
// Deterministic: the same config and seed give the same data set, bit for bit.
#ifndef SUBSLAM_SIM_SIMULATOR_H_
#define SUBSLAM_SIM_SIMULATOR_H_

#include <cstdint>

#include "absl/status/statusor.h"
#include "subslam/io/dataset.h"
#include "subslam/sim/scenario.h"

namespace subslam::sim {

absl::StatusOr<io::Dataset> Simulate(const ScenarioConfig& config, uint64_t seed);

// MakeScenario + Simulate.
absl::StatusOr<io::Dataset> SimulateScenario(const std::string& name, const ScenarioOptions& options);

}  // namespace subslam::sim

#endif  // SUBSLAM_SIM_SIMULATOR_H_
