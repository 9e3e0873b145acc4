#include "subslam/posegraph/submap_route.h"

#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <cmath>
#include <memory>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "subslam/backend/tree_joiner.h"
#include "subslam/posegraph/measurement_residuals.h"

namespace subslam::posegraph {
namespace {

// A sighting taken from a pose: a point or a bearing-range measurement.
struct Sighting {
  bool bearing_range = false;
  int index = 0;
};

// One run of the chain: poses first … last, the sightings from first … last − 1 (and
// from last too for the final run).
struct Run {
  int first = 0, last = 0;
  bool final = false;
};

// What one run's Gauss-Newton left: the local map and its poses in the first's frame.
struct RunSolution {
  LocalSubmap submap;
  std::vector<Pose2> poses;  // poses first + 1 … last − 1 (the interior)
  // The interior's conditional mean given the local map's variables: Δinterior =
  // gain · Δ[last pose, points] (the Gaussian's back-substitution, C_ik C_kk⁻¹).
  Eigen::MatrixXd gain;
};

absl::Status CheckRouteApplies(const PoseGraph& graph) {
  if (!graph.bearing_measurements.empty()) {
    return absl::UnimplementedError(
        absl::StrCat("the submap route needs point or bearing-range sightings; the graph has ",
                     graph.bearing_measurements.size(), " bearing-only ones"));
  }
  const int num_poses = static_cast<int>(graph.poses.size());
  if (num_poses < 2) return absl::InvalidArgumentError("the submap route needs at least two poses");
  std::vector<bool> reached(num_poses, false);
  for (const OdometryMeasurement& m : graph.odometry) {
    if (m.to != m.from + 1 || reached[m.to]) {
      return absl::UnimplementedError(
          absl::StrCat("the submap route needs the odometry as a chain through the poses in "
                       "order; measurement ",
                       graph.poses[m.from].id, " -> ", graph.poses[m.to].id, " is not its next step"));
    }
    reached[m.to] = true;
  }
  for (int i = 1; i < num_poses; ++i) {
    if (!reached[i]) return absl::InvalidArgumentError(absl::StrCat("no odometry reaches pose ", graph.poses[i].id));
  }
  const std::vector<int> gauge = graph.GaugePoses();
  if (gauge.size() != 1 || gauge[0] != 0) {
    return absl::UnimplementedError("the submap route holds the first pose fixed, and only it");
  }
  return absl::OkStatus();
}

// One run's least-squares problem in the frame of its first pose (held at the identity):
// the poses after it start from dead reckoning, the points (in order of first sighting) from
// their first sighting. Variables: poses 1 … steps (3 each), then the points (2 each).
class RunProblem {
 public:
  RunProblem(const PoseGraph& graph, const Run& run, const std::vector<int>& odometry_into,
             const std::vector<std::vector<Sighting>>& sightings)
      : graph_(graph), run_(run), odometry_into_(odometry_into), steps_(run.last - run.first) {
    poses.resize(steps_ + 1);  // poses[0]: the first, the identity
    for (int k = 1; k <= steps_; ++k) {
      poses[k] = Compose(poses[k - 1], graph.odometry[odometry_into[run.first + k]].z);
    }
    const int end = run.final ? run.last : run.last - 1;
    for (int p = run.first; p <= end; ++p) {
      for (const Sighting& s : sightings[p]) run_sightings_.push_back({p - run.first, s});
    }
    for (const auto& [k, s] : run_sightings_) {
      const int point =
          s.bearing_range ? graph.bearing_range_measurements[s.index].point : graph.point_measurements[s.index].point;
      if (slot_.contains(point)) continue;
      slot_[point] = static_cast<int>(point_of_slot.size());
      point_of_slot.push_back(point);
      Eigen::Vector2d z;
      if (s.bearing_range) {
        const BearingRangeMeasurement& m = graph.bearing_range_measurements[s.index];
        z = Eigen::Vector2d(m.range * std::cos(m.bearing), m.range * std::sin(m.bearing));
      } else {
        z = graph.point_measurements[s.index].z;
      }
      points.push_back(TransformFrom(poses[k], z));
    }
    H.resize(dim(), dim());
    g.resize(dim());
  }

  int steps() const { return steps_; }
  int num_points() const { return static_cast<int>(points.size()); }
  int dim() const { return 3 * steps_ + 2 * num_points(); }
  int pose_col(int k) const { return 3 * (k - 1); }
  int point_col(int j) const { return 3 * steps_ + 2 * j; }

  // Builds H and g at the current estimate (with_jacobians) and returns the cost ½ Σ rᵀΩr.
  double Linearize(bool with_jacobians) {
    double cost = 0.0;
    if (with_jacobians) {
      H.setZero();
      g.setZero();
    }
    AddOdometry(with_jacobians, &cost);
    AddSightings(with_jacobians, &cost);
    return cost;
  }

  // Moves the estimate by scale · step.
  void Apply(const Eigen::VectorXd& step, double scale) {
    for (int k = 1; k <= steps_; ++k) {
      const Eigen::Vector3d d = scale * step.segment<3>(pose_col(k));
      poses[k] = Pose2(poses[k].x + d.x(), poses[k].y + d.y(), poses[k].theta + d.z());
    }
    for (int j = 0; j < num_points(); ++j) points[j] += scale * step.segment<2>(point_col(j));
  }

  std::vector<Pose2> poses;
  std::vector<Eigen::Vector2d> points;
  std::vector<int> point_of_slot;  // the graph's point index of each point
  Eigen::MatrixXd H;
  Eigen::VectorXd g;

 private:
  void AddOdometry(bool with_jacobians, double* cost) {
    for (int k = 1; k <= steps_; ++k) {
      const OdometryMeasurement& m = graph_.odometry[odometry_into_[run_.first + k]];
      Eigen::Matrix3d J_from, J_to;
      const Eigen::Vector3d r = OdometryResidual(m.z, poses[k - 1], poses[k], &J_from, &J_to);
      *cost += 0.5 * r.dot(m.information * r);
      if (!with_jacobians) continue;
      const int a = pose_col(k);
      H.block<3, 3>(a, a) += J_to.transpose() * m.information * J_to;
      g.segment<3>(a) += J_to.transpose() * m.information * r;
      if (k > 1) {
        const int b = pose_col(k - 1);
        H.block<3, 3>(b, b) += J_from.transpose() * m.information * J_from;
        H.block<3, 3>(b, a) += J_from.transpose() * m.information * J_to;
        H.block<3, 3>(a, b) += J_to.transpose() * m.information * J_from;
        g.segment<3>(b) += J_from.transpose() * m.information * r;
      }
    }
  }

  void AddSightings(bool with_jacobians, double* cost) {
    for (const auto& [k, s] : run_sightings_) {
      Matrix23d J_pose;
      Eigen::Matrix2d J_point, information;
      Eigen::Vector2d r;
      int point;
      if (s.bearing_range) {
        const BearingRangeMeasurement& m = graph_.bearing_range_measurements[s.index];
        point = slot_.at(m.point);
        r = BearingRangeResidual(m.bearing, m.range, poses[k], points[point], &J_pose, &J_point);
        information = m.information;
      } else {
        const PointMeasurement& m = graph_.point_measurements[s.index];
        point = slot_.at(m.point);
        r = PointResidual(m.z, poses[k], points[point], &J_pose, &J_point);
        information = m.information;
      }
      *cost += 0.5 * r.dot(information * r);
      if (!with_jacobians) continue;
      const int c = point_col(point);
      H.block<2, 2>(c, c) += J_point.transpose() * information * J_point;
      g.segment<2>(c) += J_point.transpose() * information * r;
      if (k > 0) {
        const int a = pose_col(k);
        H.block<3, 3>(a, a) += J_pose.transpose() * information * J_pose;
        H.block<3, 2>(a, c) += J_pose.transpose() * information * J_point;
        H.block<2, 3>(c, a) += J_point.transpose() * information * J_pose;
        g.segment<3>(a) += J_pose.transpose() * information * r;
      }
    }
  }

  const PoseGraph& graph_;
  const Run& run_;
  const std::vector<int>& odometry_into_;
  const int steps_;
  std::vector<std::pair<int, Sighting>> run_sightings_;  // (local pose, sighting)
  absl::flat_hash_map<int, int> slot_;                   // the graph's point index -> its point
};

// Gauss-Newton on the run from its start: each step halved while it raises the cost
// (from dead reckoning it seldom has to be), until a step no longer moves the estimate.
// Leaves H factorised in `ldlt` at the solution.
absl::Status MinimizeRun(RunProblem* problem, int id, int max_iterations, Eigen::LDLT<Eigen::MatrixXd>* ldlt) {
  double cost = problem->Linearize(true);
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    ldlt->compute(problem->H);
    if (ldlt->info() != Eigen::Success) {
      return absl::InternalError(absl::StrCat("local map ", id, ": factorisation failed"));
    }
    const Eigen::VectorXd step = -ldlt->solve(problem->g);
    const std::vector<Pose2> saved_poses = problem->poses;
    const std::vector<Eigen::Vector2d> saved_points = problem->points;
    double scale = 1.0;
    bool descended = false;
    for (int halvings = 0; halvings < 10; ++halvings) {
      problem->Apply(step, scale);
      descended = problem->Linearize(false) <= cost * (1.0 + 1e-12);
      if (descended) break;
      problem->poses = saved_poses;
      problem->points = saved_points;
      scale *= 0.5;
    }
    cost = problem->Linearize(true);
    // No descent along the step: the run is at its minimum to rounding.
    if (!descended || scale * step.cwiseAbs().maxCoeff() < 1e-9) break;
  }
  ldlt->compute(problem->H);
  if (ldlt->info() != Eigen::Success) {
    return absl::InternalError(absl::StrCat("local map ", id, ": factorisation failed"));
  }
  return absl::OkStatus();
}

// Gauss-Newton over one run in the frame of its first pose (held at the identity), then
// the Gaussian over [last pose, points] from the inverse of the information.
absl::StatusOr<RunSolution> SolveRun(const PoseGraph& graph, const Run& run, const std::vector<int>& odometry_into,
                                     const std::vector<std::vector<Sighting>>& sightings, int id, int max_iterations) {
  RunProblem problem(graph, run, odometry_into, sightings);
  Eigen::LDLT<Eigen::MatrixXd> ldlt;
  if (absl::Status s = MinimizeRun(&problem, id, max_iterations, &ldlt); !s.ok()) return s;
  const int steps = problem.steps();
  const int num_points = problem.num_points();
  // The marginal over [last pose, points]: those columns of H⁻¹.
  std::vector<int> keep;
  for (int c = 0; c < 3; ++c) keep.push_back(problem.pose_col(steps) + c);
  for (int j = 0; j < num_points; ++j) {
    keep.push_back(problem.point_col(j));
    keep.push_back(problem.point_col(j) + 1);
  }
  const int m = static_cast<int>(keep.size());
  Eigen::MatrixXd E = Eigen::MatrixXd::Zero(problem.dim(), m);
  for (int c = 0; c < m; ++c) E(keep[c], c) = 1.0;
  const Eigen::MatrixXd columns = ldlt.solve(E);
  RunSolution out;
  LocalSubmap& s = out.submap;
  s.id = id;
  s.t_start = run.first;
  s.t_end = run.last;
  s.mean.resize(m);
  s.covariance.resize(m, m);
  for (int r = 0; r < m; ++r) {
    for (int c = 0; c < m; ++c) s.covariance(r, c) = columns(keep[r], c);
  }
  s.covariance = (0.5 * (s.covariance + s.covariance.transpose())).eval();
  const Pose2& last = problem.poses[steps];
  s.mean.head<3>() << last.x, last.y, WrapAngle(last.theta);
  for (int j = 0; j < num_points; ++j) {
    s.mean.segment<2>(3 + 2 * j) = problem.points[j];
    LocalSubmapLandmark landmark;
    landmark.local_id = j;
    landmark.truth_id = problem.point_of_slot[j];
    s.landmarks.push_back(landmark);
  }
  out.poses.assign(problem.poses.begin() + 1, problem.poses.end() - 1);
  const int interior = 3 * (steps - 1);
  if (interior > 0) {
    const Eigen::MatrixXd C_ik = columns.topRows(interior);
    out.gain = s.covariance.ldlt().solve(C_ik.transpose()).transpose();
  }
  return out;
}

}  // namespace

absl::Status SubmapRouteOptions::Validate() const {
  if (poses_per_map < 1) return absl::InvalidArgumentError("poses_per_map must be >= 1");
  if (max_local_iterations < 1) return absl::InvalidArgumentError("max_local_iterations must be >= 1");
  return eif.Validate();
}

absl::StatusOr<SubmapRouteReport> SolveBySubmaps(PoseGraph* graph, const SubmapRouteOptions& options,
                                                 std::vector<LocalSubmap>* local_maps) {
  if (absl::Status s = options.Validate(); !s.ok()) return s;
  if (absl::Status s = graph->Validate(); !s.ok()) return s;
  if (absl::Status s = CheckRouteApplies(*graph); !s.ok()) return s;
  const int num_poses = static_cast<int>(graph->poses.size());
  std::vector<int> odometry_into(num_poses, -1);
  for (int e = 0; e < static_cast<int>(graph->odometry.size()); ++e) odometry_into[graph->odometry[e].to] = e;
  std::vector<std::vector<Sighting>> sightings(num_poses);
  for (int i = 0; i < static_cast<int>(graph->point_measurements.size()); ++i) {
    sightings[graph->point_measurements[i].pose].push_back({false, i});
  }
  for (int i = 0; i < static_cast<int>(graph->bearing_range_measurements.size()); ++i) {
    sightings[graph->bearing_range_measurements[i].pose].push_back({true, i});
  }
  backend::EifJoinerOptions eif = options.eif;
  eif.association.known_association = true;
  eif.validate_joins = false;  // a rejected join would give a point two landmarks
  const Pose2 initial = graph->poses[0].has_estimate ? graph->poses[0].estimate : Pose2();
  std::unique_ptr<backend::MapJoiner> joiner_holder;
  if (options.tree) {
    joiner_holder = std::make_unique<backend::TreeJoiner>(
        std::make_unique<backend::EifJoiner>(initial, eif.ForTreeNode()), backend::TreeJoinerOptions{});
  } else {
    joiner_holder = std::make_unique<backend::EifJoiner>(initial, eif);
  }
  backend::MapJoiner& joiner = *joiner_holder;
  SubmapRouteReport report;
  std::vector<Run> runs;
  for (int first = 0; first < num_poses - 1; first += options.poses_per_map) {
    const int last = std::min(first + options.poses_per_map, num_poses - 1);
    runs.push_back({first, last, last == num_poses - 1});
  }
  std::vector<RunSolution> solutions;
  for (int k = 0; k < static_cast<int>(runs.size()); ++k) {
    const absl::Time t0 = absl::Now();
    auto solution = SolveRun(*graph, runs[k], odometry_into, sightings, k, options.max_local_iterations);
    if (!solution.ok()) return solution.status();
    const absl::Time t1 = absl::Now();
    report.local_map_seconds += absl::ToDoubleSeconds(t1 - t0);
    if (absl::Status s = joiner.Join(solution->submap); !s.ok()) return s;
    report.join_seconds += absl::ToDoubleSeconds(absl::Now() - t1);
    solutions.push_back(std::move(*solution));
  }
  const absl::Time t2 = absl::Now();
  if (absl::Status s = joiner.Finish(); !s.ok()) return s;
  report.join_seconds += absl::ToDoubleSeconds(absl::Now() - t2);
  report.local_maps = static_cast<int>(runs.size());
  report.counters = joiner.counters();
  report.stage_times = joiner.stage_times();
  // Anchor k is the first pose of run k (and the last of run k − 1); the interior poses
  // follow their local map's variables through the gain.
  const SubmapGraph& joined = joiner.graph();
  graph->poses[0].estimate = initial;
  for (int k = 0; k < static_cast<int>(runs.size()); ++k) {
    const SubmapFactor& f = joined.factors()[k];
    const LocalSubmap& s = solutions[k].submap;
    const Pose2 anchor = joined.anchors()[f.start_anchor];
    Eigen::VectorXd change(s.mean.size());
    change.head<3>() = PoseDifference(Between(anchor, joined.anchors()[f.end_anchor]), s.end_pose());
    for (int i = 0; i < s.num_landmarks(); ++i) {
      const Eigen::Vector2d point = joined.landmarks()[f.landmark_of_feature[i]];
      change.segment<2>(3 + 2 * i) = TransformTo(anchor, point) - s.landmark(i);
      graph->points[*s.landmarks[i].truth_id].estimate = point;
    }
    const std::vector<Pose2>& interior = solutions[k].poses;
    const Eigen::VectorXd interior_change =
        interior.empty() ? Eigen::VectorXd() : Eigen::VectorXd(solutions[k].gain * change);
    for (int i = 0; i < static_cast<int>(interior.size()); ++i) {
      const Eigen::Vector3d local = interior[i].vector() + interior_change.segment<3>(3 * i);
      graph->poses[runs[k].first + 1 + i].estimate = Compose(anchor, Pose2::FromVector(local));
    }
    graph->poses[runs[k].last].estimate = joined.anchors()[f.end_anchor];
  }
  if (local_maps != nullptr) {
    local_maps->clear();
    for (RunSolution& solution : solutions) local_maps->push_back(std::move(solution.submap));
  }
  for (PoseVertex& p : graph->poses) p.has_estimate = true;
  for (PointVertex& p : graph->points) p.has_estimate = true;
  return report;
}

}  // namespace subslam::posegraph
