// A small known-association graph for the posegraph tests: a robot driving a circle
// (odometry chain, pose i − 1 → pose i) among points on a ring, each pose seeing the
// points within `sensor_range`, with seeded Gaussian noise drawn from the stated
// information. The truth is kept beside the graph.
#ifndef SUBSLAM_TESTS_POSEGRAPH_SYNTHETIC_GRAPH_H_
#define SUBSLAM_TESTS_POSEGRAPH_SYNTHETIC_GRAPH_H_

#include <Eigen/Cholesky>
#include <cmath>
#include <random>
#include <vector>

#include "subslam/posegraph/pose_graph.h"

namespace subslam::testing {

enum class Sightings { kPoint, kBearingRange };

struct SyntheticGraph {
  posegraph::PoseGraph graph;
  std::vector<Pose2> true_poses;
  std::vector<Eigen::Vector2d> true_points;
};

inline SyntheticGraph MakeSyntheticGraph(int num_poses, int num_points, Sightings kind, uint64_t seed,
                                         double laps = 1.2, double sensor_range = 12.0) {
  SyntheticGraph s;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  const double radius = 20.0;
  for (int i = 0; i < num_poses; ++i) {
    const double a = 2.0 * kPi * laps * i / num_poses;
    s.true_poses.emplace_back(radius * std::cos(a), radius * std::sin(a), WrapAngle(a + kPi / 2));
  }
  for (int j = 0; j < num_points; ++j) {
    const double a = 2.0 * kPi * j / num_points;
    const double r = j % 2 == 0 ? radius - 6.0 : radius + 6.0;
    s.true_points.emplace_back(r * std::cos(a), r * std::sin(a));
  }
  // Noise of information Ω: ε = L⁻ᵀ n with Ω = L Lᵀ, n standard normal.
  const auto draw = [&](const Eigen::MatrixXd& information) {
    Eigen::VectorXd n(information.rows());
    for (int k = 0; k < n.size(); ++k) n[k] = n01(rng);
    const Eigen::MatrixXd U = Eigen::LLT<Eigen::MatrixXd>(information).matrixU();
    return Eigen::VectorXd(U.triangularView<Eigen::Upper>().solve(n));
  };
  posegraph::PoseGraph& g = s.graph;
  for (int i = 0; i < num_poses; ++i) g.PoseIndex(i);
  for (int j = 0; j < num_points; ++j) g.PointIndex(num_poses + j);
  Eigen::Matrix3d odometry_information =
      Eigen::Vector3d(1.0 / (0.05 * 0.05), 1.0 / (0.02 * 0.02), 1.0 / (0.01 * 0.01)).asDiagonal();
  odometry_information(0, 2) = odometry_information(2, 0) = 100.0;  // a correlation, so order matters
  for (int i = 1; i < num_poses; ++i) {
    const Eigen::Vector3d e = draw(odometry_information);
    const Pose2 rel = Between(s.true_poses[i - 1], s.true_poses[i]);
    g.odometry.push_back(
        {i - 1, i, Pose2(rel.x + e.x(), rel.y + e.y(), WrapAngle(rel.theta + e.z())), odometry_information});
    // Sightings from pose i − 1 (the pose before the step), in time order.
    for (int j = 0; j < num_points; ++j) {
      const Eigen::Vector2d local = TransformTo(s.true_poses[i - 1], s.true_points[j]);
      if (local.norm() > sensor_range) continue;
      if (kind == Sightings::kPoint) {
        Eigen::Matrix2d information;
        information << 1.0 / 0.09, 2.0, 2.0, 1.0 / 0.04;
        g.point_measurements.push_back({i - 1, j, local + draw(information), information});
      } else {
        const Eigen::Matrix2d information = Eigen::Vector2d(1.0 / (0.02 * 0.02), 1.0 / (0.1 * 0.1)).asDiagonal();
        const Eigen::VectorXd e = draw(information);
        g.bearing_range_measurements.push_back(
            {i - 1, j, WrapAngle(std::atan2(local.y(), local.x()) + e[0]), local.norm() + e[1], information});
      }
    }
  }
  return s;
}

}  // namespace subslam::testing

#endif  // SUBSLAM_TESTS_POSEGRAPH_SYNTHETIC_GRAPH_H_
