#include "subslam/backend/landmark_persistence.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "subslam/core/check.h"
#include "subslam/sim/simulator.h"

namespace subslam::backend {
namespace {

// The camera robot's truth: its poses at the scans and its landmarks, exactly known.
struct World {
  sim::ScenarioConfig config;
  io::Dataset data;
  Trajectory trajectory;
  std::vector<LandmarkEstimate> landmarks;
};

World CameraRobot(int moving_objects) {
  sim::ScenarioOptions o;
  o.seed = 2;
  o.moving_objects = moving_objects;
  absl::StatusOr<sim::ScenarioConfig> config = sim::MakeScenario("camera-robot", o);
  SUBSLAM_CHECK(config.ok()) << config.status().message();
  absl::StatusOr<io::Dataset> d = sim::Simulate(*config, o.seed);
  SUBSLAM_CHECK(d.ok()) << d.status().message();
  World w{*config, *std::move(d), {}, {}};
  for (const io::TimedPose& p : w.data.truth_poses) w.trajectory.push_back({p.t, p.pose, Eigen::Matrix3d::Zero()});
  for (const io::TruthLandmark& l : w.data.truth_landmarks) {
    w.landmarks.push_back({l.id, l.p, Eigen::Matrix2d::Identity() * 1e-6});
  }
  return w;
}

// On the true map along the true path, every landmark is confirmed, and P_D by range
// falls as the simulator's does (0.56 to 2 m, linearly to 0 at 8.7 m): no bin's estimate
// rises above the one before by three binomial standard deviations of the two, and the
// farthest falls below the nearest by more than that.
TEST(LandmarkPersistence, TheTrueMapIsConfirmedAndItsDetectionCurveFalls) {
  const World w = CameraRobot(0);
  const LandmarkPersistence p =
      AssessLandmarkPersistence(w.landmarks, w.trajectory, w.data.scans, w.data.sensor.range_bearing, {});
  EXPECT_EQ(p.num_confirmed, static_cast<int>(w.landmarks.size()));
  const auto three_sigma = [](const DetectionRate& a, const DetectionRate& b) {
    const auto variance = [](const DetectionRate& d) {
      return d.probability * (1 - d.probability) / static_cast<double>(d.expected);
    };
    return 3 * std::sqrt(variance(a) + variance(b));
  };
  std::vector<DetectionRate> populated;
  for (const DetectionRate& r : p.detection_probability) {
    if (r.expected >= 100) populated.push_back(r);
  }
  ASSERT_GE(populated.size(), 4u);
  for (size_t b = 1; b < populated.size(); ++b) {
    EXPECT_LT(populated[b].probability, populated[b - 1].probability + three_sigma(populated[b], populated[b - 1]))
        << populated[b].range_min_m << " m";
  }
  EXPECT_LT(populated.back().probability,
            populated.front().probability - three_sigma(populated.back(), populated.front()));
}

// Places where nothing stands — the moving robots' markers leave such features — are
// not confirmed: with 20 of them added to the true map (anywhere in the room at least
// 1 m from a landmark), the four robots' detections that fall into their gates are what
// chance explains; every true landmark is still confirmed.
TEST(LandmarkPersistence, FeaturesWhereNothingStandsAreNotConfirmed) {
  World w = CameraRobot(4);
  const size_t true_landmarks = w.landmarks.size();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> x(0.5, 14.5), y(0.5, 7.5);
  while (w.landmarks.size() < true_landmarks + 20) {
    const Eigen::Vector2d p(x(rng), y(rng));
    bool apart = true;
    for (size_t i = 0; i < true_landmarks; ++i) apart = apart && (w.landmarks[i].position - p).norm() >= 1.0;
    if (apart) w.landmarks.push_back({static_cast<int>(w.landmarks.size()), p, Eigen::Matrix2d::Identity() * 1e-6});
  }
  const LandmarkPersistence p =
      AssessLandmarkPersistence(w.landmarks, w.trajectory, w.data.scans, w.data.sensor.range_bearing, {});
  for (size_t i = 0; i < w.landmarks.size(); ++i) {
    EXPECT_EQ(p.confirmed[i], i < true_landmarks)
        << i << ": " << p.detected[i] << " of " << p.expected[i] << ", chance " << p.chance_expected[i];
  }
  EXPECT_GT(p.chance_pairing_density, 0.0);
}

TEST(LandmarkPersistence, OptionsRefuseWhatCannotBe) {
  EXPECT_FALSE((LandmarkPersistenceOptions{.gate_probability = 1.0}).Validate().ok());
  EXPECT_FALSE((LandmarkPersistenceOptions{.confirm_probability = 0.0}).Validate().ok());
  EXPECT_FALSE((LandmarkPersistenceOptions{.range_bins = 0}).Validate().ok());
  EXPECT_TRUE(LandmarkPersistenceOptions{}.Validate().ok());
}

}  // namespace
}  // namespace subslam::backend
