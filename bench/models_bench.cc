// Micro-benchmarks of the geometry, the models and one EKF-SLAM update.
//   build/bench/models_bench [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cstdlib>

#include "subslam/core/pose2.h"
#include "subslam/frontend/ekf_slam.h"
#include "subslam/io/steps.h"
#include "subslam/models/ackermann_model.h"
#include "subslam/models/range_bearing_model.h"
#include "subslam/models/unicycle_model.h"
#include "subslam/sim/simulator.h"

namespace subslam {
namespace {

void BM_ComposeWithJacobians(benchmark::State& state) {
  Pose2 a(1, 2, 0.3), b(0.5, -0.2, 0.1);
  Eigen::Matrix3d Ja, Jb;
  for (auto _ : state) {
    a = Compose(a, b, &Ja, &Jb);
    benchmark::DoNotOptimize(a);
  }
}
BENCHMARK(BM_ComposeWithJacobians);

// One prediction with both Jacobians per iteration.
void PredictLoop(benchmark::State& state, const models::MotionModel& model) {
  Pose2 x;
  Eigen::Matrix3d F;
  Matrix32d G;
  for (auto _ : state) {
    x = model.Predict(x, Eigen::Vector2d(2.0, 0.1), 0.025, &F, &G);
    benchmark::DoNotOptimize(x);
  }
}

void BM_AckermannPredict(benchmark::State& state) {
  PredictLoop(state, models::AckermannModel({2.83, 0.76, 3.78, 0.5}, {0.5, 0.05, 0, 0}));
}
BENCHMARK(BM_AckermannPredict);

void BM_UnicyclePredict(benchmark::State& state) { PredictLoop(state, models::UnicycleModel({0.1, 0.01, 0, 0})); }
BENCHMARK(BM_UnicyclePredict);

void BM_RangeBearingObserve(benchmark::State& state) {
  const models::RangeBearingModel model(models::RangeBearingConfig{});
  const Pose2 x(1, 2, 0.3);
  Matrix23d Hp;
  Eigen::Matrix2d Hl;
  Eigen::Vector2d l(10, 5);
  for (auto _ : state) {
    benchmark::DoNotOptimize(model.Observe(x, l, &Hp, &Hl));
    l.x() += 1e-9;
  }
}
BENCHMARK(BM_RangeBearingObserve);

// A whole EKF-SLAM run on a `random` world of state.range(0) landmarks; time per step.
void BM_EkfSlamRandomWorld(benchmark::State& state) {
  sim::ScenarioOptions o;
  o.seed = 1;
  o.random_landmarks = static_cast<int>(state.range(0));
  o.random_world_size_m = 20.0 * std::sqrt(static_cast<double>(state.range(0)));
  o.random_path_length_m = 400.0;
  const io::Dataset d = *sim::SimulateScenario("random", o);
  const std::vector<io::Step> steps = io::BuildSteps(d);
  long landmarks = 0;
  for (auto _ : state) {
    frontend::EkfSlam ekf(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, {});
    for (const io::Step& s : steps) {
      ekf.Predict(s.control, s.dt);
      if (s.scan_index >= 0 && !ekf.Update(d.scans[s.scan_index]).ok()) std::abort();
    }
    landmarks = ekf.num_landmarks();
  }
  state.counters["landmarks"] = static_cast<double>(landmarks);
  state.counters["steps"] = static_cast<double>(steps.size());
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(steps.size()));
}
BENCHMARK(BM_EkfSlamRandomWorld)->Arg(50)->Arg(200)->Arg(800)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace subslam

BENCHMARK_MAIN();
