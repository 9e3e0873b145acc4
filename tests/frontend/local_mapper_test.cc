#include "subslam/frontend/local_mapper.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>

#include "test_util.h"

namespace subslam::frontend {
namespace {

using testing::MatricesNear;

// A local mapper whose filter is a fixed Gaussian over [pose, three features], built as
// x = M z, z ~ N(0, I): the end pose 3 m uncertain; feature 4 tight; feature 7 5 m wide
// along a diagonal axis, apart from the pose; feature 9 the pose's position plus 0.1 m
// (3 m wide in the start frame, 0.1 m relative to the end pose); small couplings between
// all of them.
class FixedGaussianMapper final : public LocalMapper {
 public:
  FixedGaussianMapper(const SubmapPolicyOptions& policy, const models::RangeBearingConfig& sensor)
      : LocalMapper(policy, sensor, 0.0) {
    Eigen::MatrixXd M = 0.02 * Eigen::MatrixXd::Random(9, 9);
    M.topLeftCorner<3, 3>() += Eigen::Vector3d(3.0, 3.0, 0.05).asDiagonal();
    M.block<2, 2>(3, 3) += 0.1 * Eigen::Matrix2d::Identity();
    M.block<2, 2>(5, 5) += 5.0 * Eigen::Vector2d(1, 1).normalized() * Eigen::Vector2d(1, 0).transpose() +
                           0.1 * Eigen::Vector2d(-1, 1).normalized() * Eigen::Vector2d(0, 1).transpose();
    M.block<2, 9>(7, 0) += M.block<2, 9>(0, 0);
    M.block<2, 2>(7, 7) += 0.1 * Eigen::Matrix2d::Identity();
    const Eigen::MatrixXd C = M * M.transpose();
    gaussian_.mean = Eigen::VectorXd::LinSpaced(9, 1.0, 9.0);
    gaussian_.covariance = C;
    gaussian_.features = {4, 7, 9};
    gaussian_.existence = {0.99, 0.98, 0.97};
    gaussian_.signature = {0.1, 0.2, 0.3};
  }
  const MomentMatchedGaussian& gaussian() const { return gaussian_; }
  void set_gaussian(const MomentMatchedGaussian& g) { gaussian_ = g; }
  std::string Name() const override { return "fixed"; }
  const std::vector<int>& last_scan_features() const override { return none_; }

 private:
  void FilterPredict(const Eigen::Vector2d&, double) override {}
  absl::Status FilterUpdate(const Scan&) override { return absl::OkStatus(); }
  void FilterReset() override {}
  SubmapStatus FilterStatus() const override { return {}; }
  Pose2 FilterPose() const override { return Pose2(); }
  Eigen::Matrix3d FilterPoseCovariance() const override { return Eigen::Matrix3d::Zero(); }
  MomentMatchedGaussian Export() const override { return gaussian_; }
  StageTimes FilterStageTimes() const override { return {}; }
  std::map<std::string, double> FilterCounters() const override { return {}; }

  MomentMatchedGaussian gaussian_;
  std::vector<int> none_;
};

// A feature more uncertain relative to the end pose than one detection at the sensor's
// maximum range is not exported; one as uncertain only through the pose's drift is. The
// others' mean and covariance are the original rows and columns (the Gaussian
// marginalised), with their ids, existence and signatures; the count is reported. With
// the rule off every feature is exported.
TEST(LocalMapper, DoesNotExportAFeatureWiderThanOneDetectionAtMaximumRange) {
  models::RangeBearingConfig sensor;
  sensor.sigma_range_m = 0.5;
  sensor.sigma_bearing_rad = 0.05;
  sensor.max_range_m = 40.0;  // one detection there: 2 m across
  for (const double ratio : {1.0, 0.0}) {
    SubmapPolicyOptions policy;
    policy.max_feature_sigma_ratio = ratio;
    FixedGaussianMapper mapper(policy, sensor);
    Scan scan;
    scan.t = 0.5;
    EXPECT_TRUE(mapper.Update(scan).ok());
    mapper.Finish();
    const std::vector<ClosedLocalMap> closed = mapper.TakeClosed();
    ASSERT_EQ(closed.size(), 1u);
    const LocalSubmap& s = closed[0].submap;
    const MomentMatchedGaussian& g = mapper.gaussian();
    if (ratio == 0.0) {
      EXPECT_EQ(s.num_landmarks(), 3);
      EXPECT_TRUE(MatricesNear(g.covariance, s.covariance, 0.0));
      continue;
    }
    ASSERT_EQ(s.num_landmarks(), 2);
    const std::vector<int> rows = {0, 1, 2, 3, 4, 7, 8};
    EXPECT_TRUE(MatricesNear(g.mean(rows), s.mean, 0.0));
    EXPECT_TRUE(MatricesNear(g.covariance(rows, rows), s.covariance, 0.0));
    EXPECT_EQ(s.landmarks[0].local_id, 4);
    EXPECT_EQ(s.landmarks[1].local_id, 9);
    EXPECT_GT(std::sqrt(s.covariance.block<2, 2>(5, 5).eigenvalues().real().maxCoeff()),
              2.5);  // 3 m in the start frame
    EXPECT_EQ(s.landmarks[1].existence, 0.97);
    EXPECT_EQ(s.landmarks[1].signature, 0.3);
    EXPECT_EQ(mapper.Counters().at("features_too_uncertain_to_export"), 1.0);
  }
}

// A map over almost no motion (one 0.1 s step of a vehicle barely moving: 1.1e-15 m² along
// its path) is nearly rigid: the mapper closes it regularised by the documented rule and
// counts the repair, instead of failing the export.
TEST(LocalMapper, RegularizesANearlyRigidMapItCloses) {
  models::RangeBearingConfig sensor;
  FixedGaussianMapper mapper(SubmapPolicyOptions{}, sensor);
  MomentMatchedGaussian rigid;
  rigid.mean = Eigen::Vector3d(-1.2e-4, 0.0, -6.2e-5);
  rigid.covariance = Eigen::Vector3d(1.1e-15, 6.5e-7, 1.1e-6).asDiagonal();
  mapper.set_gaussian(rigid);
  Scan scan;
  scan.t = 0.1;
  EXPECT_TRUE(mapper.Update(scan).ok());
  mapper.Finish();
  ASSERT_TRUE(mapper.status().ok()) << mapper.status();
  const std::vector<ClosedLocalMap> closed = mapper.TakeClosed();
  ASSERT_EQ(closed.size(), 1u);
  const LocalSubmap& s = closed[0].submap;
  EXPECT_TRUE(s.Validate().ok()) << s.Validate();
  EXPECT_EQ(s.covariance_repairs, 1);
  EXPECT_DOUBLE_EQ(s.covariance(0, 0), 1.1e-15 + LocalSubmap::kRegularizationVariance);
  EXPECT_EQ(mapper.Counters().at("covariance_repairs"), 1.0);
}

}  // namespace
}  // namespace subslam::frontend
