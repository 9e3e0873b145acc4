// Consistency of one local map against ground truth: the true end pose and the true
// positions of its features, both expressed in the TRUE start-pose frame, compared with
// the local map's Gaussian (NEES over the joint state).
//
// A feature is evaluated when its truth_id names a true landmark (the pipeline assigns
// the majority true id of the detections voted to the feature; −1 marks a false alarm).
// The NEES has 3 + 2k degrees of freedom (k evaluated features); it is inside the
// two-sided 95% χ² bounds of that dof when the map is consistent (95% of the maps).
#ifndef SUBSLAM_EVAL_LOCAL_MAP_ERRORS_H_
#define SUBSLAM_EVAL_LOCAL_MAP_ERRORS_H_

#include <optional>
#include <vector>

#include "subslam/core/local_submap.h"
#include "subslam/io/dataset.h"

namespace subslam::eval {

struct LocalMapNees {
  int id = 0;
  double nees = 0.0;  // joint, dof = 3 + 2k
  int dof = 3;
  double pose_nees = 0.0;  // end pose alone, 3 dof
  int landmarks_evaluated = 0;
  std::vector<double> landmark_nees;  // per evaluated feature, its 2-dof marginal
  int false_alarms = 0;               // exported features whose truth_id is −1
  int unlabelled = 0;                 // exported features without a truth id
  double lower = 0.0, upper = 0.0;    // two-sided 95% χ²_dof bounds
  bool inside() const { return nees >= lower && nees <= upper; }
};

// nullopt when the truth does not cover the map's time span or the covariance block is
// not positive definite.
std::optional<LocalMapNees> EvaluateLocalMap(const LocalSubmap& submap, const std::vector<io::TimedPose>& truth_poses,
                                             const std::vector<io::TruthLandmark>& truth_landmarks);

}  // namespace subslam::eval

#endif  // SUBSLAM_EVAL_LOCAL_MAP_ERRORS_H_
