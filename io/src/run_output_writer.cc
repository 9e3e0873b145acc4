#include "subslam/io/run_output_writer.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "subslam/io/text_table.h"

namespace subslam::io {

absl::Status WriteTextFile(const std::string& path, const std::string& content) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return absl::PermissionDeniedError(absl::StrCat(path, ": cannot open for writing"));
  out << content;
  out.close();
  if (!out) return absl::DataLossError(absl::StrCat(path, ": write failed"));
  return absl::OkStatus();
}

namespace {

// The per-step files (a trajectory per step of a run: 70,000 rows on Victoria Park) are
// written with std::to_chars, which gives printf's "%.6f" and "%.10g" to the character
// (in the C locale) at a fraction of a formatting library's cost.
void AppendFixed6(double v, std::string* text) {
  char buffer[64];
  text->append(buffer, std::to_chars(buffer, buffer + sizeof(buffer), v, std::chars_format::fixed, 6).ptr);
}

void AppendGeneral10(double v, std::string* text) {
  char buffer[64];
  text->append(buffer, std::to_chars(buffer, buffer + sizeof(buffer), v, std::chars_format::general, 10).ptr);
}

// t (%.6f), then each value (%.10g), separated by `separator`, and a newline.
void AppendRow(double t, std::initializer_list<double> values, char separator, std::string* text) {
  AppendFixed6(t, text);
  for (double v : values) {
    text->push_back(separator);
    AppendGeneral10(v, text);
  }
  text->push_back('\n');
}

}  // namespace

absl::Status WriteTrajectoryCsv(const std::string& path, const Trajectory& trajectory) {
  std::string text = "t,x,y,theta,cov_xx,cov_xy,cov_xt,cov_yy,cov_yt,cov_tt\n";
  text.reserve(trajectory.size() * 160);
  for (const PoseEstimate& p : trajectory) {
    const Eigen::Matrix3d& c = p.covariance;
    AppendRow(p.t, {p.pose.x, p.pose.y, p.pose.theta, c(0, 0), c(0, 1), c(0, 2), c(1, 1), c(1, 2), c(2, 2)}, ',',
              &text);
  }
  return WriteTextFile(path, text);
}

absl::Status WriteLandmarksCsv(const std::string& path, const std::vector<LandmarkEstimate>& landmarks) {
  std::string text = "id,x,y,cov_xx,cov_xy,cov_yy\n";
  for (const LandmarkEstimate& l : landmarks) {
    absl::StrAppendFormat(&text, "%d,%.10g,%.10g,%.10g,%.10g,%.10g\n", l.id, l.position.x(), l.position.y(),
                          l.covariance(0, 0), l.covariance(0, 1), l.covariance(1, 1));
  }
  return WriteTextFile(path, text);
}

namespace {

void AppendTumPose(double t, const Pose2& pose, std::string* text) {
  AppendRow(t, {pose.x, pose.y, 0.0, 0.0, 0.0, std::sin(pose.theta / 2), std::cos(pose.theta / 2)}, ' ', text);
}

}  // namespace

absl::Status WriteTumTrajectory(const std::string& path, const Trajectory& trajectory) {
  std::string text;
  text.reserve(trajectory.size() * 80);
  for (const PoseEstimate& p : trajectory) AppendTumPose(p.t, p.pose, &text);
  return WriteTextFile(path, text);
}

absl::Status WriteTumTrajectory(const std::string& path, const std::vector<TimedPose>& poses) {
  std::string text;
  text.reserve(poses.size() * 80);
  for (const TimedPose& p : poses) AppendTumPose(p.t, p.pose, &text);
  return WriteTextFile(path, text);
}

absl::Status WriteTruthTrajectoryCsv(const std::string& path, const std::vector<TimedPose>& poses) {
  std::string text = "t,x,y,theta\n";
  text.reserve(poses.size() * 60);
  for (const TimedPose& p : poses) AppendRow(p.t, {p.pose.x, p.pose.y, p.pose.theta}, ',', &text);
  return WriteTextFile(path, text);
}

absl::Status WriteTruthLandmarksCsv(const std::string& path, const std::vector<TruthLandmark>& landmarks) {
  std::string text = "id,x,y\n";
  for (const TruthLandmark& l : landmarks) absl::StrAppendFormat(&text, "%d,%.10g,%.10g\n", l.id, l.p.x(), l.p.y());
  return WriteTextFile(path, text);
}

absl::Status WriteGpsCsv(const std::string& path, const std::vector<TimedPoint>& fixes,
                         const std::vector<bool>& rejected) {
  std::string text = "t,x,y,rejected\n";
  for (size_t i = 0; i < fixes.size(); ++i) {
    absl::StrAppendFormat(&text, "%.6f,%.10g,%.10g,%d\n", fixes[i].t, fixes[i].p.x(), fixes[i].p.y(),
                          i < rejected.size() && rejected[i] ? 1 : 0);
  }
  return WriteTextFile(path, text);
}

absl::StatusOr<Trajectory> ReadTrajectoryCsv(const std::string& path) {
  auto text = ReadFileToString(path);
  if (!text.ok()) return text.status();
  Trajectory out;
  int line_number = 0;
  for (absl::string_view line : absl::StrSplit(*text, '\n', absl::SkipEmpty())) {
    ++line_number;
    if (line_number == 1) continue;  // header
    std::vector<absl::string_view> f = absl::StrSplit(line, ',');
    if (f.size() != 10) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ":", line_number, ": expected 10 columns, found ", f.size()));
    }
    double v[10];
    for (int i = 0; i < 10; ++i) {
      if (!absl::SimpleAtod(f[i], &v[i])) {
        return absl::InvalidArgumentError(absl::StrCat(path, ":", line_number, ": column ", i + 1, " is not a number"));
      }
    }
    PoseEstimate p;
    p.t = v[0];
    p.pose = Pose2(v[1], v[2], v[3]);
    p.covariance << v[4], v[5], v[6], v[5], v[7], v[8], v[6], v[8], v[9];
    out.push_back(p);
  }
  return out;
}

}  // namespace subslam::io
