#include "graph_text.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <charconv>
#include <cmath>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"

namespace subslam::posegraph::internal {

absl::Status GraphLine::Expect(std::initializer_list<const char*> names) {
  names_.assign(names.begin(), names.end());
  const int want = static_cast<int>(names_.size());
  if (size() < want) {
    return Error(absl::StrCat("missing field '", names_[size()], "' (field ", size() + 1, " of ", want, ")"));
  }
  if (size() > want) {
    return Error(
        absl::StrCat(size() - want, " field(s) beyond the ", want, " expected, from '", fields_[want + 1], "'"));
  }
  return absl::OkStatus();
}

absl::Status GraphLine::Error(absl::string_view message) const {
  return absl::InvalidArgumentError(absl::StrCat(source_, ":", line_, ": ", fields_.front(), ": ", message));
}

absl::Status GraphLine::FieldError(int field, absl::string_view message) const {
  const std::string name = field - 1 < static_cast<int>(names_.size()) ? names_[field - 1] : "?";
  return Error(absl::StrCat("field '", name, "' (field ", field, ") ", message));
}

absl::StatusOr<long> GraphLine::Id(int field) const {
  long id = 0;
  if (!absl::SimpleAtoi(fields_[field], &id)) {
    return FieldError(field, absl::StrCat("is not an integer id: '", fields_[field], "'"));
  }
  if (id < 0) return FieldError(field, absl::StrCat("is a negative id: ", id));
  return id;
}

absl::StatusOr<double> GraphLine::Number(int field) const {
  double value = 0.0;
  if (!absl::SimpleAtod(fields_[field], &value)) {
    return FieldError(field, absl::StrCat("is not a number: '", fields_[field], "'"));
  }
  if (!std::isfinite(value)) return FieldError(field, absl::StrCat("is not finite: '", fields_[field], "'"));
  return value;
}

absl::StatusOr<std::pair<long, long>> GraphLine::EdgeIds() const {
  auto a = Id(1);
  if (!a.ok()) return a.status();
  auto b = Id(2);
  if (!b.ok()) return b.status();
  return std::pair<long, long>(*a, *b);
}

absl::StatusOr<std::vector<double>> GraphLine::Numbers(int first, int count) const {
  std::vector<double> values;
  for (int f = first; f < first + count; ++f) {
    auto v = Number(f);
    if (!v.ok()) return v.status();
    values.push_back(*v);
  }
  return values;
}

absl::StatusOr<Eigen::MatrixXd> GraphLine::Information(int first, int n, NoiseConvention noise) const {
  auto upper = Numbers(first, n * (n + 1) / 2);
  if (!upper.ok()) return upper.status();
  auto information = InformationFromUpperTriangle(*upper, n, noise);
  if (!information.ok()) return Error(absl::StrCat("noise: ", information.status().message()));
  return information;
}

absl::Status ParseVertexEstimate(const GraphLine& line, bool pose, bool shared_ids, PoseGraph* graph) {
  auto id = line.Id(1);
  if (!id.ok()) return id.status();
  if (shared_ids && (pose ? graph->FindPoint(*id) : graph->FindPose(*id)) >= 0) {
    return line.FieldError(1,
                           absl::StrCat("names ", pose ? "point " : "pose ", *id, ", not a ", pose ? "pose" : "point"));
  }
  auto v = line.Numbers(2, pose ? 3 : 2);
  if (!v.ok()) return v.status();
  const int index = pose ? graph->PoseIndex(*id) : graph->PointIndex(*id);
  bool& has_estimate = pose ? graph->poses[index].has_estimate : graph->points[index].has_estimate;
  if (has_estimate) return line.FieldError(1, absl::StrCat("vertex ", *id, " is defined twice"));
  has_estimate = true;
  if (pose) {
    graph->poses[index].estimate = Pose2((*v)[0], (*v)[1], (*v)[2]);
  } else {
    graph->points[index].estimate = Eigen::Vector2d((*v)[0], (*v)[1]);
  }
  return absl::OkStatus();
}

absl::Status ParseOdometryLine(GraphLine& line, const std::array<const char*, 6>& noise_names,
                               const std::array<int, 6>& upper_of_noise, NoiseConvention noise, PoseGraph* graph) {
  const auto& n = noise_names;
  if (absl::Status s = line.Expect({"from", "to", "dx", "dy", "dtheta", n[0], n[1], n[2], n[3], n[4], n[5]}); !s.ok()) {
    return s;
  }
  auto ids = line.EdgeIds();
  if (!ids.ok()) return ids.status();
  const auto [a, b] = *ids;
  if (a == b) return line.Error("an edge from a pose to itself");
  auto z = line.Numbers(3, 3);
  if (!z.ok()) return z.status();
  auto given = line.Numbers(6, 6);
  if (!given.ok()) return given.status();
  std::vector<double> upper(6);
  for (int k = 0; k < 6; ++k) upper[upper_of_noise[k]] = (*given)[k];
  auto information = InformationFromUpperTriangle(upper, 3, noise);
  if (!information.ok()) return line.Error(absl::StrCat("noise: ", information.status().message()));
  graph->odometry.push_back({graph->PoseIndex(a), graph->PoseIndex(b), Pose2((*z)[0], (*z)[1], (*z)[2]), *information});
  return absl::OkStatus();
}

absl::StatusOr<Eigen::MatrixXd> InformationFromUpperTriangle(const std::vector<double>& upper, int n,
                                                             NoiseConvention noise) {
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n);
  int k = 0;
  for (int i = 0; i < n; ++i) {
    for (int j = i; j < n; ++j) {
      M(i, j) = upper[k++];
      if (noise != NoiseConvention::kSqrtInformation) M(j, i) = M(i, j);
    }
  }
  Eigen::MatrixXd information;
  switch (noise) {
    case NoiseConvention::kInformation:
      information = M;
      break;
    case NoiseConvention::kSqrtInformation:
      for (int i = 0; i < n; ++i) {
        if (M(i, i) == 0.0) return absl::InvalidArgumentError("square-root information is singular (a zero diagonal)");
      }
      information = M.transpose() * M;
      break;
    case NoiseConvention::kCovariance: {
      Eigen::LLT<Eigen::MatrixXd> llt(M);
      if (llt.info() != Eigen::Success) return absl::InvalidArgumentError("covariance not positive definite");
      information = llt.solve(Eigen::MatrixXd::Identity(n, n));
      information = 0.5 * (information + information.transpose()).eval();
      break;
    }
  }
  Eigen::LLT<Eigen::MatrixXd> llt(information);
  if (!information.allFinite() || llt.info() != Eigen::Success) {
    return absl::InvalidArgumentError(absl::StrCat(ToString(noise), " not positive definite"));
  }
  return information;
}

std::vector<double> UpperTriangleFromInformation(const Eigen::MatrixXd& information, NoiseConvention noise) {
  const int n = static_cast<int>(information.rows());
  Eigen::MatrixXd M;
  switch (noise) {
    case NoiseConvention::kInformation:
      M = information;
      break;
    case NoiseConvention::kSqrtInformation:
      M = Eigen::LLT<Eigen::MatrixXd>(information).matrixU();
      break;
    case NoiseConvention::kCovariance:
      M = Eigen::LLT<Eigen::MatrixXd>(information).solve(Eigen::MatrixXd::Identity(n, n));
      break;
  }
  std::vector<double> upper;
  for (int i = 0; i < n; ++i) {
    for (int j = i; j < n; ++j) upper.push_back(M(i, j));
  }
  return upper;
}

std::string FormatNumber(double value) {
  if (value == 0.0) return "0";  // also -0
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

void AppendNumbers(std::string* out, std::initializer_list<double> values) {
  for (double v : values) absl::StrAppend(out, " ", FormatNumber(v));
}

void AppendNumbers(std::string* out, const std::vector<double>& values) {
  for (double v : values) absl::StrAppend(out, " ", FormatNumber(v));
}

void AppendMeasurementLine(std::string* out, absl::string_view tag, long a, long b, std::initializer_list<double> z,
                           const Eigen::MatrixXd& information, NoiseConvention noise) {
  absl::StrAppend(out, tag, " ", a, " ", b);
  AppendNumbers(out, z);
  AppendNumbers(out, UpperTriangleFromInformation(information, noise));
  *out += '\n';
}

std::vector<MeasurementRef> WritingOrder(const PoseGraph& graph) {
  const int num_poses = static_cast<int>(graph.poses.size());
  std::vector<std::vector<MeasurementRef>> sightings(num_poses);
  for (int i = 0; i < static_cast<int>(graph.point_measurements.size()); ++i) {
    sightings[graph.point_measurements[i].pose].push_back({MeasurementRef::kPoint, i});
  }
  for (int i = 0; i < static_cast<int>(graph.bearing_range_measurements.size()); ++i) {
    sightings[graph.bearing_range_measurements[i].pose].push_back({MeasurementRef::kBearingRange, i});
  }
  for (int i = 0; i < static_cast<int>(graph.bearing_measurements.size()); ++i) {
    sightings[graph.bearing_measurements[i].pose].push_back({MeasurementRef::kBearing, i});
  }
  std::vector<MeasurementRef> order;
  std::vector<bool> written(num_poses, false);
  const auto write_sightings = [&](int pose) {
    if (written[pose]) return;
    written[pose] = true;
    order.insert(order.end(), sightings[pose].begin(), sightings[pose].end());
  };
  if (num_poses > 0) write_sightings(0);
  for (int i = 0; i < static_cast<int>(graph.odometry.size()); ++i) {
    order.push_back({MeasurementRef::kOdometry, i});
    write_sightings(graph.odometry[i].to);
  }
  for (int pose = 0; pose < num_poses; ++pose) write_sightings(pose);
  return order;
}

}  // namespace subslam::posegraph::internal
