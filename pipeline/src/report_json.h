// Pieces of report.json shared by the run and join pipelines, and the output directory.
// Private to subslam::pipeline.
#ifndef SUBSLAM_APPS_SRC_REPORT_JSON_H_
#define SUBSLAM_APPS_SRC_REPORT_JSON_H_

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "subslam/eval/gps_alignment.h"
#include "subslam/eval/labelled_map_errors.h"
#include "subslam/eval/trajectory_errors.h"
#include "subslam/pipeline/build_info.h"
#include "subslam/pipeline/join_pipeline.h"

namespace subslam::pipeline {

inline nlohmann::json ErrorsJson(const eval::TrajectoryErrors& e) {
  return {{"steps", e.steps},
          {"rms_position_m", e.rms_position_m},
          {"rms_x_m", e.rms_x_m},
          {"rms_y_m", e.rms_y_m},
          {"rms_heading_rad", e.rms_heading_rad},
          {"max_position_error_m", e.max_position_error_m},
          {"final_position_error_m", e.final_position_error_m},
          {"nees_steps", e.nees_steps},
          {"mean_pose_nees", e.mean_nees},
          {"fraction_steps_nees_in_95_bounds", e.fraction_nees_in_bounds},
          {"mean_consistency_index", e.mean_consistency_index},
          {"failed_10_sigma_test", e.failed},
          {"longest_10_sigma_excursion_steps", e.longest_excursion_steps}};
}

inline nlohmann::json MapErrorsJson(const eval::MapErrors& m, size_t true_landmarks, size_t observed) {
  return {{"estimated", m.estimated},
          {"matched", m.matched},
          {"spurious", m.spurious},
          {"duplicates", m.duplicates},
          {"true_landmarks", true_landmarks},
          {"true_landmarks_observed", observed},
          {"rms_m", m.rms_m},
          {"mean_landmark_nees", m.mean_nees}};
}

inline nlohmann::json LabelledMapErrorsJson(const eval::LabelledMapErrors& m) {
  return {{"labelled", m.labelled},
          {"distinct_true_landmarks", m.true_landmarks},
          {"duplicates", m.duplicates},
          {"rms_m", m.rms_m},
          {"rms_x_m", m.rms_x_m},
          {"rms_y_m", m.rms_y_m},
          {"mean_landmark_nees", m.mean_nees},
          {"fraction_nees_in_95", m.fraction_nees_in_95}};
}

inline nlohmann::json AssociationVsTruthJson(const AssociationVsTruth& a) {
  return {{"true_landmarks_seen", a.correct},
          {"missed_merges", a.missed},
          {"wrong_merges", a.wrong},
          {"wrong_merges_with_mixed_feature", a.wrong_with_mixed_feature},
          {"wrong_merges_sharing_no_true_landmark", a.wrong_sharing_no_true_landmark},
          {"reobserved_recent_merged", a.recent_merged},
          {"reobserved_recent_missed", a.recent_missed},
          {"reobserved_loop_merged", a.loop_merged},
          {"reobserved_loop_missed", a.loop_missed}};
}

inline nlohmann::json GpsJson(const eval::GpsComparison& g) {
  return {{"matched_fixes", g.matched_fixes},
          {"rejected_fixes", g.rejected_fixes},
          {"aligned_rms_m", g.rms_m},
          {"aligned_rms_x_m", g.rms_x_m},
          {"aligned_rms_y_m", g.rms_y_m},
          {"aligned_max_m", g.max_m},
          {"gps_T_estimate", {g.gps_T_estimate.x, g.gps_T_estimate.y, g.gps_T_estimate.theta}}};
}

// report.json's "build": the version, commit and build type of the library that wrote it.
inline nlohmann::json BuildJson() {
  return {{"version", Version()}, {"commit", Commit()}, {"build_type", BuildType()}};
}

}  // namespace subslam::pipeline

#endif  // SUBSLAM_APPS_SRC_REPORT_JSON_H_
