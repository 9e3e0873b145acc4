#include "subslam/posegraph/dataset_graph.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <filesystem>

#include "subslam/io/steps.h"
#include "subslam/posegraph/graph_format.h"

namespace subslam::posegraph {

absl::StatusOr<PoseGraph> GraphFromDataset(const io::Dataset& dataset, SightingForm form) {
  if (dataset.scans.empty()) return absl::InvalidArgumentError("the data set has no scan");
  const std::unique_ptr<models::MotionModel> model = dataset.motion.MakeModel();
  const models::RangeBearingConfig& sensor = dataset.sensor.range_bearing;
  Eigen::Matrix2d polar_information = Eigen::Matrix2d::Zero();  // over (bearing, range)
  polar_information(0, 0) = 1.0 / (sensor.sigma_bearing_rad * sensor.sigma_bearing_rad);
  polar_information(1, 1) = 1.0 / (sensor.sigma_range_m * sensor.sigma_range_m);
  PoseGraph graph;
  Pose2 moved;  // the motion since the last scan's pose, in its frame
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  Pose2 world = dataset.initial_pose;  // dead reckoning, for the estimates
  int sightings = 0;
  for (const io::Step& step : io::BuildSteps(dataset)) {
    if (step.dt > 0.0) {
      Eigen::Matrix3d J_x;
      Matrix32d J_u;
      const Pose2 next = model->Predict(moved, step.control, step.dt, &J_x, &J_u);
      covariance = J_x * covariance * J_x.transpose() + J_u * model->noise().Covariance(step.control) * J_u.transpose();
      moved = next;
    }
    if (step.scan_index < 0) continue;
    const int pose = graph.PoseIndex(step.scan_index);
    world = Compose(world, moved);
    graph.poses[pose].estimate = world;
    graph.poses[pose].has_estimate = true;
    if (pose > 0) {
      // A covariance singular or nearly so (no motion, or one straight step: the motion
      // model has no sideways noise) gets a floor in every direction.
      const Eigen::Vector3d eigenvalues = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance).eigenvalues();
      const double floor = std::max(kMinOdometryVariance, kMinOdometryVarianceRatio * eigenvalues.maxCoeff());
      if (!(eigenvalues.minCoeff() >= floor)) covariance += floor * Eigen::Matrix3d::Identity();
      Eigen::Matrix3d information = covariance.inverse();
      information = (0.5 * (information + information.transpose())).eval();
      graph.odometry.push_back({pose - 1, pose, moved, information});
    }
    moved = Pose2();
    covariance.setZero();
    for (const Detection& d : dataset.scans[step.scan_index].detections) {
      if (d.truth_id < 0) continue;  // a false alarm, or no truth
      const int point = graph.PointIndex(kLandmarkIdOffset + d.truth_id);
      ++sightings;
      if (form == SightingForm::kBearingRange) {
        graph.bearing_range_measurements.push_back({pose, point, d.bearing_rad, d.range_m, polar_information});
        continue;
      }
      const double c = std::cos(d.bearing_rad), s = std::sin(d.bearing_rad);
      Eigen::Matrix2d J;  // d(x, y) / d(bearing, range)
      J << -d.range_m * s, c, d.range_m * c, s;
      Eigen::Matrix2d point_information = (J * polar_information.inverse() * J.transpose()).inverse();
      point_information = (0.5 * (point_information + point_information.transpose())).eval();
      graph.point_measurements.push_back(
          {pose, point, Eigen::Vector2d(d.range_m * c, d.range_m * s), point_information});
    }
  }
  if (sightings == 0) return absl::InvalidArgumentError("no detection carries a true landmark id");
  if (absl::Status s = InitializeByDeadReckoning(&graph); !s.ok()) return s;
  for (PointVertex& p : graph.points) p.has_estimate = true;
  return graph;
}

absl::Status WriteDatasetGraphs(const io::Dataset& dataset, const std::string& dir) {
  auto polar = GraphFromDataset(dataset, SightingForm::kBearingRange);
  if (!polar.ok()) return polar.status();
  auto cartesian = GraphFromDataset(dataset, SightingForm::kPoint);
  if (!cartesian.ok()) return cartesian.status();
  PoseGraph poses_only = *cartesian;
  poses_only.ClearPoints();
  const std::filesystem::path d(dir);
  GraphWriteOptions isam;
  isam.format = GraphFormat::kIsam;
  if (absl::Status s = WriteGraph(*polar, (d / "graph.isam").string(), isam); !s.ok()) return s;
  GraphWriteOptions g2o;
  g2o.format = GraphFormat::kG2o;
  if (absl::Status s = WriteGraph(*cartesian, (d / "graph.g2o").string(), g2o); !s.ok()) return s;
  GraphWriteOptions toro;
  toro.format = GraphFormat::kToro;
  return WriteGraph(poses_only, (d / "graph.toro").string(), toro);
}

}  // namespace subslam::posegraph
