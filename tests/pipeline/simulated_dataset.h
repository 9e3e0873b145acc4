// A simulated scenario for the pipeline tests (fails the test if the scenario is unknown).
#ifndef SUBSLAM_TESTS_PIPELINE_SIMULATED_DATASET_H_
#define SUBSLAM_TESTS_PIPELINE_SIMULATED_DATASET_H_

#include <gtest/gtest.h>

#include <optional>
#include <string>

#include "subslam/sim/simulator.h"

namespace subslam::pipeline {

inline io::Dataset Simulate(uint64_t seed, const std::string& scenario = "hybrid-120m",
                            std::optional<double> duration_s = std::nullopt) {
  sim::ScenarioOptions o;
  o.seed = seed;
  o.duration_s = duration_s;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario(scenario, o);
  EXPECT_TRUE(d.ok()) << d.status();
  return *std::move(d);
}

// The simulated camera robot (docs/scenarios.md), 300 s, with `moving_objects` other
// robots and its odometry's true scale on both channels (nullopt: the scenario's own).
inline io::Dataset SimulateCameraRobot(uint64_t seed, std::optional<int> moving_objects = std::nullopt,
                                       std::optional<double> odometry_scale = std::nullopt) {
  sim::ScenarioOptions o;
  o.seed = seed;
  o.moving_objects = moving_objects;
  o.duration_s = 300.0;
  absl::StatusOr<sim::ScenarioConfig> config = sim::MakeScenario("camera-robot", o);
  EXPECT_TRUE(config.ok()) << config.status();
  if (odometry_scale) config->odometry_scale = Eigen::Vector2d::Constant(*odometry_scale);
  absl::StatusOr<io::Dataset> d = sim::Simulate(*config, seed);
  EXPECT_TRUE(d.ok()) << d.status();
  return *std::move(d);
}

}  // namespace subslam::pipeline

#endif  // SUBSLAM_TESTS_PIPELINE_SIMULATED_DATASET_H_
