#include "subslam/io/dataset_reader.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>

#include "subslam/io/dataset_writer.h"
#include "subslam/io/run_output_writer.h"
#include "subslam/io/steps.h"
#include "subslam/sim/simulator.h"
#include "test_util.h"

namespace subslam::io {
namespace {

namespace fs = std::filesystem;

TEST(ReadDataset, LoadsVictoriaPark) {
  const std::string dir = testing::VictoriaParkDir();
  if (!fs::exists(dir + "/dataset.json")) GTEST_SKIP() << "no Victoria Park data at " << dir;
  absl::StatusOr<Dataset> d = ReadDataset(dir);
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_EQ(d->motion.model, MotionModelType::kAckermann);
  EXPECT_EQ(d->controls.size(), 61945u);
  EXPECT_EQ(d->NumDetections(), 52974u);
  EXPECT_EQ(d->gps.size(), 4466u);
  EXPECT_TRUE(d->sensor.has_signature);
  EXPECT_FALSE(d->sensor.has_truth_id);
  EXPECT_DOUBLE_EQ(d->motion.geometry.wheelbase_m, 2.83);
  // First detection: bearing 0.88575 − π/2 in the vehicle frame, diameter 0.35404.
  const Detection& first = d->scans.front().detections.front();
  EXPECT_NEAR(first.bearing_rad, 0.88575 - kPi / 2, 1e-12);
  EXPECT_DOUBLE_EQ(first.signature, 0.35404);
}

// A small valid data set in a temporary directory, which each test then breaks.
class MalformedDataset : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) /
           ("subslam_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::create_directories(dir_);
    Write("dataset.json", R"({
  "format": "subslam-dataset/1", "name": "tiny", "initial_pose": [0, 0, 0],
  "motion": {"model": "unicycle", "controls_file": "c.dat", "sigma_v": 0.1, "sigma_omega": 0.01},
  "sensor": {"type": "range_bearing", "observations_file": "o.dat", "truth_id_column": 4,
             "sigma_range": 0.1, "sigma_bearing": 0.01, "max_range": 30},
  "ground_truth": {"gps_file": null, "poses_file": "p.dat", "landmarks_file": null}
})");
    Write("c.dat", "# t v omega\n0 1 0\n0.1 1 0.1\n0.2 1 0\n");
    Write("o.dat", "0.1 5 0.2 3\n0.1 7 -0.4 -1\n0.2 5.1 0.21 3\n");
    Write("p.dat", "0 0 0 0\n0.1 0.1 0 0\n0.2 0.2 0 0.01\n");
  }
  void Write(const std::string& name, const std::string& text) { std::ofstream(dir_ / name) << text; }
  // Expects ReadDataset to fail with a message containing every fragment.
  void ExpectError(const std::vector<std::string>& fragments) {
    absl::StatusOr<Dataset> d = ReadDataset(dir_.string());
    ASSERT_FALSE(d.ok());
    for (const std::string& f : fragments) {
      EXPECT_NE(d.status().message().find(f), std::string::npos) << "'" << f << "' not in: " << d.status().message();
    }
  }
  fs::path dir_;
};

TEST_F(MalformedDataset, ValidBaselineLoads) {
  absl::StatusOr<Dataset> d = ReadDataset(dir_.string());
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_EQ(d->scans.size(), 2u);
  EXPECT_EQ(d->scans[0].detections[1].truth_id, kFalseAlarmId);
  EXPECT_EQ(d->truth_poses.size(), 3u);
}

TEST_F(MalformedDataset, RepeatedControlTimeKeepsTheLaterLineAndIsCounted) {
  Write("c.dat", "0 1 0\n0.1 1 0.1\n0.1 2 0.2\n0.2 1 0\n");
  absl::StatusOr<Dataset> d = ReadDataset(dir_.string());
  ASSERT_TRUE(d.ok()) << d.status();
  ASSERT_EQ(d->controls.size(), 3u);
  EXPECT_EQ(d->controls[1].u, Eigen::Vector2d(2, 0.2));
  EXPECT_EQ(d->duplicate_control_times, 1);
}

TEST_F(MalformedDataset, NonNumericField) {
  Write("c.dat", "0 1 0\n0.1 abc 0\n");
  ExpectError({"c.dat:2", "'v'", "not a number"});
}

TEST_F(MalformedDataset, ShortLine) {
  Write("o.dat", "0.1 5 0.2 3\n0.2 5\n");
  ExpectError({"o.dat:2", "missing field 'bearing'"});
}

TEST_F(MalformedDataset, NanAndInfinity) {
  Write("o.dat", "0.1 nan 0.2 3\n");
  ExpectError({"o.dat:1", "'range'", "not finite"});
  Write("o.dat", "0.1 5 0.2 3\n");
  Write("c.dat", "0 1 inf\n");
  ExpectError({"c.dat:1", "'omega'", "not finite"});
}

TEST_F(MalformedDataset, TimeGoingBackwards) {
  Write("c.dat", "0 1 0\n0.2 1 0\n0.1 1 0\n");
  ExpectError({"c.dat:3", "'t'", "backwards"});
}

TEST_F(MalformedDataset, NegativeOrZeroSigma) {
  Write("dataset.json", R"({"format": "subslam-dataset/1", "name": "tiny",
  "motion": {"model": "unicycle", "controls_file": "c.dat", "sigma_v": -0.1, "sigma_omega": 0.01},
  "sensor": {"type": "range_bearing", "observations_file": "o.dat", "sigma_range": 0.1,
             "sigma_bearing": 0.01, "max_range": 30}})");
  ExpectError({"dataset.json", "motion.sigma_v", "must be > 0"});
  Write("dataset.json", R"({"format": "subslam-dataset/1", "name": "tiny",
  "motion": {"model": "unicycle", "controls_file": "c.dat", "sigma_v": 0.1, "sigma_omega": 0.01},
  "sensor": {"type": "range_bearing", "observations_file": "o.dat", "sigma_range": 0,
             "sigma_bearing": 0.01, "max_range": 30}})");
  ExpectError({"sensor.sigma_range", "must be > 0"});
}

TEST_F(MalformedDataset, MissingOrMistypedField) {
  Write("dataset.json", R"({"format": "subslam-dataset/1", "name": "tiny",
  "motion": {"model": "unicycle", "controls_file": "c.dat", "sigma_v": 0.1},
  "sensor": {"type": "range_bearing", "observations_file": "o.dat", "sigma_range": 0.1,
             "sigma_bearing": 0.01, "max_range": 30}})");
  ExpectError({"motion.sigma_omega", "missing"});
  Write("dataset.json", R"({"format": "subslam-dataset/1", "name": "tiny",
  "motion": {"model": "unicycle", "controls_file": "c.dat", "sigma_v": "0.1", "sigma_omega": 0.1},
  "sensor": {"type": "range_bearing", "observations_file": "o.dat", "sigma_range": 0.1,
             "sigma_bearing": 0.01, "max_range": 30}})");
  ExpectError({"motion.sigma_v", "expected a number"});
  Write("dataset.json", R"({"format": "subslam-dataset/1", "name": "tiny", "motoin": {}})");
  ExpectError({"motoin", "unknown key"});
}

TEST_F(MalformedDataset, InvalidJsonReportsLine) {
  Write("dataset.json", "{\n  \"format\": \"subslam-dataset/1\",\n  \"name\": tiny\n}\n");
  ExpectError({"dataset.json:3", "invalid JSON"});
  // A number beyond a double's range (an exception other than a syntax error).
  Write("dataset.json", R"({"format": "subslam-dataset/1", "name": "tiny", "initial_pose": [1e999, 0, 0]})");
  ExpectError({"dataset.json", "invalid JSON", "number overflow"});
}

TEST_F(MalformedDataset, EmptyOrMissingFile) {
  Write("c.dat", "# only a comment\n\n");
  ExpectError({"c.dat", "no data lines"});
  fs::remove(dir_ / "c.dat");
  ExpectError({"c.dat", "cannot open"});
}

TEST_F(MalformedDataset, DirectoryOrDeviceNamedAsFile) {
  fs::remove(dir_ / "c.dat");
  fs::create_directories(dir_ / "c.dat");
  ExpectError({"c.dat", "not a regular file"});
  Write("dataset.json", R"({"format": "subslam-dataset/1", "name": "tiny",
  "motion": {"model": "unicycle", "controls_file": "/dev/zero", "sigma_v": 0.1, "sigma_omega": 0.01},
  "sensor": {"type": "range_bearing", "observations_file": "o.dat", "sigma_range": 0.1,
             "sigma_bearing": 0.01, "max_range": 30}})");
  ExpectError({"/dev/zero", "not a regular file"});  // would never end if read
}

TEST(ReadDatasetFromMemory, ReadsTheFilesThroughTheReaderAndNamesThem) {
  std::map<std::string, std::string> files = {
      {"mem/dataset.json", R"({"format": "subslam-dataset/1", "name": "in memory",
  "motion": {"model": "unicycle", "controls_file": "c.dat", "sigma_v": 0.1, "sigma_omega": 0.01},
  "sensor": {"type": "range_bearing", "observations_file": "o.dat", "sigma_range": 0.1,
             "sigma_bearing": 0.01, "max_range": 30}})"},
      {"mem/c.dat", "0 1 0\n0.1 1 0.1\n"},
      {"mem/o.dat", "0.1 5 0.2\n0.1 6 0.3\n"}};
  std::vector<std::string> asked;
  const FileReader read = [&](const std::string& path) -> absl::StatusOr<std::string> {
    asked.push_back(path);
    const auto it = files.find(path);
    if (it == files.end()) return absl::NotFoundError(path + ": cannot open file");
    return it->second;
  };
  absl::StatusOr<Dataset> d = ReadDataset("mem", read);
  ASSERT_TRUE(d.ok()) << d.status();
  EXPECT_EQ(d->name, "in memory");
  EXPECT_EQ(d->controls.size(), 2u);
  ASSERT_EQ(d->scans.size(), 1u);
  EXPECT_EQ(d->scans[0].detections.size(), 2u);
  EXPECT_EQ(asked, (std::vector<std::string>{"mem/dataset.json", "mem/c.dat", "mem/o.dat"}));
  files["mem/o.dat"] = "0.1 5 0.2\n0.2 x 0.3\n";
  d = ReadDataset("mem", read);
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.status().message().find("mem/o.dat:2: field 'range'"), std::string::npos) << d.status();
}

TEST_F(MalformedDataset, BadTruthIdAndRange) {
  Write("o.dat", "0.1 5 0.2 2.5\n");
  ExpectError({"o.dat:1", "'truth_id'"});
  Write("o.dat", "0.1 -5 0.2 2\n");
  ExpectError({"o.dat:1", "'range'", "must be > 0"});
}

TEST_F(MalformedDataset, DuplicateTruthLandmarkId) {
  Write("dataset.json", R"({"format": "subslam-dataset/1", "name": "tiny",
  "motion": {"model": "unicycle", "controls_file": "c.dat", "sigma_v": 0.1, "sigma_omega": 0.01},
  "sensor": {"type": "range_bearing", "observations_file": "o.dat", "sigma_range": 0.1,
             "sigma_bearing": 0.01, "max_range": 30},
  "ground_truth": {"landmarks_file": "l.dat"}})");
  Write("l.dat", "0 1 2\n1 3 4\n0 5 6\n");
  ExpectError({"l.dat:3", "'id'", "unique"});
}

TEST_F(MalformedDataset, UnknownModelAndSteeringOutOfRange) {
  Write("dataset.json", R"({"format": "subslam-dataset/1", "name": "tiny",
  "motion": {"model": "tricycle", "controls_file": "c.dat", "sigma_v": 0.1},
  "sensor": {"type": "range_bearing", "observations_file": "o.dat", "sigma_range": 0.1,
             "sigma_bearing": 0.01, "max_range": 30}})");
  ExpectError({"motion.model", "tricycle"});
  Write("dataset.json", R"({"format": "subslam-dataset/1", "name": "tiny",
  "motion": {"model": "ackermann", "controls_file": "c.dat", "sigma_v": 0.1, "sigma_steer": 0.01,
             "wheelbase": 2.5},
  "sensor": {"type": "range_bearing", "observations_file": "o.dat", "sigma_range": 0.1,
             "sigma_bearing": 0.01, "max_range": 30}})");
  Write("c.dat", "0 1 0\n0.1 1 2.0\n");
  ExpectError({"c.dat:2", "'steer'"});
}

TEST(ReadTrajectoryCsv, RejectsMalformedLines) {
  const std::string path = ::testing::TempDir() + "/subslam_bad_trajectory.csv";
  ASSERT_TRUE(WriteTextFile(path,
                            "t,x,y,theta,cov_xx,cov_xy,cov_xt,cov_yy,cov_yt,cov_tt\n"
                            "0,1,2,3,1,0,0,1,0,1\n0.1,1,2,3\n")
                  .ok());
  absl::StatusOr<Trajectory> t = ReadTrajectoryCsv(path);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find(":3: expected 10 columns"), std::string::npos) << t.status().message();
  ASSERT_TRUE(WriteTextFile(path, "header\n0,1,x,3,1,0,0,1,0,1\n").ok());
  t = ReadTrajectoryCsv(path);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.status().message().find(":2: column 3"), std::string::npos) << t.status().message();
}

TEST(WriteDataset, RoundTripIsExact) {
  sim::ScenarioOptions options;
  options.seed = 3;
  options.duration_s = 20.0;
  options.detection_probability = 0.7;
  options.false_alarm_probability = 0.02;
  options.with_signature = true;
  absl::StatusOr<Dataset> d = sim::SimulateScenario("hybrid-120m", options);
  ASSERT_TRUE(d.ok()) << d.status();
  const std::string dir = ::testing::TempDir() + "/subslam_roundtrip";
  ASSERT_TRUE(WriteDataset(*d, dir).ok());
  absl::StatusOr<Dataset> back = ReadDataset(dir);
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->controls.size(), d->controls.size());
  ASSERT_EQ(back->scans.size(), d->scans.size());
  for (size_t i = 0; i < d->controls.size(); ++i) {
    EXPECT_EQ(back->controls[i].t, d->controls[i].t);
    EXPECT_EQ(back->controls[i].u, d->controls[i].u);
  }
  for (size_t i = 0; i < d->scans.size(); ++i) {
    ASSERT_EQ(back->scans[i].detections.size(), d->scans[i].detections.size());
    for (size_t j = 0; j < d->scans[i].detections.size(); ++j) {
      EXPECT_EQ(back->scans[i].detections[j].range_m, d->scans[i].detections[j].range_m);
      EXPECT_EQ(back->scans[i].detections[j].bearing_rad, d->scans[i].detections[j].bearing_rad);
      EXPECT_EQ(back->scans[i].detections[j].truth_id, d->scans[i].detections[j].truth_id);
      EXPECT_EQ(back->scans[i].detections[j].signature, d->scans[i].detections[j].signature);
    }
  }
  EXPECT_EQ(back->truth_poses.size(), d->truth_poses.size());
  EXPECT_EQ(back->truth_landmarks.size(), d->truth_landmarks.size());
  EXPECT_EQ(back->motion.noise.scale_u1, d->motion.noise.scale_u1);
}

TEST(BuildSteps, MergesControlsAndScansInTimeOrder) {
  Dataset d;
  d.controls = {{0.0, {1, 0}}, {1.0, {2, 0}}, {2.0, {3, 0}}};
  d.scans = {{0.5, {}}, {1.0, {}}};
  const std::vector<Step> steps = BuildSteps(d);
  ASSERT_EQ(steps.size(), 4u);
  EXPECT_EQ(steps[0].t, 0.0);
  EXPECT_EQ(steps[1].t, 0.5);
  EXPECT_EQ(steps[1].control[0], 1.0);  // active over (0, 0.5]
  EXPECT_EQ(steps[1].scan_index, 0);
  EXPECT_EQ(steps[2].t, 1.0);
  EXPECT_EQ(steps[2].dt, 0.5);
  EXPECT_EQ(steps[2].control[0], 1.0);  // the control at t = 1 applies from then on
  EXPECT_EQ(steps[2].scan_index, 1);
  EXPECT_EQ(steps[3].control[0], 2.0);
}

}  // namespace
}  // namespace subslam::io
