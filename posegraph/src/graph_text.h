// Internal to the graph formats (graph_format.h): one data line split into its fields
// with errors that name the file, line and field; noise numbers to and from information
// matrices under each convention; numbers written to read back exactly.
#ifndef SUBSLAM_POSEGRAPH_SRC_GRAPH_TEXT_H_
#define SUBSLAM_POSEGRAPH_SRC_GRAPH_TEXT_H_

#include <Eigen/Core>
#include <array>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "subslam/posegraph/graph_format.h"

namespace subslam::posegraph::internal {

class GraphLine {
 public:
  GraphLine(absl::string_view source, int line_number, std::vector<absl::string_view> fields)
      : source_(source), line_(line_number), fields_(std::move(fields)) {}

  absl::string_view tag() const { return fields_.front(); }
  // The line must hold the tag and exactly these fields (names for the errors).
  absl::Status Expect(std::initializer_list<const char*> names);
  // Fields after the tag, 1-based: an integer id, a finite number.
  absl::StatusOr<long> Id(int field) const;
  absl::StatusOr<double> Number(int field) const;
  // Fields 1 and 2 as ids (an edge's two ends).
  absl::StatusOr<std::pair<long, long>> EdgeIds() const;
  // Fields first … first + count − 1 as numbers.
  absl::StatusOr<std::vector<double>> Numbers(int first, int count) const;
  // The n × n information of the n(n+1)/2 noise numbers from field `first` (upper
  // triangle row by row) under `noise`.
  absl::StatusOr<Eigen::MatrixXd> Information(int first, int n, NoiseConvention noise) const;
  // An error at this line: "SOURCE:LINE: TAG: message".
  absl::Status Error(absl::string_view message) const;
  absl::Status FieldError(int field, absl::string_view message) const;
  int size() const { return static_cast<int>(fields_.size()) - 1; }  // fields after the tag

 private:
  absl::string_view source_;
  int line_ = 0;
  std::vector<absl::string_view> fields_;
  std::vector<const char*> names_;
};

// Splits text into data lines (blank lines and '#' comments skipped) and calls
// `parse` on each until one fails.
template <typename Parse>
absl::Status ForEachLine(absl::string_view text, absl::string_view source, Parse&& parse);

// The information matrix of n×n noise numbers given as the upper triangle row by row
// (`upper`, n(n+1)/2 values) under `noise`: information as is, covariance inverted,
// square-root information R (upper triangular) as RᵀR. Not symmetric positive definite:
// an error (the caller adds the line).
absl::StatusOr<Eigen::MatrixXd> InformationFromUpperTriangle(const std::vector<double>& upper, int n,
                                                             NoiseConvention noise);
// The upper triangle, row by row, of `information` under `noise` (the inverse of the above).
std::vector<double> UpperTriangleFromInformation(const Eigen::MatrixXd& information, NoiseConvention noise);

// The shortest decimal form that reads back to the same double.
std::string FormatNumber(double value);
void AppendNumbers(std::string* out, std::initializer_list<double> values);
void AppendNumbers(std::string* out, const std::vector<double>& values);
// One measurement line: "TAG a b z… noise…\n", the noise numbers being the upper
// triangle of `information` under `noise`.
void AppendMeasurementLine(std::string* out, absl::string_view tag, long a, long b, std::initializer_list<double> z,
                           const Eigen::MatrixXd& information, NoiseConvention noise);

// The measurements in the order the writers put them: each odometry measurement in
// graph order, followed — when it reaches a pose for the first time — by the sightings
// taken from that pose (point, bearing-range, bearing, each in graph order); the first
// pose's sightings lead, those of poses no odometry reaches close. A file written in time
// order (odometry into a pose, then what was seen there) keeps its order.
struct MeasurementRef {
  enum Kind { kOdometry, kPoint, kBearingRange, kBearing } kind;
  int index;
};
std::vector<MeasurementRef> WritingOrder(const PoseGraph& graph);

// A vertex line `TAG id x y [θ]` (Expect already checked): the estimate of pose or point
// `id`, given once. `shared_ids`: poses and points share one id space (g2o), so an id
// already used by the other kind is an error.
absl::Status ParseVertexEstimate(const GraphLine& line, bool pose, bool shared_ids, PoseGraph* graph);

// An odometry line `TAG from to dx dy dθ n…` (6 noise numbers named `noise_names`, in
// the order given by upper_of_noise: noise number k is entry upper_of_noise[k] of the
// upper triangle row by row) added to the graph.
absl::Status ParseOdometryLine(GraphLine& line, const std::array<const char*, 6>& noise_names,
                               const std::array<int, 6>& upper_of_noise, NoiseConvention noise, PoseGraph* graph);

// The readers and writers of each format (GraphLine errors already name the line).
absl::Status ParseG2oLine(GraphLine& line, NoiseConvention noise, PoseGraph* graph);
absl::Status ParseToroLine(GraphLine& line, NoiseConvention noise, PoseGraph* graph);
absl::Status ParseIsamLine(GraphLine& line, NoiseConvention noise, bool gtsam_landmarks, PoseGraph* graph);
absl::StatusOr<std::string> FormatG2o(const PoseGraph& graph, NoiseConvention noise, bool bearing_range_as_points);
absl::StatusOr<std::string> FormatToro(const PoseGraph& graph, NoiseConvention noise);
absl::StatusOr<std::string> FormatIsam(const PoseGraph& graph, NoiseConvention noise, bool gtsam_landmarks);

// --- template definition ---
template <typename Parse>
absl::Status ForEachLine(absl::string_view text, absl::string_view source, Parse&& parse) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; };
  int line_number = 0;
  size_t start = 0;
  while (start <= text.size()) {
    size_t end = text.find('\n', start);
    if (end == absl::string_view::npos) end = text.size();
    const absl::string_view line = text.substr(start, end - start);
    ++line_number;
    std::vector<absl::string_view> fields;
    for (size_t k = 0; k < line.size();) {
      while (k < line.size() && blank(line[k])) ++k;
      size_t e = k;
      while (e < line.size() && !blank(line[e])) ++e;
      if (e > k) fields.push_back(line.substr(k, e - k));
      k = e;
    }
    if (!fields.empty() && fields.front().front() != '#') {
      GraphLine graph_line(source, line_number, std::move(fields));
      if (absl::Status s = parse(graph_line); !s.ok()) return s;
    }
    if (end == text.size()) break;
    start = end + 1;
  }
  return absl::OkStatus();
}

}  // namespace subslam::posegraph::internal

#endif  // SUBSLAM_POSEGRAPH_SRC_GRAPH_TEXT_H_
