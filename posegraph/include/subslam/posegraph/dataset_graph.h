// The known-association graph of a data set whose detections carry their true landmark
// ids (a simulation: `subslam simulate` writes it beside the data set, docs/formats.md).
//
// One pose per scan (id k for the k-th scan), pose 0 given the data set's initial pose
// carried to the first scan's time (the graph's gauge); odometry from each scan's pose to
// the next by integrating the controls between them with the motion model's mean, its
// covariance propagated in the frame of the earlier pose (ProcessCovariance per control
// step); each detection with a true id a sighting of landmark (point) id 1,000,000 + id
// (false alarms and unknown ids are left out) with the sensor's noise: as bearing-range,
// or as a Cartesian point at the measured position with the noise carried through the
// polar-to-Cartesian Jacobian (for formats without a bearing-range line).
//
// Where the vehicle stood still or moved straight for a single control step, the
// odometry covariance is singular in some direction (the motion models have no sideways
// noise); the graph then adds to it, in every direction, kMinOdometryVarianceRatio of its
// largest variance (at least kMinOdometryVariance: 10 µm and 10 µrad), so that every
// measurement has an information matrix and none is a million times sharper across than
// along.
#ifndef SUBSLAM_POSEGRAPH_DATASET_GRAPH_H_
#define SUBSLAM_POSEGRAPH_DATASET_GRAPH_H_

#include <string>

#include "absl/status/statusor.h"
#include "subslam/io/dataset.h"
#include "subslam/posegraph/pose_graph.h"

namespace subslam::posegraph {

enum class SightingForm { kBearingRange, kPoint };

inline constexpr long kLandmarkIdOffset = 1'000'000;
inline constexpr double kMinOdometryVariance = 1e-10;
inline constexpr double kMinOdometryVarianceRatio = 1e-4;

// Errors: no scan, or no detection with a true id.
absl::StatusOr<PoseGraph> GraphFromDataset(const io::Dataset& dataset, SightingForm form);

// Writes the data set's graph into `dir` in every format, each vertex at its dead-reckoning
// estimate: graph.isam (bearing-range sightings as BR lines, square-root information),
// graph.g2o (Cartesian sightings), graph.toro (the poses and odometry alone: TORO holds no
// landmarks).
absl::Status WriteDatasetGraphs(const io::Dataset& dataset, const std::string& dir);

}  // namespace subslam::posegraph

#endif  // SUBSLAM_POSEGRAPH_DATASET_GRAPH_H_
