// The filters that learn the odometry's systematic error (odometry_calibration.h).
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "subslam/core/check.h"
#include "subslam/frontend/ekf_slam.h"
#include "subslam/frontend/fastslam.h"
#include "subslam/io/steps.h"
#include "subslam/models/ackermann_model.h"
#include "subslam/models/unicycle_model.h"
#include "subslam/sim/simulator.h"

namespace subslam::frontend {
namespace {

// ∂f(x, u'(c))/∂c = G · ∂u'/∂c, the block Predict() puts between the pose and the
// calibration, against central differences, for both motion models.
TEST(OdometryCalibration, PredictionJacobianMatchesCentralDifferences) {
  const models::UnicycleModel unicycle;
  const models::AckermannModel ackermann(models::AckermannGeometry{}, models::ControlNoise{});
  const Pose2 x(1.0, -2.0, 0.7);
  const Eigen::Vector3d c(0.93, 1.04, 0.02);
  for (const models::MotionModel* model :
       {static_cast<const models::MotionModel*>(&unicycle), static_cast<const models::MotionModel*>(&ackermann)}) {
    const Eigen::Vector2d u(1.3, 0.21);
    const double dt = 0.4;
    Eigen::Matrix<double, 2, 3> du_dc;
    Matrix32d G;
    model->Predict(x, CalibratedControl(u, c, &du_dc), dt, nullptr, &G);
    const Eigen::Matrix3d analytic = G * du_dc;
    Eigen::Matrix3d numeric;
    const double h = 1e-6;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d step = Eigen::Vector3d::Unit(k) * h;
      const Pose2 plus = model->Predict(x, CalibratedControl(u, c + step), dt);
      const Pose2 minus = model->Predict(x, CalibratedControl(u, c - step), dt);
      numeric.col(k) = (plus.vector() - minus.vector()) / (2 * h);
    }
    EXPECT_LT((analytic - numeric).cwiseAbs().maxCoeff(), 1e-7) << model->Name() << "\n" << analytic << "\n" << numeric;
  }
}

struct CalibratedRun {
  OdometryCalibrationEstimate estimate;
  double rms_position_error_m = 0.0;  // over the scans
};

// The camera robot (no moving objects, true ids) driving at `scale` × what its odometry
// reports, through EKF-SLAM or FastSLAM 2.0 with the calibration `odometry`; with `reset`,
// a new local map starts halfway.
template <typename Kind>
CalibratedRun RunCameraRobot(const Eigen::Vector2d& scale, const OdometryCalibrationOptions& odometry,
                             bool reset = false) {
  sim::ScenarioOptions o;
  o.seed = 4;
  o.moving_objects = 0;
  absl::StatusOr<sim::ScenarioConfig> config = sim::MakeScenario("camera-robot", o);
  SUBSLAM_CHECK(config.ok()) << config.status().message();
  config->odometry_scale = scale;
  absl::StatusOr<io::Dataset> d = sim::Simulate(*config, o.seed);
  SUBSLAM_CHECK(d.ok()) << d.status().message();
  typename Kind::Options options;
  options.landmarks.known_association = true;
  options.odometry = odometry;
  typename Kind::Filter filter(d->motion.MakeModel(), d->sensor.range_bearing, d->initial_pose, options);
  const std::vector<io::Step> steps = io::BuildSteps(*d);
  std::map<double, Pose2> truth;
  for (const io::TimedPose& p : d->truth_poses) truth[p.t] = p.pose;
  double squared_error = 0.0;
  long scans = 0;
  for (size_t k = 0; k < steps.size(); ++k) {
    // A new local map: the calibration carries over, the pose's uncertainty not.
    if (reset && k == steps.size() / 2) {
      const OdometryCalibrationEstimate before = filter.odometry_calibration();
      filter.Reset(filter.pose());
      EXPECT_LT((filter.odometry_calibration().value - before.value).norm(), 1e-12);
      EXPECT_LT((filter.odometry_calibration().covariance - before.covariance).norm(), 1e-12);
      EXPECT_EQ(filter.pose_covariance(), Eigen::Matrix3d::Zero());
      EXPECT_TRUE(filter.Map().empty());
    }
    filter.Predict(steps[k].control, steps[k].dt);
    if (steps[k].scan_index < 0) continue;
    EXPECT_TRUE(filter.Update(d->scans[steps[k].scan_index]).ok());
    squared_error += (filter.pose().translation() - truth.at(steps[k].t).translation()).squaredNorm();
    ++scans;
  }
  CalibratedRun r;
  r.estimate = filter.odometry_calibration();
  r.rms_position_error_m = std::sqrt(squared_error / static_cast<double>(scans));
  return r;
}

// Every component to within a quarter of its prior's σ; for the EKF, whose covariance is
// that of a Gaussian filter, also to within four of its own standard deviations. The
// particle filter's covariance of c is optimistic (its paths descend from few ancestors:
// fastslam.h), so only the first is asked of it.
template <typename Kind>
void ExpectLearned(const OdometryCalibrationEstimate& e, const Eigen::Vector3d& truth,
                   const OdometryCalibrationOptions& prior) {
  const Eigen::Vector3d prior_sigma = prior.PriorCovariance().diagonal().cwiseSqrt();
  for (int i = 0; i < 3; ++i) {
    const double error = std::abs(e.value[i] - truth[i]), sigma = std::sqrt(e.covariance(i, i));
    EXPECT_LT(error, prior_sigma[i] / 4) << i << ": " << e.value[i];
    EXPECT_GT(sigma, 0.0) << i;
    if (Kind::kGaussianCovariance) EXPECT_LT(error, 4.0 * sigma) << i << ": " << e.value[i] << " sigma " << sigma;
  }
}

template <typename Filter>
class OdometryCalibrationOf : public ::testing::Test {};
// The two ways a filter carries the calibration: in the EKF's state, per particle.
struct EkfFilter {
  using Filter = EkfSlam;
  using Options = EkfSlamOptions;
  static constexpr bool kGaussianCovariance = true;
};
struct ParticleFilter {
  using Filter = FastSlam;
  using Options = FastSlamOptions;
  static constexpr bool kGaussianCovariance = false;
};
using Filters = ::testing::Types<EkfFilter, ParticleFilter>;
TYPED_TEST_SUITE(OdometryCalibrationOf, Filters);

constexpr OdometryCalibrationOptions kPrior{.scale_prior_sigma = 0.05, .offset_prior_sigma = 0.02};

// A robot that drives at 0.93× and turns at 0.95× its odometry: the filter finds both
// scales and no offset (ExpectLearned), and follows the robot more closely than the
// filter that takes the odometry as recorded.
TYPED_TEST(OdometryCalibrationOf, LearnsTheCameraRobotsScale) {
  const Eigen::Vector2d scale(0.93, 0.95);
  const CalibratedRun learned = RunCameraRobot<TypeParam>(scale, kPrior);
  ExpectLearned<TypeParam>(learned.estimate, Eigen::Vector3d(0.93, 0.95, 0.0), kPrior);
  const CalibratedRun as_recorded = RunCameraRobot<TypeParam>(scale, {});
  EXPECT_EQ(as_recorded.estimate.value, Eigen::Vector3d(1.0, 1.0, 0.0));
  EXPECT_LT(learned.rms_position_error_m, as_recorded.rms_position_error_m);
}

// Odometry that is right stays right (ExpectLearned), also across a Reset() that starts a
// new local map.
TYPED_TEST(OdometryCalibrationOf, RightOdometryStaysRightAcrossAReset) {
  const CalibratedRun r = RunCameraRobot<TypeParam>(Eigen::Vector2d::Ones(), kPrior, /*reset=*/true);
  ExpectLearned<TypeParam>(r.estimate, Eigen::Vector3d(1.0, 1.0, 0.0), kPrior);
}

TEST(OdometryCalibration, OptionsRefuseNegativeOrHugePriors) {
  EXPECT_FALSE((OdometryCalibrationOptions{.scale_prior_sigma = -0.1}).Validate().ok());
  EXPECT_FALSE((OdometryCalibrationOptions{.scale_prior_sigma = 1.0}).Validate().ok());
  EXPECT_FALSE((OdometryCalibrationOptions{.offset_prior_sigma = NAN}).Validate().ok());
  EXPECT_TRUE((OdometryCalibrationOptions{.scale_prior_sigma = 0.05, .offset_prior_sigma = 0.02}).Validate().ok());
}

}  // namespace
}  // namespace subslam::frontend
