// Statistical tests of the RBPF local maps against ground truth (fixed seeds).
//
// Each local map's NEES is a χ² draw with its own dof when the map is consistent, and
// maps are (nearly) independent, so the number of maps inside their two-sided 95%
// bounds is Binomial(n, 0.95). A test fails when the count is below that binomial's
// 0.1% quantile — a bound from the distribution, not a tuned constant.
#include <gtest/gtest.h>

#include <boost/math/distributions/binomial.hpp>
#include <set>

#include "subslam/io/submaps_jsonl.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/sim/simulator.h"

namespace subslam::pipeline {
namespace {

int BinomialLowerBound(int n, double p = 0.95, double alpha = 0.001) {
  return static_cast<int>(boost::math::quantile(boost::math::binomial(n, p), alpha));
}

struct Totals {
  int maps = 0, inside = 0, pose_inside = 0, landmarks = 0, landmarks_inside = 0;
  int false_alarms = 0;
  double fraction_steps_in_bounds = 0.0;
};

Totals RunLocalMaps(const std::string& scenario, const std::vector<uint64_t>& seeds, double duration_s,
                    const RunOptions& options, std::optional<double> alpha = std::nullopt,
                    std::optional<double> beta = std::nullopt) {
  Totals t;
  for (uint64_t seed : seeds) {
    sim::ScenarioOptions o;
    o.seed = seed;
    o.duration_s = duration_s;
    o.detection_probability = alpha;
    o.false_alarm_probability = beta;
    absl::StatusOr<io::Dataset> d = sim::SimulateScenario(scenario, o);
    EXPECT_TRUE(d.ok()) << d.status();
    if (!d.ok()) return t;
    absl::StatusOr<RunResult> r = RunPipeline(*std::move(d), options);
    EXPECT_TRUE(r.ok()) << r.status();
    if (!r.ok() || !r->local_map_summary) return t;
    const LocalMapSummary& s = *r->local_map_summary;
    t.maps += s.evaluated;
    t.inside += s.inside;
    t.pose_inside += s.pose_inside;
    t.landmarks += s.landmarks;
    t.landmarks_inside += s.landmarks_inside;
    t.false_alarms += s.false_alarms;
    t.fraction_steps_in_bounds = r->errors->fraction_nees_in_bounds;
  }
  return t;
}

RunOptions Rbpf(int particles) {
  RunOptions options;
  options.frontend = Frontend::kRbpf;
  options.fastslam.num_particles = particles;
  return options;
}

// hybrid-120m (accurate sensor, large motion noise, 10 Hz): with 300 particles and the
// default policy (10 s, or earlier when particle diversity collapses) the joint NEES
// of [end pose, features] is consistent.
TEST(RbpfLocalMaps, Hybrid120mJointNeesIsConsistent) {
  const Totals t = RunLocalMaps("hybrid-120m", {1, 2}, 150.0, Rbpf(300));
  ASSERT_GT(t.maps, 50);
  EXPECT_GE(t.inside, BinomialLowerBound(t.maps)) << t.inside << " / " << t.maps;
  EXPECT_GE(t.landmarks_inside, BinomialLowerBound(t.landmarks)) << t.landmarks_inside << " / " << t.landmarks;
}

// ...and with the default 100 particles, over twelve seeds (1,241 maps), once the moment
// matching accounts for the particles' shared ancestry (FastSlamOptions::
// correct_shared_ancestry: the spread under-states the posterior's, and the mean has a
// Monte Carlo error of its own). Margins (bench/RESULTS.md): joint
// 1,161 inside against the bound's 1,154, end pose about 1,159; without the correction
// 1,149 and about 1,144 (both checks fail); with the spread divided by 1 − R alone
// about 1,154 and 1,150 (the end-pose check fails). Deterministic, but near the bound:
// a change to the filter's draws can move it by a few maps either way.
TEST(RbpfLocalMaps, Hybrid120mJointNeesIsConsistentAtTheDefaultParticleCount) {
  const Totals t = RunLocalMaps("hybrid-120m", {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}, 150.0, Rbpf(100));
  ASSERT_GT(t.maps, 1000);
  EXPECT_GE(t.inside, BinomialLowerBound(t.maps)) << t.inside << " / " << t.maps;
  EXPECT_GE(t.pose_inside, BinomialLowerBound(t.maps)) << t.pose_inside << " / " << t.maps;
}

// A detection between the association gate and the new-landmark gate updates nothing,
// but a particle's weight must still score it by its landmark's likelihood: weighted
// by the new-landmark density instead, particles whose pose puts their landmarks just
// outside the gate were down-weighted, which cut off the tails of the pose posterior
// (here: end pose inside its bounds in 79% of the maps). With the likelihood the end
// pose stays consistent at a tight gate too.
TEST(RbpfLocalMaps, Hybrid120mTightGateKeepsTheEndPoseConsistent) {
  RunOptions options = Rbpf(300);
  options.fastslam.landmarks.gate_probability = 0.9;
  const Totals t = RunLocalMaps("hybrid-120m", {1, 2}, 150.0, options);
  ASSERT_GT(t.maps, 50);
  EXPECT_GE(t.pose_inside, BinomialLowerBound(t.maps)) << t.pose_inside << " / " << t.maps;
}

// The EKF local mapper under the same policy: its local maps are consistent too.
TEST(EkfLocalMaps, Hybrid120mJointNeesIsConsistent) {
  RunOptions options;
  options.frontend = Frontend::kEkfLocal;
  const Totals t = RunLocalMaps("hybrid-120m", {1, 2}, 150.0, options);
  ASSERT_GT(t.maps, 20);
  EXPECT_GE(t.inside, BinomialLowerBound(t.maps)) << t.inside << " / " << t.maps;
}

// The run writes its local maps to submaps.jsonl; they read back as written, consecutive
// maps share features (the next map re-observes the boundary), and each map starts
// where the previous one ended.
TEST(RbpfLocalMaps, WritesSubmapsJsonlAndConsecutiveMapsShareFeatures) {
  sim::ScenarioOptions o;
  o.seed = 7;
  o.duration_s = 60;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("hybrid-120m", o);
  ASSERT_TRUE(d.ok());
  RunOptions options = Rbpf(100);
  options.out_dir = ::testing::TempDir() + "/subslam_rbpf_run";
  absl::StatusOr<RunResult> r = RunPipeline(*std::move(d), options);
  ASSERT_TRUE(r.ok()) << r.status();
  absl::StatusOr<std::vector<LocalSubmap>> back = io::ReadSubmapsJsonl(options.out_dir + "/submaps.jsonl");
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->size(), r->local_maps.size());
  ASSERT_GT(back->size(), 4u);
  int sharing = 0;
  for (size_t k = 0; k < back->size(); ++k) {
    EXPECT_EQ((*back)[k].mean, r->local_maps[k].mean);
    if (k == 0) continue;
    EXPECT_EQ((*back)[k].t_start, (*back)[k - 1].t_end);
    std::set<int> previous;
    for (const LocalSubmapLandmark& l : (*back)[k - 1].landmarks) {
      if (l.truth_id && *l.truth_id >= 0) previous.insert(*l.truth_id);
    }
    bool shares = false;
    for (const LocalSubmapLandmark& l : (*back)[k].landmarks) {
      shares = shares || (l.truth_id && previous.contains(*l.truth_id));
    }
    sharing += shares ? 1 : 0;
  }
  EXPECT_GE(sharing, static_cast<int>(back->size()) - 2);
}

// combined-2km (noisy sensor: σ 0.5 m / 5°, trees a few metres apart): with unknown
// association the local maps are not consistent at the 95% level (bench/RESULTS.md:
// 84-87% of the maps inside their bounds — features mixing two true landmarks), so only
// clutter rejection is asserted here...
TEST(RbpfLocalMaps, Combined2kmWithClutterExportsNoFalseAlarm) {
  const Totals t = RunLocalMaps("combined-2km", {1}, 300.0, Rbpf(100), 0.7, 0.02);
  ASSERT_GT(t.maps, 30);
  ASSERT_GT(t.landmarks, 100);
  EXPECT_EQ(t.false_alarms, 0);
}

// ...and with the true association (Combined SLAM §7's setting) the same 100-particle
// local maps are consistent: joint and feature NEES against the binomial bound.
TEST(RbpfLocalMaps, Combined2kmWithKnownAssociationIsConsistent) {
  RunOptions options = Rbpf(100);
  options.fastslam.landmarks.known_association = true;
  const Totals t = RunLocalMaps("combined-2km", {1, 2}, 2000.0, options);
  ASSERT_GT(t.maps, 200);
  EXPECT_GE(t.inside, BinomialLowerBound(t.maps)) << t.inside << " / " << t.maps;
  EXPECT_GE(t.landmarks_inside, BinomialLowerBound(t.landmarks)) << t.landmarks_inside << " / " << t.landmarks;
}

// With clutter (α = 0.7, β = 0.02) no false alarm is exported into a local map.
TEST(RbpfLocalMaps, FalseAlarmsAreNotExported) {
  const Totals t = RunLocalMaps("hybrid-120m", {3}, 150.0, Rbpf(100), 0.7, 0.02);
  ASSERT_GT(t.maps, 10);
  EXPECT_EQ(t.false_alarms, 0);
}

// Single-map FastSLAM 2.0 over a long run becomes over-confident (HybridSLAM §5): its
// pose NEES leaves the 95% bounds for most of the run.
TEST(FastSlamSingleMap, BecomesOverconfidentOverALongRun) {
  RunOptions options;
  options.frontend = Frontend::kFastSlam;
  sim::ScenarioOptions o;
  o.seed = 1;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("hybrid-120m", o);
  ASSERT_TRUE(d.ok());
  absl::StatusOr<RunResult> r = RunPipeline(*std::move(d), options);
  ASSERT_TRUE(r.ok()) << r.status();
  EXPECT_LT(r->errors->fraction_nees_in_bounds, 0.5);
  EXPECT_LT(r->errors->rms_position_m, 2.0);  // yet it still maps and localises
  EXPECT_EQ(r->map_errors->spurious, 0);
}

}  // namespace
}  // namespace subslam::pipeline
