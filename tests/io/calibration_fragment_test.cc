#include "subslam/io/calibration_fragment.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "subslam/io/steps.h"

namespace subslam::io {
namespace {

namespace fs = std::filesystem;

class CalibrationFile : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = (fs::path(::testing::TempDir()) /
             ("subslam_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + ".json"))
                .string();
    dataset_.motion.model = MotionModelType::kUnicycle;
    dataset_.motion.noise = {0.1, 0.01, 0.0, 0.0};
    dataset_.sensor.range_bearing = {0.1, 0.01, 0.0, 30.0, -kPi, kPi};
  }
  absl::Status Apply(const std::string& text) {
    std::ofstream(path_) << text;
    return ApplyCalibrationFile(path_, &dataset_);
  }
  // Expects the file to be refused with every fragment in the message, the data set untouched.
  void ExpectError(const std::string& text, const std::vector<std::string>& fragments) {
    const Dataset before = dataset_;
    const absl::Status s = Apply(text);
    ASSERT_FALSE(s.ok()) << text;
    for (const std::string& f : fragments) {
      EXPECT_NE(s.message().find(f), std::string::npos) << "'" << f << "' not in: " << s.message();
    }
    EXPECT_EQ(dataset_.motion.noise.sigma_u0, before.motion.noise.sigma_u0);
    EXPECT_EQ(dataset_.motion.control_scale, before.motion.control_scale);
    EXPECT_EQ(dataset_.sensor.range_bearing.sigma_range_m, before.sensor.range_bearing.sigma_range_m);
  }
  std::string path_;
  Dataset dataset_;
};

TEST_F(CalibrationFile, ReplacesWhatItGivesAndKeepsTheRest) {
  ASSERT_TRUE(Apply(R"({"source": "x", "manifest_fragment": {
      "motion": {"sigma_v": 0.05, "sigma_omega_scale": 0.2, "control_scale": [0.93, 0.95], "control_offset": [0, 0.01]},
      "sensor": {"sigma_range": 0.12, "fov": [-0.6, 0.5], "max_range": 8}}})")
                  .ok());
  EXPECT_EQ(dataset_.motion.noise.sigma_u0, 0.05);
  EXPECT_EQ(dataset_.motion.noise.sigma_u1, 0.01);  // kept
  EXPECT_EQ(dataset_.motion.noise.scale_u1, 0.2);
  EXPECT_EQ(dataset_.motion.control_scale, Eigen::Vector2d(0.93, 0.95));
  EXPECT_EQ(dataset_.motion.control_offset, Eigen::Vector2d(0.0, 0.01));
  EXPECT_EQ(dataset_.sensor.range_bearing.sigma_range_m, 0.12);
  EXPECT_EQ(dataset_.sensor.range_bearing.sigma_bearing_rad, 0.01);  // kept
  EXPECT_EQ(dataset_.sensor.range_bearing.max_range_m, 8.0);
  EXPECT_EQ(dataset_.sensor.range_bearing.fov_min_rad, -0.6);
  // The correction reaches the steps every estimator reads.
  EXPECT_TRUE(dataset_.motion.Corrected(Eigen::Vector2d(1.0, 1.0)).isApprox(Eigen::Vector2d(0.93, 0.96)));
}

TEST_F(CalibrationFile, ABareFragmentIsAccepted) {
  ASSERT_TRUE(Apply(R"({"sensor": {"sigma_bearing": 0.02}})").ok());
  EXPECT_EQ(dataset_.sensor.range_bearing.sigma_bearing_rad, 0.02);
}

TEST_F(CalibrationFile, BadInputNamesTheFileAndTheFieldAndChangesNothing) {
  ExpectError(R"({"motion": {"sigma_v": -1}})", {path_, "motion.sigma_v", "> 0"});
  ExpectError(R"({"motion": {"sigma_steer": 0.1}})", {"motion.sigma_steer", "unknown key"});
  ExpectError(R"({"motion": {"sigma_v": 0.2, "control_scale": [0.9, 0]}})", {"motion.control_scale"});
  ExpectError(R"({"motion": {"control_offset": [0.1]}})", {"motion.control_offset", "2 numbers"});
  ExpectError(R"({"manifest_fragment": {"sensor": {"sigma_range": "a"}}})",
              {"manifest_fragment.sensor.sigma_range", "expected a number"});
  ExpectError(R"({"sensor": {"sigma_range": 0.2, "min_range": 5, "max_range": 4}})", {"sensor.max_range"});
  ExpectError(R"({"sensor": {"fov": [1, -1]}})", {"sensor.fov"});
  ExpectError(R"({"odometry": {}})", {"odometry", "unknown key"});
  ExpectError("{\n\"motion\": {\"sigma_v\": 0.1,}\n}", {path_ + ":2", "invalid JSON"});
  ExpectError("[1, 2]", {"expected a JSON object"});
}

TEST_F(CalibrationFile, AMissingFileIsNamed) {
  const absl::Status s = ApplyCalibrationFile(path_ + ".absent", &dataset_);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find(path_ + ".absent"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace subslam::io
