#include "subslam/posegraph/pose_graph.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <deque>

#include "absl/strings/str_cat.h"
#include "subslam/posegraph/measurement_residuals.h"

namespace subslam::posegraph {
namespace {

template <typename Matrix>
absl::Status CheckInformation(const Matrix& information, const std::string& what) {
  if (!information.allFinite()) return absl::InvalidArgumentError(absl::StrCat(what, ": information not finite"));
  const double scale = information.cwiseAbs().maxCoeff();
  if (!((information - information.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * scale)) {
    return absl::InvalidArgumentError(absl::StrCat(what, ": information not symmetric"));
  }
  Eigen::LLT<Matrix> llt(information);
  if (scale == 0.0 || llt.info() != Eigen::Success) {
    return absl::InvalidArgumentError(absl::StrCat(what, ": information not positive definite"));
  }
  return absl::OkStatus();
}

// Union-find over poses (0 … P−1) and points (P …).
struct Components {
  std::vector<int> parent;
  explicit Components(int n) : parent(n) {
    for (int i = 0; i < n; ++i) parent[i] = i;
  }
  int Find(int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  }
  void Unite(int a, int b) { parent[Find(a)] = Find(b); }
};

}  // namespace

int PoseGraph::PoseIndex(long id) {
  auto [it, inserted] = pose_index_.try_emplace(id, static_cast<int>(poses.size()));
  if (inserted) poses.push_back(PoseVertex{.id = id, .estimate = Pose2()});
  return it->second;
}

int PoseGraph::PointIndex(long id) {
  auto [it, inserted] = point_index_.try_emplace(id, static_cast<int>(points.size()));
  if (inserted) points.push_back(PointVertex{.id = id, .estimate = Eigen::Vector2d::Zero()});
  return it->second;
}

int PoseGraph::FindPose(long id) const {
  auto it = pose_index_.find(id);
  return it == pose_index_.end() ? -1 : it->second;
}

int PoseGraph::FindPoint(long id) const {
  auto it = point_index_.find(id);
  return it == point_index_.end() ? -1 : it->second;
}

void PoseGraph::ClearPoints() {
  points.clear();
  point_index_.clear();
  point_measurements.clear();
  bearing_range_measurements.clear();
  bearing_measurements.clear();
}

bool PoseGraph::HasEstimates() const {
  for (const PoseVertex& p : poses) {
    if (!p.has_estimate) return false;
  }
  for (const PointVertex& p : points) {
    if (!p.has_estimate) return false;
  }
  return true;
}

std::vector<int> PoseGraph::GaugePoses() const {
  std::vector<int> gauge;
  for (int i = 0; i < static_cast<int>(poses.size()); ++i) {
    if (poses[i].fixed) gauge.push_back(i);
  }
  if (gauge.empty() && !poses.empty()) gauge.push_back(0);
  return gauge;
}

absl::Status PoseGraph::Validate() const {
  const int num_poses = static_cast<int>(poses.size()), num_points = static_cast<int>(points.size());
  if (num_poses == 0) return absl::InvalidArgumentError("the graph has no pose");
  for (const PoseVertex& p : poses) {
    if (!std::isfinite(p.estimate.x) || !std::isfinite(p.estimate.y) || !std::isfinite(p.estimate.theta)) {
      return absl::InvalidArgumentError(absl::StrCat("pose ", p.id, ": estimate not finite"));
    }
  }
  for (const PointVertex& p : points) {
    if (!p.estimate.allFinite())
      return absl::InvalidArgumentError(absl::StrCat("point ", p.id, ": estimate not finite"));
  }
  Components components(num_poses + num_points);
  const auto pose_ok = [&](int i) { return i >= 0 && i < num_poses; };
  const auto point_ok = [&](int i) { return i >= 0 && i < num_points; };
  for (const OdometryMeasurement& m : odometry) {
    if (!pose_ok(m.from) || !pose_ok(m.to)) return absl::InvalidArgumentError("odometry: pose index out of range");
    const std::string what = absl::StrCat("odometry ", poses[m.from].id, " -> ", poses[m.to].id);
    if (m.from == m.to) return absl::InvalidArgumentError(what + ": from a pose to itself");
    if (!std::isfinite(m.z.x) || !std::isfinite(m.z.y) || !std::isfinite(m.z.theta)) {
      return absl::InvalidArgumentError(what + ": measurement not finite");
    }
    if (absl::Status s = CheckInformation(m.information, what); !s.ok()) return s;
    components.Unite(m.from, m.to);
  }
  const auto check_sighting = [&](int pose, int point, const char* kind) -> absl::StatusOr<std::string> {
    if (!pose_ok(pose) || !point_ok(point)) {
      return absl::InvalidArgumentError(absl::StrCat(kind, ": index out of range"));
    }
    components.Unite(pose, num_poses + point);
    return absl::StrCat(kind, " ", poses[pose].id, " -> ", points[point].id);
  };
  for (const PointMeasurement& m : point_measurements) {
    auto what = check_sighting(m.pose, m.point, "point measurement");
    if (!what.ok()) return what.status();
    if (!m.z.allFinite()) return absl::InvalidArgumentError(*what + ": measurement not finite");
    if (absl::Status s = CheckInformation(m.information, *what); !s.ok()) return s;
  }
  for (const BearingRangeMeasurement& m : bearing_range_measurements) {
    auto what = check_sighting(m.pose, m.point, "bearing-range measurement");
    if (!what.ok()) return what.status();
    if (!std::isfinite(m.bearing) || !std::isfinite(m.range)) {
      return absl::InvalidArgumentError(*what + ": measurement not finite");
    }
    if (!(m.range > 0.0)) return absl::InvalidArgumentError(*what + ": range not positive");
    if (absl::Status s = CheckInformation(m.information, *what); !s.ok()) return s;
  }
  for (const BearingMeasurement& m : bearing_measurements) {
    auto what = check_sighting(m.pose, m.point, "bearing measurement");
    if (!what.ok()) return what.status();
    if (!std::isfinite(m.bearing)) return absl::InvalidArgumentError(*what + ": measurement not finite");
    if (!(m.information > 0.0) || !std::isfinite(m.information)) {
      return absl::InvalidArgumentError(*what + ": information not positive");
    }
  }
  std::vector<bool> gauge_component(num_poses + num_points, false);
  for (int g : GaugePoses()) gauge_component[components.Find(g)] = true;
  for (int i = 0; i < num_poses; ++i) {
    if (!gauge_component[components.Find(i)]) {
      return absl::InvalidArgumentError(
          absl::StrCat("pose ", poses[i].id, " is not connected to a fixed pose (the first pose when none is fixed)"));
    }
  }
  for (int i = 0; i < num_points; ++i) {
    if (!gauge_component[components.Find(num_poses + i)]) {
      return absl::InvalidArgumentError(absl::StrCat("point ", points[i].id, " is not connected to a fixed pose"));
    }
  }
  return absl::OkStatus();
}

GraphError EvaluateError(const PoseGraph& graph) {
  double chi2 = 0.0;
  for (const OdometryMeasurement& m : graph.odometry) {
    const Eigen::Vector3d r = OdometryResidual(m.z, graph.poses[m.from].estimate, graph.poses[m.to].estimate);
    chi2 += r.dot(m.information * r);
  }
  for (const PointMeasurement& m : graph.point_measurements) {
    const Eigen::Vector2d r = PointResidual(m.z, graph.poses[m.pose].estimate, graph.points[m.point].estimate);
    chi2 += r.dot(m.information * r);
  }
  for (const BearingRangeMeasurement& m : graph.bearing_range_measurements) {
    const Eigen::Vector2d r =
        BearingRangeResidual(m.bearing, m.range, graph.poses[m.pose].estimate, graph.points[m.point].estimate);
    chi2 += r.dot(m.information * r);
  }
  for (const BearingMeasurement& m : graph.bearing_measurements) {
    const double r = BearingResidual(m.bearing, graph.poses[m.pose].estimate, graph.points[m.point].estimate);
    chi2 += m.information * r * r;
  }
  return {0.5 * chi2, chi2};
}

absl::Status InitializeByDeadReckoning(PoseGraph* graph) {
  const int num_poses = static_cast<int>(graph->poses.size());
  std::vector<std::vector<int>> edges_of_pose(num_poses);
  for (int e = 0; e < static_cast<int>(graph->odometry.size()); ++e) {
    edges_of_pose[graph->odometry[e].from].push_back(e);
    edges_of_pose[graph->odometry[e].to].push_back(e);
  }
  std::vector<bool> reached(num_poses, false);
  std::deque<int> queue;
  for (int g : graph->GaugePoses()) {
    if (!graph->poses[g].has_estimate) graph->poses[g].estimate = Pose2();
    reached[g] = true;
    queue.push_back(g);
  }
  while (!queue.empty()) {
    const int i = queue.front();
    queue.pop_front();
    for (int e : edges_of_pose[i]) {
      const OdometryMeasurement& m = graph->odometry[e];
      const int other = m.from == i ? m.to : m.from;
      if (reached[other]) continue;
      const Pose2& here = graph->poses[i].estimate;
      graph->poses[other].estimate = m.from == i ? Compose(here, m.z) : Compose(here, Inverse(m.z));
      reached[other] = true;
      queue.push_back(other);
    }
  }
  for (int i = 0; i < num_poses; ++i) {
    if (!reached[i]) {
      return absl::InvalidArgumentError(absl::StrCat("dead reckoning: no odometry reaches pose ", graph->poses[i].id));
    }
  }
  const int num_points = static_cast<int>(graph->points.size());
  std::vector<bool> placed(num_points, false);
  for (const PointMeasurement& m : graph->point_measurements) {
    if (placed[m.point]) continue;
    graph->points[m.point].estimate = TransformFrom(graph->poses[m.pose].estimate, m.z);
    placed[m.point] = true;
  }
  for (const BearingRangeMeasurement& m : graph->bearing_range_measurements) {
    if (placed[m.point]) continue;
    const Eigen::Vector2d z(m.range * std::cos(m.bearing), m.range * std::sin(m.bearing));
    graph->points[m.point].estimate = TransformFrom(graph->poses[m.pose].estimate, z);
    placed[m.point] = true;
  }
  // Bearing-only points: the point closest to every bearing line in the least-squares
  // sense, Σ (I − d dᵀ)(p − o) = 0 over the lines (origin o, unit direction d).
  std::vector<Eigen::Matrix2d> A(num_points, Eigen::Matrix2d::Zero());
  std::vector<Eigen::Vector2d> b(num_points, Eigen::Vector2d::Zero());
  for (const BearingMeasurement& m : graph->bearing_measurements) {
    if (placed[m.point]) continue;
    const Pose2& pose = graph->poses[m.pose].estimate;
    const Eigen::Vector2d d(std::cos(pose.theta + m.bearing), std::sin(pose.theta + m.bearing));
    const Eigen::Matrix2d P = Eigen::Matrix2d::Identity() - d * d.transpose();
    A[m.point] += P;
    b[m.point] += P * pose.translation();
  }
  for (int j = 0; j < num_points; ++j) {
    if (placed[j]) continue;
    if (A[j].isZero()) {
      return absl::InvalidArgumentError(absl::StrCat("dead reckoning: point ", graph->points[j].id, " is never seen"));
    }
    const Eigen::FullPivLU<Eigen::Matrix2d> lu(A[j]);
    if (lu.rank() < 2 || A[j].determinant() < 1e-9 * A[j].squaredNorm()) {
      return absl::InvalidArgumentError(absl::StrCat("dead reckoning: the bearings to point ", graph->points[j].id,
                                                     " are parallel; it cannot be placed"));
    }
    graph->points[j].estimate = lu.solve(b[j]);
  }
  return absl::OkStatus();
}

}  // namespace subslam::posegraph
