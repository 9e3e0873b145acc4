// The known-association study option of the single-map filters (FastSlam, EkfSlam):
// detections are paired by their true ids, so every true landmark is one feature and a
// false alarm is none.
#include <gtest/gtest.h>

#include <map>
#include <set>

#include "subslam/core/check.h"
#include "subslam/frontend/ekf_slam.h"
#include "subslam/frontend/fastslam.h"
#include "subslam/io/steps.h"
#include "subslam/sim/simulator.h"

namespace subslam::frontend {
namespace {

// combined-2km (σ 0.5 m / 5°, trees a few metres apart: unknown association mixes
// landmarks there) with clutter and missed detections.
io::Dataset ClutteredCombined(double duration_s) {
  sim::ScenarioOptions o;
  o.seed = 3;
  o.duration_s = duration_s;
  o.detection_probability = 0.7;
  o.false_alarm_probability = 0.05;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("combined-2km", o);
  SUBSLAM_CHECK(d.ok()) << d.status().message();
  return *std::move(d);
}

// Runs `filter` over `d` and checks, scan by scan, that the feature each detection is
// given is a one-to-one function of its true id and that false alarms get none. Returns
// the true id of every feature seen, and counts the false alarms in range.
template <typename Filter>
std::map<int, int> CheckFeaturesFollowTrueIds(Filter* filter, const io::Dataset& d, int* false_alarms) {
  std::map<int, int> feature_of_truth, truth_of_feature;
  *false_alarms = 0;
  for (const io::Step& step : io::BuildSteps(d)) {
    filter->Predict(step.control, step.dt);
    if (step.scan_index < 0) continue;
    const Scan& scan = d.scans[step.scan_index];
    EXPECT_TRUE(filter->Update(scan).ok());
    const std::vector<int>& features = filter->last_scan_features();
    EXPECT_EQ(features.size(), scan.detections.size());
    for (size_t k = 0; k < features.size(); ++k) {
      const int truth = scan.detections[k].truth_id;
      const Detection& z = scan.detections[k];
      const bool in_range =
          z.range_m >= d.sensor.range_bearing.min_range_m && z.range_m <= d.sensor.range_bearing.max_range_m;
      if (truth < 0) {
        *false_alarms += in_range ? 1 : 0;
        EXPECT_EQ(features[k], -1) << "a false alarm became feature " << features[k];
        continue;
      }
      if (features[k] < 0) continue;  // out of the sensor's valid range
      const auto [f, new_truth] = feature_of_truth.emplace(truth, features[k]);
      EXPECT_EQ(f->second, features[k]) << "true landmark " << truth << " split";
      const auto [t, new_feature] = truth_of_feature.emplace(features[k], truth);
      EXPECT_EQ(t->second, truth) << "feature " << features[k] << " mixes landmarks";
    }
  }
  EXPECT_GT(*false_alarms, 50);
  EXPECT_GT(feature_of_truth.size(), 50u);
  return truth_of_feature;
}

void ExpectExportCarriesTrueIds(const MomentMatchedGaussian& g, const std::map<int, int>& truth_of_feature) {
  ASSERT_EQ(g.truth_id.size(), g.features.size());
  ASSERT_GT(g.features.size(), 20u);
  for (size_t k = 0; k < g.features.size(); ++k) {
    const auto it = truth_of_feature.find(g.features[k]);
    ASSERT_NE(it, truth_of_feature.end()) << g.features[k];
    EXPECT_EQ(g.truth_id[k], it->second);
  }
}

TEST(KnownAssociation, FastSlamFeaturesFollowTheTrueIds) {
  const io::Dataset d = ClutteredCombined(200.0);
  FastSlamOptions options;
  options.num_particles = 30;
  options.num_threads = 2;  // the per-particle pairing runs on worker threads too
  options.landmarks.known_association = true;
  FastSlam filter(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  int false_alarms = 0;
  const std::map<int, int> truth_of_feature = CheckFeaturesFollowTrueIds(&filter, d, &false_alarms);
  ExpectExportCarriesTrueIds(filter.MomentMatched(), truth_of_feature);
  // Every particle ignores exactly the false alarms: nothing is left between gates.
  EXPECT_EQ(filter.counters().ignored, static_cast<long>(false_alarms) * options.num_particles);
}

TEST(KnownAssociation, EkfSlamFeaturesFollowTheTrueIds) {
  const io::Dataset d = ClutteredCombined(200.0);
  EkfSlamOptions options;
  options.landmarks.known_association = true;
  EkfSlam filter(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  int false_alarms = 0;
  const std::map<int, int> truth_of_feature = CheckFeaturesFollowTrueIds(&filter, d, &false_alarms);
  ExpectExportCarriesTrueIds(filter.Export(0.0), truth_of_feature);
  EXPECT_EQ(filter.counters().known_ignored, false_alarms);
  EXPECT_EQ(filter.counters().ambiguous, 0);
}

// A sensor that detects far less often than the filters' existence model assumes (the
// simulation's α 0.3 against the model's 0.9): with the true ids a miss does not lower a
// landmark's existence, so every landmark detected twice stays in the map.
TEST(KnownAssociation, MissedDetectionsKeepEveryLandmarkInTheMap) {
  sim::ScenarioOptions o;
  o.seed = 5;
  o.duration_s = 150.0;
  o.detection_probability = 0.3;
  absl::StatusOr<io::Dataset> d = sim::SimulateScenario("combined-2km", o);
  ASSERT_TRUE(d.ok()) << d.status().message();
  std::map<int, int> detections;
  for (const Scan& scan : d->scans) {
    for (const Detection& z : scan.detections) {
      if (z.truth_id >= 0 && z.range_m >= d->sensor.range_bearing.min_range_m &&
          z.range_m <= d->sensor.range_bearing.max_range_m) {
        ++detections[z.truth_id];
      }
    }
  }
  std::set<int> seen;  // detected at least twice: confirmed
  for (const auto& [id, count] : detections) {
    if (count >= 2) seen.insert(id);
  }
  ASSERT_GT(seen.size(), 30u);
  FastSlamOptions fastslam;
  fastslam.num_particles = 20;
  fastslam.num_threads = 1;
  fastslam.landmarks.known_association = true;
  FastSlam particles(d->motion.MakeModel(), d->sensor.range_bearing, d->initial_pose, fastslam);
  EkfSlamOptions ekf;
  ekf.landmarks.known_association = true;
  EkfSlam single(d->motion.MakeModel(), d->sensor.range_bearing, d->initial_pose, ekf);
  for (const io::Step& step : io::BuildSteps(*d)) {
    particles.Predict(step.control, step.dt);
    single.Predict(step.control, step.dt);
    if (step.scan_index < 0) continue;
    EXPECT_TRUE(particles.Update(d->scans[step.scan_index]).ok());
    EXPECT_TRUE(single.Update(d->scans[step.scan_index]).ok());
  }
  EXPECT_EQ(particles.Map().size(), seen.size());
  EXPECT_EQ(single.Map().size(), seen.size());
  EXPECT_EQ(single.Export(0.95).features.size(), seen.size());  // a local map's export threshold
}

// Without the option the same filters never read the true ids: a run on data whose ids
// are scrambled is the same run.
TEST(KnownAssociation, UnknownAssociationNeverReadsTrueIds) {
  const io::Dataset d = ClutteredCombined(60.0);
  io::Dataset scrambled = d;
  for (Scan& scan : scrambled.scans) {
    for (Detection& det : scan.detections) det.truth_id = 1000 - det.truth_id;
  }
  FastSlamOptions options;
  options.num_particles = 20;
  FastSlam a(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  FastSlam b(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, options);
  EkfSlam c(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, EkfSlamOptions{});
  EkfSlam e(d.motion.MakeModel(), d.sensor.range_bearing, d.initial_pose, EkfSlamOptions{});
  const std::vector<io::Step> steps = io::BuildSteps(d);
  for (const io::Step& step : steps) {
    for (OnlineEstimator* f : std::initializer_list<OnlineEstimator*>{&a, &b, &c, &e}) {
      f->Predict(step.control, step.dt);
    }
    if (step.scan_index < 0) continue;
    EXPECT_TRUE(a.Update(d.scans[step.scan_index]).ok());
    EXPECT_TRUE(b.Update(scrambled.scans[step.scan_index]).ok());
    EXPECT_TRUE(c.Update(d.scans[step.scan_index]).ok());
    EXPECT_TRUE(e.Update(scrambled.scans[step.scan_index]).ok());
  }
  EXPECT_EQ(a.pose().vector(), b.pose().vector());
  EXPECT_EQ(c.pose().vector(), e.pose().vector());
  EXPECT_TRUE(a.MomentMatched().truth_id.empty());
  EXPECT_TRUE(c.Export(0.0).truth_id.empty());
}

TEST(KnownAssociation, ExcludesDataAssociationSampling) {
  FastSlamOptions options;
  options.landmarks.known_association = true;
  EXPECT_TRUE(options.Validate().ok());
  options.sample_association = true;
  EXPECT_FALSE(options.Validate().ok());
}

}  // namespace
}  // namespace subslam::frontend
