// A 2-D pose–landmark graph as the field's standard graph files hold it (g2o, iSAM /
// GTSAM, TORO; posegraph/graph_format.h): robot poses, point landmarks, and measurements
// between them with known association, each with its noise as an information matrix.
//
// Frames and units (docs/conventions.md): poses (x [m], y [m], θ [rad]) and points
// (x, y [m]) in one world frame; every measurement is taken from pose `pose` / `from` and
// expressed in that pose's frame (x forward, y left, bearings counter-clockwise from x).
//
// Residuals (measurement_residuals.h) and the error readings:
//   odometry       r = (z⁻¹ ∘ (x_from⁻¹ ∘ x_to)) as (x, y, θ), θ wrapped — g2o's EDGE_SE2
//                  error; GTSAM's BetweenFactor<Pose2> uses the same pose difference
//                  (through Pose2's chart, equal to first order at the minimum);
//   point          r = x_pose⁻¹ · l − z (a Cartesian sighting in the robot frame);
//   bearing-range  r = (wrap(b̂ − b), r̂ − r);  bearing  r = wrap(b̂ − b);
// error = ½ Σ rᵀ Ω r (GTSAM's "error": ½ Σ ‖whitened residual‖²) and χ² = Σ rᵀ Ω r
// (g2o's chi2), Ω each measurement's information.
#ifndef SUBSLAM_POSEGRAPH_POSE_GRAPH_H_
#define SUBSLAM_POSEGRAPH_POSE_GRAPH_H_

#include <Eigen/Core>
#include <string>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/core/pose2.h"

namespace subslam::posegraph {

struct PoseVertex {
  long id = 0;     // the file's id
  Pose2 estimate;  // the file's estimate when has_estimate, else set by the solver
  bool has_estimate = false;
  bool fixed = false;  // held constant (g2o FIX); with none fixed, the first pose is
};

struct PointVertex {
  long id = 0;
  Eigen::Vector2d estimate = Eigen::Vector2d::Zero();
  bool has_estimate = false;
};

// Pose `to` seen from pose `from`: z = x_from⁻¹ ∘ x_to.
struct OdometryMeasurement {
  int from = 0, to = 0;  // pose indices
  Pose2 z;
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity();
};

// Point `point` at z (m) in the frame of pose `pose`.
struct PointMeasurement {
  int pose = 0, point = 0;  // pose and point indices
  Eigen::Vector2d z = Eigen::Vector2d::Zero();
  Eigen::Matrix2d information = Eigen::Matrix2d::Identity();
};

// Point `point` at bearing b (rad) and range r (m) from pose `pose`; information over
// (bearing, range).
struct BearingRangeMeasurement {
  int pose = 0, point = 0;
  double bearing = 0.0, range = 0.0;
  Eigen::Matrix2d information = Eigen::Matrix2d::Identity();
};

// Point `point` at bearing b (rad) from pose `pose`.
struct BearingMeasurement {
  int pose = 0, point = 0;
  double bearing = 0.0;
  double information = 1.0;  // 1 / σ_b²
};

class PoseGraph {
 public:
  // The index of the pose / point with this file id, added (without an estimate) if new.
  int PoseIndex(long id);
  int PointIndex(long id);
  // The index, or -1 when there is none with this id.
  int FindPose(long id) const;
  int FindPoint(long id) const;
  // Removes every point and every measurement of one (a pose graph remains).
  void ClearPoints();

  std::vector<PoseVertex> poses;  // in order of first appearance in the file
  std::vector<PointVertex> points;
  std::vector<OdometryMeasurement> odometry;  // in file order (time order for the incremental solvers)
  std::vector<PointMeasurement> point_measurements;
  std::vector<BearingRangeMeasurement> bearing_range_measurements;
  std::vector<BearingMeasurement> bearing_measurements;

  int num_measurements() const {
    return static_cast<int>(odometry.size() + point_measurements.size() + bearing_range_measurements.size() +
                            bearing_measurements.size());
  }
  // Whether every pose and point carries an estimate from the file.
  bool HasEstimates() const;
  // The poses held constant: the fixed ones, or the first pose when none is fixed.
  std::vector<int> GaugePoses() const;

  // Indices in range, values finite, information symmetric positive definite, no
  // measurement from a pose to itself, and every pose and point reached from a gauge
  // pose through the measurements (else the problem has no unique minimum).
  absl::Status Validate() const;

 private:
  absl::flat_hash_map<long, int> pose_index_, point_index_;
};

// The two error readings of an estimate (the graph's vertex estimates).
struct GraphError {
  double error = 0.0;  // ½ Σ rᵀ Ω r
  double chi2 = 0.0;   //   Σ rᵀ Ω r
};
GraphError EvaluateError(const PoseGraph& graph);

// Dead reckoning: every pose except the gauge poses (which keep their given estimates, or
// take the origin) is set by composing odometry outward from them, breadth first over
// the odometry measurements in file order; every point from its
// first sighting in measurement order (point or bearing-range), or — seen by bearings
// only — by least-squares intersection of its bearing lines. Errors: a pose no odometry
// reaches, a point without a sighting, bearing lines that do not intersect (parallel).
absl::Status InitializeByDeadReckoning(PoseGraph* graph);

}  // namespace subslam::posegraph

#endif  // SUBSLAM_POSEGRAPH_POSE_GRAPH_H_
