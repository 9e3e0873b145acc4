// Errors of an estimated trajectory and map against ground truth.
//
// Trajectory: the truth is interpolated at each estimate's time (linear in position,
// shortest-arc in heading); RMS of position ( √mean(ex² + ey²) ) and heading, per-axis
// RMS, per-step pose NEES, the share of steps whose NEES lies inside the single-run
// two-sided 95% χ²₃ interval, and the HybridSLAM failure test (§5: the true pose more
// than `failure_sigma` standard deviations — Mahalanobis distance √NEES — from the
// estimate for more than `failure_steps` consecutive steps).
//
// Map: estimated landmarks are matched one-to-one to true landmarks within
// `match_radius_m`, by the matching with the most pairs and, among those, the smallest
// sum of squared distances (not nearest-first, which on a displaced map can leave an
// estimate unmatched that had a true landmark of its own); RMS over matched pairs.
// Unmatched estimates are counted as spurious (no true landmark within the radius: a
// false alarm or a diverged landmark) or duplicates (near true landmarks that are all
// matched: the fewest surplus estimates any one-to-one reading allows). Copies displaced
// beyond the radius count as spurious; where local maps carry true ids,
// labelled_map_errors.h counts copies however far.
#ifndef SUBSLAM_EVAL_TRAJECTORY_ERRORS_H_
#define SUBSLAM_EVAL_TRAJECTORY_ERRORS_H_

#include <optional>
#include <vector>

#include "subslam/core/estimates.h"
#include "subslam/io/dataset.h"

namespace subslam::eval {

// Pose of a time-sorted truth sequence at time t (clamped to its ends).
Pose2 InterpolatePose(const std::vector<io::TimedPose>& truth, double t);

struct TrajectoryErrorOptions {
  double failure_sigma = 10.0;  // HybridSLAM failure threshold (Mahalanobis distance)
  int failure_steps = 20;       // ... exceeded for more than this many consecutive steps
};

struct TrajectoryErrors {
  int steps = 0;
  double rms_position_m = 0.0;
  double rms_x_m = 0.0;
  double rms_y_m = 0.0;
  double rms_heading_rad = 0.0;
  double max_position_error_m = 0.0;
  double final_position_error_m = 0.0;
  int nees_steps = 0;                    // steps whose covariance is non-singular
  double mean_nees = 0.0;                // over nees_steps
  double fraction_nees_in_bounds = 0.0;  // of nees_steps, inside [χ²₃(0.025), χ²₃(0.975)]
  double mean_consistency_index = 0.0;
  bool failed = false;              // HybridSLAM failure test
  int longest_excursion_steps = 0;  // longest run beyond failure_sigma
  std::vector<double> nees;         // per step (NaN if P is singular)
};

TrajectoryErrors ComputeTrajectoryErrors(const Trajectory& estimate, const std::vector<io::TimedPose>& truth,
                                         const TrajectoryErrorOptions& options = {});

struct MapErrors {
  int estimated = 0;
  int matched = 0;
  int spurious = 0;      // estimates with no true landmark within the radius at all
  int duplicates = 0;    // unmatched estimates near true landmarks, all matched
  double rms_m = 0.0;    // over matched pairs
  double rms_x_m = 0.0;  // per axis, over matched pairs
  double rms_y_m = 0.0;
  double mean_nees = 0.0;  // over matched pairs
};

// `truth`: the true landmarks an estimate may stand for — those the sensor saw
// (ObservedTruthLandmarks). Matched against every true landmark, a copy or a displaced
// estimate takes an unseen neighbour within the radius and is counted as a match.
MapErrors ComputeMapErrors(const std::vector<LandmarkEstimate>& estimate, const std::vector<io::TruthLandmark>& truth,
                           double match_radius_m = 5.0);

// The true landmarks whose id some detection of `dataset` carries; all of them when its
// detections carry no true ids (sensor.has_truth_id false).
std::vector<io::TruthLandmark> ObservedTruthLandmarks(const io::Dataset& dataset);

}  // namespace subslam::eval

#endif  // SUBSLAM_EVAL_TRAJECTORY_ERRORS_H_
