// Micro-benchmark of the RBPF (FastSLAM 2.0) update: time per step (one prediction and
// one scan) against the particle count and the number of landmarks in the local map.
//   build/bench/rbpf_bench [--benchmark_filter=...] [--benchmark_out=FILE --benchmark_out_format=json]
//
// World: L landmarks on a ring of radius 15 m; the vehicle drives a circle of radius
// 3 m at its centre (1 m/s) with a 20 m, 90° range-bearing sensor (σ 0.1 m / 1°), so the
// map holds all L landmarks and each scan sees about L / 4 of them. Before timing, 100
// scans build the map; timed steps continue the same run (seeded noise).
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <random>

#include "subslam/frontend/fastslam.h"
#include "subslam/models/range_bearing_model.h"
#include "subslam/models/unicycle_model.h"

namespace subslam {
namespace {

class RingWorld {
 public:
  explicit RingWorld(int landmarks) : rng_(7) {
    for (int i = 0; i < landmarks; ++i) {
      const double a = 2.0 * kPi * i / landmarks;
      ring_.push_back(15.0 * Eigen::Vector2d(std::cos(a), std::sin(a)));
    }
    sensor_.sigma_range_m = 0.1;
    sensor_.sigma_bearing_rad = DegToRad(1.0);
    sensor_.max_range_m = 20.0;
    sensor_.fov_min_rad = -kPi / 4;
    sensor_.fov_max_rad = kPi / 4;
  }
  const models::RangeBearingConfig& sensor() const { return sensor_; }
  models::ControlNoise noise() const { return {0.05, DegToRad(2.0), 0.0, 0.0}; }
  Eigen::Vector2d control() const { return {1.0, 1.0 / 3.0}; }
  static constexpr double kDt = 0.1;

  // Advances the truth one step and returns its scan.
  Scan Step() {
    truth_ = Compose(truth_, Pose2(control()[0] * kDt, 0.0, control()[1] * kDt));
    t_ += kDt;
    const models::RangeBearingModel model(sensor_);
    std::normal_distribution<double> nr(0.0, sensor_.sigma_range_m), nb(0.0, sensor_.sigma_bearing_rad);
    Scan scan;
    scan.t = t_;
    for (size_t i = 0; i < ring_.size(); ++i) {
      const Eigen::Vector2d z = model.Observe(truth_, ring_[i]);
      if (!model.IsVisible(z)) continue;
      scan.detections.push_back({z[0] + nr(rng_), WrapAngle(z[1] + nb(rng_)), NAN, static_cast<int>(i)});
    }
    return scan;
  }
  Pose2 start() const { return Pose2(0.0, -3.0, 0.0); }

 private:
  std::vector<Eigen::Vector2d> ring_;
  models::RangeBearingConfig sensor_;
  std::mt19937_64 rng_;
  Pose2 truth_{0.0, -3.0, 0.0};
  double t_ = 0.0;
};

void BM_RbpfStep(benchmark::State& state) {
  const int particles = static_cast<int>(state.range(0));
  const int landmarks = static_cast<int>(state.range(1));
  RingWorld world(landmarks);
  frontend::FastSlamOptions options;
  options.num_particles = particles;
  frontend::FastSlam filter(std::make_unique<models::UnicycleModel>(world.noise()), world.sensor(), world.start(),
                            options);
  for (int k = 0; k < 100; ++k) {
    filter.Predict(world.control(), RingWorld::kDt);
    if (!filter.Update(world.Step()).ok()) std::abort();
  }
  long detections = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const Scan scan = world.Step();
    detections += static_cast<long>(scan.detections.size());
    state.ResumeTiming();
    filter.Predict(world.control(), RingWorld::kDt);
    if (!filter.Update(scan).ok()) std::abort();
    benchmark::DoNotOptimize(filter.pose());
  }
  state.counters["detections_per_scan"] = benchmark::Counter(static_cast<double>(detections) / state.iterations());
  state.counters["landmarks_per_particle"] = filter.Counters().at("mean_landmarks_per_particle");
}
BENCHMARK(BM_RbpfStep)
    ->ArgNames({"particles", "landmarks"})
    ->ArgsProduct({{100, 500, 5000}, {10, 30, 100}})
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace subslam

BENCHMARK_MAIN();
