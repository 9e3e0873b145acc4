#include "subslam/io/input_screening.h"

#include <gtest/gtest.h>

namespace subslam::io {
namespace {

// Controls every 0.1 s with speed 1 m/s and ω 0.1 rad/s, σ 0.1 m/s and 0.01 rad/s.
Dataset Steady(int n) {
  Dataset d;
  d.motion.noise.sigma_u0 = 0.1;
  d.motion.noise.sigma_u1 = 0.01;
  for (int k = 0; k < n; ++k) d.controls.push_back({0.1 * k, {1.0, 0.1}});
  d.sensor.range_bearing.min_range_m = 1.0;
  d.sensor.range_bearing.max_range_m = 30.0;
  return d;
}

TEST(ScreenInputs, ReplacesAnIsolatedControlSpikeByItsNeighboursMedian) {
  Dataset d = Steady(10);
  d.controls[4].u = {1.0 + 11 * 0.1, 0.1};  // 11 σ above both neighbours
  d.controls[6].u = {1.0 + 9 * 0.1, 0.1};   // 9 σ: inside the bound
  const InputScreening s = ScreenInputs(InputScreeningOptions{}, &d);
  EXPECT_EQ(s.control_spikes, 1);
  EXPECT_DOUBLE_EQ(d.controls[4].u[0], 1.0);
  EXPECT_DOUBLE_EQ(d.controls[6].u[0], 1.9);
  // Counting only.
  Dataset e = Steady(10);
  e.controls[4].u[1] = 0.1 + 0.5;  // 50 σ in ω
  InputScreeningOptions count_only;
  count_only.replace_control_spikes = false;
  EXPECT_EQ(ScreenInputs(count_only, &e).control_spikes, 1);
  EXPECT_DOUBLE_EQ(e.controls[4].u[1], 0.6);
}

TEST(ScreenInputs, LeavesAStepInTheControlAlone) {
  Dataset d = Steady(10);
  for (int k = 5; k < 10; ++k) d.controls[k].u[1] = 0.6;  // a turn begins: 50 σ step
  EXPECT_EQ(ScreenInputs(InputScreeningOptions{}, &d).control_spikes, 0);
  EXPECT_DOUBLE_EQ(d.controls[5].u[1], 0.6);
}

TEST(ScreenInputs, CountsTimeGapsRepeatedTimesAndDetectionsOutOfRange) {
  Dataset d = Steady(50);
  for (int k = 30; k < 50; ++k) d.controls[k].t += 5.0;  // one 5.1 s interval among 0.1 s ones
  d.duplicate_control_times = 2;                         // as the reader counted them
  d.scans.push_back({0.05, {Detection{.range_m = 0.5}, Detection{.range_m = 5.0}, Detection{.range_m = 31.0}}});
  const InputScreening s = ScreenInputs(InputScreeningOptions{}, &d);
  EXPECT_EQ(s.time_gaps, 1);
  EXPECT_NEAR(s.longest_gap_s, 5.1, 1e-9);
  EXPECT_NEAR(s.median_interval_s, 0.1, 1e-9);
  EXPECT_EQ(s.duplicate_control_times, 2);
  EXPECT_EQ(s.detections_out_of_range, 2);
}

TEST(InputScreeningOptions, RejectsNonsense) {
  InputScreeningOptions o;
  o.control_spike_sigmas = 0.0;
  EXPECT_FALSE(o.Validate().ok());
  o = InputScreeningOptions{};
  o.time_gap_factor = 1.0;
  EXPECT_FALSE(o.Validate().ok());
  EXPECT_TRUE(InputScreeningOptions{}.Validate().ok());
}

}  // namespace
}  // namespace subslam::io
