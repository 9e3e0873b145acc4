#include "subslam/io/submaps_jsonl.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace subslam::io {
namespace {

namespace fs = std::filesystem;

LocalSubmap Map(int id, int n) {
  LocalSubmap s;
  s.id = id;
  s.t_start = 10.0 * id;
  s.t_end = 10.0 * id + 9.975;
  s.mean = Eigen::VectorXd::LinSpaced(3 + 2 * n, 0.1, 3.7);
  s.mean[2] = 1.0 / 3.0;
  const Eigen::MatrixXd A = Eigen::MatrixXd::Random(3 + 2 * n, 3 + 2 * n);
  s.covariance = A * A.transpose() + 0.01 * Eigen::MatrixXd::Identity(3 + 2 * n, 3 + 2 * n);
  for (int i = 0; i < n; ++i) {
    s.landmarks.push_back({7 * i, i % 2 ? NAN : 0.1 * i, 0.96, i % 3 ? std::optional<int>(i) : std::nullopt,
                           i % 3 ? std::optional<int>(1 + i % 2) : std::nullopt,
                           i % 3 ? (i % 2 ? std::vector<int>{i, i + 100} : std::vector<int>{i}) : std::vector<int>{}});
  }
  return s;
}

std::string Write(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

TEST(SubmapsJsonl, RoundTripIsBitIdentical) {
  const std::vector<LocalSubmap> maps = {Map(0, 0), Map(1, 3), Map(2, 5)};
  const std::string path = ::testing::TempDir() + "/submaps_round_trip.jsonl";
  ASSERT_TRUE(WriteSubmapsJsonl(path, maps).ok());
  absl::StatusOr<std::vector<LocalSubmap>> back = ReadSubmapsJsonl(path);
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->size(), maps.size());
  for (size_t k = 0; k < maps.size(); ++k) {
    EXPECT_EQ((*back)[k].id, maps[k].id);
    EXPECT_EQ((*back)[k].t_end, maps[k].t_end);
    EXPECT_EQ((*back)[k].mean, maps[k].mean);
    EXPECT_EQ((*back)[k].covariance, maps[k].covariance);
    ASSERT_EQ((*back)[k].landmarks.size(), maps[k].landmarks.size());
    for (size_t i = 0; i < maps[k].landmarks.size(); ++i) {
      const LocalSubmapLandmark &a = (*back)[k].landmarks[i], &b = maps[k].landmarks[i];
      EXPECT_EQ(a.local_id, b.local_id);
      EXPECT_EQ(std::isnan(a.signature), std::isnan(b.signature));
      if (!std::isnan(b.signature)) {
        EXPECT_EQ(a.signature, b.signature);
      }
      EXPECT_EQ(a.truth_id, b.truth_id);
      EXPECT_EQ(a.truth_landmarks, b.truth_landmarks);
      EXPECT_EQ(a.truth_ids, b.truth_ids);
    }
  }
}

// Local maps as other tools write them: no times (absent or null), and a degenerate
// covariance (zero: the robot stood still) regularised by the documented rule and counted.
TEST(SubmapsJsonl, AcceptsMissingTimesAndRegularizesADegenerateCovariance) {
  const std::string text =
      R"({"id":0,"t_start":0,"t_end":2.5,"state":[1,2,0.1],"cov":[1,0,0,0,1,0,0,0,1],"landmarks":[]})"
      "\n"
      R"({"id":1,"t_start":null,"t_end":null,"state":[1,0,0],"cov":[1,0,0,0,1,0,0,0,1],"landmarks":[]})"
      "\n"
      R"({"id":2,"state":[0,0,0],"cov":[0,0,0,0,0,0,0,0,0],"landmarks":[]})"
      "\n";
  absl::StatusOr<std::vector<LocalSubmap>> r = ReadSubmapsJsonl(Write("other_tools.jsonl", text));
  ASSERT_TRUE(r.ok()) << r.status();
  ASSERT_EQ(r->size(), 3u);
  EXPECT_EQ((*r)[1].t_start, 2.5);
  EXPECT_EQ((*r)[1].t_end, 2.5);
  EXPECT_EQ((*r)[2].t_start, 2.5);
  EXPECT_EQ((*r)[0].covariance_repairs, 0);
  EXPECT_EQ((*r)[2].covariance_repairs, 1);
  EXPECT_EQ((*r)[2].covariance(0, 0), LocalSubmap::kRegularizationVariance);
  EXPECT_EQ((*r)[2].covariance(0, 1), 0.0);
  // One time without the other is an error; an indefinite covariance is not "degenerate".
  const std::string half = R"({"id":0,"t_start":1,"state":[0,0,0],"cov":[1,0,0,0,1,0,0,0,1],"landmarks":[]})";
  absl::StatusOr<std::vector<LocalSubmap>> bad = ReadSubmapsJsonl(Write("half.jsonl", half + "\n"));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("field 't_end': missing while the other time is given"), std::string::npos)
      << bad.status();
}

// Each malformed line is reported with the file, the line and the field.
TEST(SubmapsJsonl, RejectsMalformedInputWithFileLineAndField) {
  // A line whose one landmark is `landmark` (a JSON object), all else valid.
  const auto OneLandmark = [](const std::string& landmark) {
    return R"({"id":0,"t_start":0,"t_end":1,"state":[1,2,0.1,4,5],"cov":[1,0,0,0,0, 0,1,0,0,0, 0,0,1,0,0, 0,0,0,1,0, 0,0,0,0,1],"landmarks":[)" +
           landmark + "]}";
  };
  const std::string good = OneLandmark(R"({"local_id":3,"signature":null,"existence":0.99,"truth_id":null})");
  ASSERT_TRUE(ReadSubmapsJsonl(Write("good.jsonl", good + "\n")).ok());
  struct Case {
    std::string text;
    std::string expect;  // substring of the error
  };
  const std::vector<Case> cases = {
      {"", "empty"},
      {good + "\n{not json\n", ":2: field '(line)': invalid JSON"},
      // Found by fuzzing (scripts/fuzz.sh): a number beyond a double's range once escaped
      // the reader as an exception.
      {R"({"id":0,"t_start":0,"t_end":1,"state":[1,2,-2.1e803665060896854],"cov":[1,0,0,0,1,0,0,0,1],"landmarks":[]})",
       ":1: field '(line)': invalid JSON: [json.exception.out_of_range.406] number overflow"},
      {R"({"id":0,"t_start":0,"t_end":1,"state":[1,2,0.1],"cov":[1,0,0,0,1,0,0,0,1]})", "field 'landmarks': missing"},
      {R"({"id":0,"t_start":0,"t_end":1,"state":[1,2,0.1,4],"cov":[1,0,0,0,1,0,0,0,1],"landmarks":[]})",
       "field 'state': has 4 numbers"},
      {R"({"id":0,"t_start":0,"t_end":1,"state":[1,2,0.1],"cov":[1,0,0,0,-1,0,0,0,1],"landmarks":[]})",
       "not positive definite"},
      {R"({"id":0,"t_start":0,"t_end":1,"state":[1,"x",0.1],"cov":[1,0,0,0,1,0,0,0,1],"landmarks":[]})",
       "field 'state[1]'"},
      {R"({"id":0,"t_start":2,"t_end":1,"state":[1,2,0.1],"cov":[1,0,0,0,1,0,0,0,1],"landmarks":[]})", "field 't_end'"},
      {R"({"id":0,"t_start":0,"t_end":1,"state":[1,2,0.1],"cov":[1,0,0,0,1,0,0,0,1],"landmarks":[],"extra":1})",
       "field 'extra': unknown key"},
      {good + "\n" + good + "\n", ":2: field 'id': ids must increase"},
      {OneLandmark(R"({"local_id":3,"signature":null,"existence":0.99,"truth_id":2,"truth_landmarks":-1})"),
       "field 'landmarks[0].truth_landmarks': must be >= 0"},
      {OneLandmark(R"({"local_id":3,"existence":0.99,"truth_ids":[4,-2]})"),
       "field 'landmarks[0].truth_ids[1]': expected an integer id in [0, 2147483647], got -2"},
      {OneLandmark(R"({"local_id":3,"existence":0.99,"truth_ids":[4,3000000000]})"),
       "field 'landmarks[0].truth_ids[1]': expected an integer id in [0, 2147483647], got 3000000000"},
      {OneLandmark(R"({"local_id":3,"existence":0.99,"truth_ids":[1.5]})"),
       "field 'landmarks[0].truth_ids[0]': expected an integer id in [0, 2147483647], got 1.5"},
      {OneLandmark(R"({"local_id":3,"existence":0.99,"truth_id":5,"truth_ids":[4,6]})"),
       "field 'landmarks[0].truth_ids': does not contain truth_id 5"},
      {OneLandmark(R"({"local_id":3,"existence":0.99,"truth_id":4,"truth_landmarks":1,"truth_ids":[4,6]})"),
       "field 'landmarks[0].truth_ids': lists 2 ids but truth_landmarks is 1"},
      {OneLandmark(R"({"local_id":3,"existence":0.99,"truth_ids":[4,4]})"),
       "field 'landmarks[0].truth_ids[1]': ids must be ascending and distinct"},
      {OneLandmark(R"({"local_id":3,"existence":0.99,"truth_ids":7})"),
       "field 'landmarks[0].truth_ids': expected an array of true ids, got 7"},
      {OneLandmark(R"({"local_id":3,"existence":1.5})"), "landmarks[0].existence"},
  };
  for (size_t k = 0; k < cases.size(); ++k) {
    const std::string path = Write("bad" + std::to_string(k) + ".jsonl", cases[k].text);
    absl::StatusOr<std::vector<LocalSubmap>> r = ReadSubmapsJsonl(path);
    ASSERT_FALSE(r.ok()) << k;
    EXPECT_NE(r.status().message().find(cases[k].expect), std::string::npos) << k << ": " << r.status().message();
    EXPECT_NE(r.status().message().find(path), std::string::npos) << k;
  }
  EXPECT_FALSE(ReadSubmapsJsonl(::testing::TempDir() + "/does_not_exist.jsonl").ok());
}

}  // namespace
}  // namespace subslam::io
