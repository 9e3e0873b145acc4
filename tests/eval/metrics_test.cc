#include <gtest/gtest.h>

#include <cmath>

#include "subslam/eval/gps_alignment.h"
#include "subslam/eval/labelled_map_errors.h"
#include "subslam/eval/local_map_errors.h"
#include "subslam/eval/nees.h"
#include "subslam/eval/trajectory_errors.h"
#include "test_util.h"

namespace subslam::eval {
namespace {

TEST(Nees, KnownValues) {
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  P.diagonal() << 4.0, 1.0, 0.01;
  // Errors of 1σ on each axis → 1 + 1 + 1.
  EXPECT_NEAR(*PoseNees(Pose2(2, 1, 0.1), Pose2(0, 0, 0), P), 3.0, 1e-12);
  // Heading difference across ±π wraps.
  EXPECT_NEAR(*PoseNees(Pose2(0, 0, kPi - 0.05), Pose2(0, 0, -kPi + 0.05), P), 1.0, 1e-9);
  EXPECT_FALSE(PoseNees(Pose2(), Pose2(), Eigen::Matrix3d::Zero()).has_value());
  EXPECT_NEAR(*PointNees({1, 1}, {0, 0}, Eigen::Matrix2d::Identity() * 2), 1.0, 1e-12);
}

TEST(Nees, AverageBoundsAndConsistencyIndex) {
  const NeesBounds b = AverageNeesBounds(3, 50);
  EXPECT_NEAR(b.lower, 2.36, 0.005);  // ISEIF §4: [2.36, 3.72]
  EXPECT_NEAR(b.upper, 3.72, 0.005);
  EXPECT_TRUE(b.Contains(3.0));
  EXPECT_FALSE(b.Contains(3.8));
  const NeesBounds one = AverageNeesBounds(2, 1);
  EXPECT_NEAR(one.lower, 0.0506356, 1e-6);
  EXPECT_NEAR(one.upper, 7.3777589, 1e-6);
  EXPECT_NEAR(ConsistencyIndex(7.814727903, 3), 1.0, 1e-9);
}

TEST(TrajectoryErrors, RmsAndFailureTest) {
  std::vector<io::TimedPose> truth;
  Trajectory est;
  for (int k = 0; k < 100; ++k) {
    truth.push_back({k * 1.0, Pose2(k, 0, 0)});
    PoseEstimate e;
    e.t = k;
    e.pose = Pose2(k + 3.0, 4.0, 0.0);  // 5 m off
    e.covariance = Eigen::Matrix3d::Identity() * (k < 50 ? 100.0 : 0.01);
    est.push_back(e);
  }
  const TrajectoryErrors r = ComputeTrajectoryErrors(est, truth);
  EXPECT_NEAR(r.rms_position_m, 5.0, 1e-12);
  EXPECT_NEAR(r.rms_x_m, 3.0, 1e-12);
  EXPECT_NEAR(r.rms_heading_rad, 0.0, 1e-12);
  // Steps 50..99: 50 m / 0.1 m = 50σ for 50 consecutive steps > 20 → failed.
  EXPECT_TRUE(r.failed);
  EXPECT_EQ(r.longest_excursion_steps, 50);
  EXPECT_NEAR(r.nees[0], 0.25, 1e-12);
  est.resize(60);  // only 10 bad steps: passes
  EXPECT_FALSE(ComputeTrajectoryErrors(est, truth).failed);
}

TEST(TrajectoryErrors, InterpolatesTruthInTime) {
  const std::vector<io::TimedPose> truth = {{0.0, Pose2(0, 0, kPi - 0.1)}, {1.0, Pose2(2, 4, -kPi + 0.1)}};
  const Pose2 mid = InterpolatePose(truth, 0.5);
  EXPECT_NEAR(mid.x, 1.0, 1e-12);
  EXPECT_NEAR(mid.y, 2.0, 1e-12);
  EXPECT_NEAR(std::abs(mid.theta), kPi, 1e-12);  // through π, not through 0
}

TEST(MapErrors, MatchesNearestAndCountsSpurious) {
  const std::vector<io::TruthLandmark> truth = {{0, {0, 0}}, {1, {10, 0}}, {2, {20, 0}}};
  std::vector<LandmarkEstimate> est = {{5, {0.3, 0.4}, Eigen::Matrix2d::Identity()},
                                       {6, {10, -0.5}, Eigen::Matrix2d::Identity()},
                                       {7, {50, 50}, Eigen::Matrix2d::Identity()},
                                       {8, {0.5, 0.0}, Eigen::Matrix2d::Identity()}};
  const MapErrors m = ComputeMapErrors(est, truth, 2.0);
  EXPECT_EQ(m.matched, 2);
  EXPECT_EQ(m.spurious, 1);
  EXPECT_EQ(m.duplicates, 1);
  EXPECT_NEAR(m.rms_m, std::sqrt((0.25 + 0.25) / 2), 1e-12);
}

// Nearest-first would give the one true landmark the second estimate reaches to the first
// (0.5 m) and call the second a duplicate; each has a true landmark of its own within the
// radius, so both are matched (1.5 m each).
TEST(MapErrors, MatchesAsManyAsOneToOneAllowsThenTheNearest) {
  const std::vector<io::TruthLandmark> truth = {{0, {0, 0}}, {1, {2, 0}}};
  const std::vector<LandmarkEstimate> est = {{5, {0.5, 0}, Eigen::Matrix2d::Identity()},
                                             {6, {-1.5, 0}, Eigen::Matrix2d::Identity()}};
  const MapErrors m = ComputeMapErrors(est, truth, 2.0);
  EXPECT_EQ(m.matched, 2);
  EXPECT_EQ(m.duplicates, 0);
  EXPECT_EQ(m.spurious, 0);
  EXPECT_NEAR(m.rms_m, 1.5, 1e-6);
  // Of the two complete matchings, the one of the smaller sum of squared distances
  // (0.1² + 0.2², not 0.9² + 0.8²).
  const std::vector<io::TruthLandmark> two = {{0, {0, 0}}, {1, {1, 0}}};
  const std::vector<LandmarkEstimate> near = {{5, {0.1, 0}, Eigen::Matrix2d::Identity()},
                                              {6, {0.8, 0}, Eigen::Matrix2d::Identity()}};
  const MapErrors n = ComputeMapErrors(near, two, 3.0);
  EXPECT_EQ(n.matched, 2);
  EXPECT_NEAR(n.rms_m, std::sqrt((0.1 * 0.1 + 0.2 * 0.2) / 2), 1e-6);
}

// The map metric matches against the true landmarks some detection saw (a false alarm's
// id names none); without true ids on the detections, against all of them.
TEST(MapErrors, MatchesAgainstTheTrueLandmarksTheSensorSaw) {
  io::Dataset d;
  d.truth_landmarks = {{0, {0, 0}}, {1, {3, 0}}, {2, {30, 0}}};
  d.sensor.has_truth_id = true;
  d.scans = {{0.0, {{5.0, 0.0, NAN, 2}, {1.0, 0.5, NAN, kFalseAlarmId}}}, {0.1, {{4.0, 0.1, NAN, 0}}}};
  const std::vector<io::TruthLandmark> observed = ObservedTruthLandmarks(d);
  ASSERT_EQ(observed.size(), 2u);
  EXPECT_EQ(observed[0].id, 0);
  EXPECT_EQ(observed[1].id, 2);
  // Two estimates of landmark 0: against every true landmark the copy would take the
  // unseen landmark 1 (2.5 m off); against those seen it is a duplicate.
  const std::vector<LandmarkEstimate> est = {{5, {0.1, 0}, Eigen::Matrix2d::Identity()},
                                             {6, {0.5, 0}, Eigen::Matrix2d::Identity()}};
  EXPECT_EQ(ComputeMapErrors(est, d.truth_landmarks, 5.0).duplicates, 0);
  EXPECT_EQ(ComputeMapErrors(est, observed, 5.0).duplicates, 1);
  d.sensor.has_truth_id = false;
  EXPECT_EQ(ObservedTruthLandmarks(d).size(), 3u);
}

// By label, a landmark far from its true position still counts; unknown labels do not;
// two estimates of one true landmark are a duplicate.
TEST(MapErrors, LabelledErrorsFollowTheLabelsNotTheDistances) {
  const std::vector<io::TruthLandmark> truth = {{0, {0, 0}}, {1, {10, 0}}};
  const std::vector<LandmarkEstimate> est = {{5, {3, 4}, Eigen::Matrix2d::Identity()},
                                             {6, {0, 0}, 4 * Eigen::Matrix2d::Identity()},
                                             {7, {10, 0}, Eigen::Matrix2d::Identity()},
                                             {8, {40, 0}, Eigen::Matrix2d::Identity()}};
  const LabelledMapErrors m = ComputeLabelledMapErrors(est, {0, 0, -1, 99}, truth);
  EXPECT_EQ(m.labelled, 2);
  EXPECT_EQ(m.true_landmarks, 1);
  EXPECT_EQ(m.duplicates, 1);
  EXPECT_NEAR(m.rms_m, std::sqrt(25.0 / 2), 1e-12);
  EXPECT_NEAR(m.rms_x_m, std::sqrt(9.0 / 2), 1e-12);
  EXPECT_NEAR(m.mean_nees, 25.0 / 2, 1e-12);
  EXPECT_NEAR(m.fraction_nees_in_95, 0.5, 1e-12);
}

TEST(GpsAlignment, RecoversRigidTransformAndResidual) {
  const Pose2 gps_T_est(5.0, -3.0, DegToRad(-33.0));
  Trajectory traj;
  std::vector<io::TimedPoint> gps;
  for (int k = 0; k <= 100; ++k) {
    const double t = 0.5 * k;
    const Eigen::Vector2d p(10 * std::cos(0.1 * t), 7 * std::sin(0.2 * t));
    traj.push_back({t, Pose2(p.x(), p.y(), 0.0), Eigen::Matrix3d::Identity()});
    if (k % 2 == 1) {
      // GPS between two estimate samples: time interpolation must be used.
      const double tg = t - 0.25;
      const Eigen::Vector2d pg(10 * std::cos(0.1 * tg), 7 * std::sin(0.2 * tg));
      gps.push_back({tg, TransformFrom(gps_T_est, pg)});
    }
  }
  absl::StatusOr<GpsComparison> c = CompareWithGps(traj, gps);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(c->matched_fixes, 50);
  EXPECT_NEAR(c->gps_T_estimate.theta, gps_T_est.theta, 1e-3);
  EXPECT_NEAR(c->gps_T_estimate.x, gps_T_est.x, 2e-2);
  EXPECT_LT(c->rms_m, 0.05);  // linear interpolation error only
  // A constant 1 m offset along x in GPS frame with exact poses: alignment absorbs it.
  for (io::TimedPoint& g : gps) g.p.x() += 1.0;
  EXPECT_LT(CompareWithGps(traj, gps)->rms_m, 0.05);
  EXPECT_FALSE(RigidAlignment2D({{0, 0}}, {{1, 1}}).ok());
}

// A gross fault (130 m off its neighbours) is dropped and counted; the clean fixes of a
// vehicle at 5 m/s, one a second, are all kept, and so is a fix 20 m off (within the rule).
TEST(GpsAlignment, DropsGrossFaultsJudgedFromTheGpsAlone) {
  Trajectory traj;
  std::vector<io::TimedPoint> gps;
  for (int k = 0; k <= 60; ++k) {
    const double t = k;
    const Eigen::Vector2d p(5.0 * t, 0.0);
    traj.push_back({t, Pose2(p.x(), p.y(), 0.0), Eigen::Matrix3d::Identity()});
    gps.push_back({t, p});
  }
  EXPECT_TRUE(GrossGpsFaults(gps).empty());
  gps[30].p.y() += 20.0;
  EXPECT_TRUE(GrossGpsFaults(gps).empty());
  gps[30].p.y() += 110.0;
  EXPECT_EQ(GrossGpsFaults(gps), std::vector<int>{30});
  absl::StatusOr<GpsComparison> c = CompareWithGps(traj, gps);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(c->rejected_fixes, 1);
  EXPECT_EQ(c->matched_fixes, 60);
  EXPECT_LT(c->rms_m, 1e-9);
  // The rule's own bound: at 25 m + 6 m/s × 2 s from the median, kept; beyond, dropped.
  gps[30].p.y() = 36.9;
  EXPECT_TRUE(GrossGpsFaults(gps).empty());
  gps[30].p.y() = 37.1;
  EXPECT_EQ(GrossGpsFaults(gps), std::vector<int>{30});
}

// The local map is compared with the truth in the TRUE start frame: the end pose is
// Between(start, end) and each feature the true landmark seen from the start pose.
TEST(LocalMapNees, KnownValue) {
  const std::vector<io::TimedPose> truth = {{0.0, Pose2(10, 0, kPi / 2)}, {10.0, Pose2(10, 5, kPi / 2)}};
  const std::vector<io::TruthLandmark> landmarks = {{3, Eigen::Vector2d(8, 4)}};
  LocalSubmap s;
  s.t_start = 0.0;
  s.t_end = 10.0;
  s.mean = Eigen::VectorXd(5);
  // True end pose in the start frame: (5, 0, 0); true landmark: (4, 2).
  s.mean << 5.1, 0.0, 0.0, 4.0, 2.2;
  s.covariance = 0.01 * Eigen::MatrixXd::Identity(5, 5);
  s.landmarks = {{0, NAN, 1.0, 3, std::nullopt, {}}};
  const std::optional<LocalMapNees> e = EvaluateLocalMap(s, truth, landmarks);
  ASSERT_TRUE(e.has_value());
  EXPECT_EQ(e->dof, 5);
  EXPECT_EQ(e->landmarks_evaluated, 1);
  EXPECT_NEAR(e->pose_nees, 0.01 / 0.01, 1e-9);
  EXPECT_NEAR(e->nees, (0.01 + 0.04) / 0.01, 1e-9);
  ASSERT_EQ(e->landmark_nees.size(), 1u);
  EXPECT_NEAR(e->landmark_nees[0], 4.0, 1e-9);
  EXPECT_NEAR(e->lower, 0.831, 1e-3);  // χ²₅ 2.5% and 97.5%
  EXPECT_NEAR(e->upper, 12.833, 1e-3);
  // A false alarm and an unlabelled feature are counted, not evaluated.
  s.landmarks[0].truth_id = -1;
  EXPECT_EQ(EvaluateLocalMap(s, truth, landmarks)->false_alarms, 1);
  s.landmarks[0].truth_id.reset();
  EXPECT_EQ(EvaluateLocalMap(s, truth, landmarks)->unlabelled, 1);
  // Outside the truth's time span: nothing to compare.
  s.t_end = 11.0;
  EXPECT_FALSE(EvaluateLocalMap(s, truth, landmarks).has_value());
}

}  // namespace
}  // namespace subslam::eval
