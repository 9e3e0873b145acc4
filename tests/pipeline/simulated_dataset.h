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

}  // namespace subslam::pipeline

#endif  // SUBSLAM_TESTS_PIPELINE_SIMULATED_DATASET_H_
