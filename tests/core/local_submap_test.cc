#include "subslam/core/local_submap.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <string>

namespace subslam {
namespace {

LocalSubmap Valid() {
  LocalSubmap s;
  s.id = 4;
  s.t_start = 10.0;
  s.t_end = 20.0;
  s.mean = Eigen::VectorXd(7);
  s.mean << 5.0, 1.0, 0.2, 3.0, 4.0, -2.0, 6.0;
  s.covariance = Eigen::MatrixXd::Identity(7, 7) * 0.1;
  s.covariance(0, 3) = s.covariance(3, 0) = 0.05;
  s.landmarks = {{0, 0.3, 0.99, 17, std::nullopt, {}}, {5, NAN, 0.97, std::nullopt, std::nullopt, {}}};
  return s;
}

TEST(LocalSubmap, AcceptsAValidMapAndReadsBlocks) {
  const LocalSubmap s = Valid();
  EXPECT_TRUE(s.Validate().ok()) << s.Validate();
  EXPECT_EQ(s.num_landmarks(), 2);
  EXPECT_EQ(s.end_pose().theta, 0.2);
  EXPECT_EQ(s.landmark(1), Eigen::Vector2d(-2.0, 6.0));
  EXPECT_EQ(s.landmark_covariance(0)(0, 0), 0.1);
}

// A covariance that is positive definite only through rounding (condition ~1e17) is
// rejected with its eigenvalues: a joiner cannot whiten by it.
TEST(LocalSubmap, RejectsANumericallySingularCovariance) {
  LocalSubmap s = Valid();
  Eigen::VectorXd direction = Eigen::VectorXd::Ones(7).normalized();
  s.covariance =
      Eigen::MatrixXd::Identity(7, 7) - direction * direction.transpose() + 1e-17 * direction * direction.transpose();
  ASSERT_EQ(Eigen::LLT<Eigen::MatrixXd>(s.covariance).info(), Eigen::Success);
  const absl::Status st = s.Validate();
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("numerically singular"), std::string::npos) << st;
  s.covariance += 1e-11 * direction * direction.transpose();  // condition 1e11: accepted
  EXPECT_TRUE(s.Validate().ok()) << s.Validate();
}

// A map over almost no motion (one 0.1 s step of a vehicle barely moving: 1.1e-15 m² along
// its path) is well conditioned in itself but nearly rigid: its information would swamp Λ.
// Validate() rejects it; the regularisation rule makes it valid in one round and counts it.
TEST(LocalSubmap, RejectsANearlyRigidCovarianceAndTheRuleRegularizesIt) {
  LocalSubmap s;
  s.id = 111;
  s.t_start = 429.1;
  s.t_end = 429.2;
  s.mean = Eigen::Vector3d(-1.2e-4, 0.0, -6.2e-5);
  s.covariance = Eigen::Vector3d(1.1e-15, 6.5e-7, 1.1e-6).asDiagonal();
  const absl::Status st = s.Validate();
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("nearly rigid"), std::string::npos) << st;
  EXPECT_NE(st.message().find("local map 111"), std::string::npos) << st;
  EXPECT_EQ(s.RegularizeDegenerateCovariance(), 1);
  EXPECT_TRUE(s.Validate().ok()) << s.Validate();
  EXPECT_EQ(s.covariance_repairs, 1);
  EXPECT_DOUBLE_EQ(s.covariance(0, 0), 1.1e-15 + LocalSubmap::kRegularizationVariance);
  // At the floor itself it is accepted as it is.
  s.covariance = Eigen::Vector3d(LocalSubmap::kMinVariance, 6.5e-7, 1.1e-6).asDiagonal();
  EXPECT_TRUE(s.Validate().ok()) << s.Validate();
}

TEST(LocalSubmap, RejectsEachBrokenInvariant) {
  const auto broken = [](auto&& edit) {
    LocalSubmap s = Valid();
    edit(s);
    return !s.Validate().ok();
  };
  EXPECT_TRUE(broken([](LocalSubmap& s) { s.mean.conservativeResize(5); }));
  EXPECT_TRUE(broken([](LocalSubmap& s) { s.covariance.conservativeResize(5, 5); }));
  EXPECT_TRUE(broken([](LocalSubmap& s) { s.t_end = 5.0; }));
  EXPECT_TRUE(broken([](LocalSubmap& s) { s.mean[4] = NAN; }));
  EXPECT_TRUE(broken([](LocalSubmap& s) { s.mean[2] = 4.0; }));  // heading not wrapped
  EXPECT_TRUE(broken([](LocalSubmap& s) { s.landmarks[1].local_id = 0; }));
  EXPECT_TRUE(broken([](LocalSubmap& s) { s.landmarks[0].existence = 1.5; }));
  EXPECT_TRUE(broken([](LocalSubmap& s) { s.covariance(0, 1) = 0.01; }));  // asymmetric
  EXPECT_TRUE(broken([](LocalSubmap& s) { s.covariance(6, 6) = -0.1; }));  // not PD
}

}  // namespace
}  // namespace subslam
