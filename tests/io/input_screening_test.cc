#include "subslam/io/input_screening.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "subslam/io/control_screen.h"

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

// A caller streaming its controls: each record comes out kSpikeWindow pushes later, a spike
// already replaced (it needs the records after it), and Flush() gives the rest unjudged.
TEST(ControlScreen, StreamsTheRecordsWithAFixedLagAndReplacesASpike) {
  Dataset d = Steady(10);
  d.controls[4].u[0] = 1.0 + 11 * 0.1;
  ControlScreen screen(d.motion.noise, InputScreeningOptions{});
  const int w = InputScreeningOptions::kSpikeWindow;
  std::vector<ControlRecord> out;
  for (int k = 0; k < 10; ++k) {
    const std::optional<ControlRecord> r = screen.Push(d.controls[k]);
    ASSERT_EQ(r.has_value(), k >= w) << k;
    if (!r) continue;
    EXPECT_EQ(r->t, d.controls[k - w].t);
    out.push_back(*r);
  }
  EXPECT_EQ(screen.control_spikes(), 1);
  EXPECT_DOUBLE_EQ(out[4].u[0], 1.0);
  const std::vector<ControlRecord> rest = screen.Flush();
  ASSERT_EQ(rest.size(), static_cast<size_t>(w));
  EXPECT_EQ(rest.front().t, d.controls[10 - w].t);
  // Fewer records than a window: nothing judged, all back in order.
  for (int k = 0; k < 2 * w; ++k) EXPECT_EQ(screen.Push(d.controls[k]).has_value(), k >= w);
  const std::vector<ControlRecord> short_rest = screen.Flush();
  ASSERT_EQ(short_rest.size(), static_cast<size_t>(w));
  EXPECT_EQ(short_rest.front().t, d.controls[w].t);
  EXPECT_TRUE(screen.Flush().empty());
}

// The rule written out directly (median of the 2w neighbours as read, the larger of the
// noise σ at it and 1.4826 × their median absolute deviation) against the screen, on a
// noisy stream with spikes and steps: the same records to the bit.
TEST(ControlScreen, AppliesTheSpikeRuleAsWrittenToEveryInnerRecord) {
  Dataset d = Steady(400);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal;
  for (int k = 0; k < 400; ++k) {
    d.controls[k].u += Eigen::Vector2d(0.1 * normal(rng), 0.01 * normal(rng));
    if (k >= 200) d.controls[k].u[1] += 0.5;                               // a step
    if (k % 37 == 5) d.controls[k].u[k % 2] += (k % 3 == 0 ? 2.0 : -0.3);  // spikes
  }
  const int w = InputScreeningOptions::kSpikeWindow;
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  };
  std::vector<ControlRecord> expected = d.controls;
  int spikes = 0;
  for (int k = w; k + w < 400; ++k) {
    bool spike = false;
    for (int c = 0; c < 2; ++c) {
      std::vector<double> around, deviations;
      for (int i = k - w; i <= k + w; ++i) {
        if (i != k) around.push_back(d.controls[i].u[c]);
      }
      const double m = median(around);
      for (double a : around) deviations.push_back(std::abs(a - m));
      const double sigma = c == 0 ? d.motion.noise.sigma_u0 : d.motion.noise.sigma_u1;
      if (std::abs(d.controls[k].u[c] - m) > 10.0 * std::max(sigma, 1.4826 * median(deviations))) {
        spike = true;
        expected[k].u[c] = m;
      }
    }
    spikes += spike ? 1 : 0;
  }
  ASSERT_GT(spikes, 3);
  const InputScreening s = ScreenInputs(InputScreeningOptions{}, &d);
  EXPECT_EQ(s.control_spikes, spikes);
  ASSERT_EQ(d.controls.size(), expected.size());
  for (size_t k = 0; k < expected.size(); ++k) {
    EXPECT_EQ(d.controls[k].t, expected[k].t) << k;
    EXPECT_EQ(d.controls[k].u, expected[k].u) << k;
  }
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
