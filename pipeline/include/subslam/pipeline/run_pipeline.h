// The `subslam run` job as a library call: feed a data set (read or simulated) through
// an online estimator, evaluate it against whatever ground truth the data set has,
// and write the run outputs of docs/formats.md to a directory.
//
// Outputs (in RunOptions::out_dir, when set):
//   trajectory_online.csv  the pose and covariance after every step, as it was then;
//   trajectory_final.csv   every step re-expressed with the final anchors (local-map
//                          pipelines); the single-map filters have no anchors, so for
//                          them it equals the online one;
//   landmarks.csv          the final map (confirmed landmarks);
//   report.json            configuration, counts, time per stage, metrics;
//   submaps.jsonl          (rbpf, ekf) the local maps, in the exchange format.
#ifndef SUBSLAM_PIPELINE_RUN_PIPELINE_H_
#define SUBSLAM_PIPELINE_RUN_PIPELINE_H_

#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "absl/status/statusor.h"
#include "subslam/backend/landmark_persistence.h"
#include "subslam/backend/map_joiner.h"
#include "subslam/core/estimates.h"
#include "subslam/core/local_submap.h"
#include "subslam/eval/gps_alignment.h"
#include "subslam/eval/labelled_map_errors.h"
#include "subslam/eval/trajectory_errors.h"
#include "subslam/frontend/ekf_slam.h"
#include "subslam/frontend/fastslam.h"
#include "subslam/frontend/seif_slam.h"
#include "subslam/frontend/submap_policy.h"
#include "subslam/io/dataset.h"
#include "subslam/io/input_screening.h"
#include "subslam/pipeline/join_pipeline.h"
#include "subslam/pipeline/submap_slam.h"

namespace subslam::pipeline {

// odometry: dead reckoning; ekfslam, fastslam: single-map filters; rbpf, ekf: local
// mappers (FastSLAM 2.0 / EKF-SLAM per local map), joined by RunOptions::backend.
// Single-map filters: odometry, ekfslam, fastslam, seif, iseif; local-map front-ends
// (joined by a back-end): rbpf, ekf.
enum class Frontend { kOdometry, kEkfSlam, kFastSlam, kRbpf, kEkfLocal, kSeif, kIseif };
const char* ToString(Frontend frontend);
absl::StatusOr<Frontend> FrontendFromString(const std::string& name);

// Overrides of the data set's noise values (unset: use the manifest's).
struct NoiseOverrides {
  std::optional<double> sigma_v;        // m/s
  std::optional<double> sigma_u1;       // rad/s (unicycle ω) or rad (ackermann steer)
  std::optional<double> sigma_range;    // m
  std::optional<double> sigma_bearing;  // rad
  std::optional<double> max_range;      // m: detections beyond are not used
  // rad, added to every bearing: the sensor's yaw on the vehicle beyond the data set's
  // own bearing_offset — a calibration (bench/sensor_yaw_calibration estimates it from
  // EKF-SLAM's innovation likelihood; bench/RESULTS.md).
  std::optional<double> sensor_yaw;

  absl::Status ApplyTo(io::Dataset* dataset) const;
};

// The final map against the run's own scans along the final trajectory
// (backend/landmark_persistence.h): which landmarks are detected more often than chance
// pairings explain, and P_D by range; reported in report.json's health, and with
// drop_unconfirmed the unconfirmed landmarks leave the map (landmarks.csv, the metrics).
struct MapConfirmationOptions {
  bool enabled = true;
  bool drop_unconfirmed = false;
  backend::LandmarkPersistenceOptions test;

  absl::Status Validate() const { return test.Validate(); }
};

struct RunOptions {
  Frontend frontend = Frontend::kEkfSlam;
  frontend::EkfSlamOptions ekf;
  frontend::FastSlamOptions fastslam;
  // seif, iseif (--frontend iseif turns seif.iterated.enabled on).
  frontend::SeifOptions seif;
  frontend::SubmapPolicyOptions policy;  // rbpf, ekf
  BackendOptions backend;                // rbpf, ekf: how local maps are joined
  NoiseOverrides noise;
  io::InputScreeningOptions inputs;  // implausible inputs: the rules of io/input_screening.h
  MapConfirmationOptions map_confirmation;
  std::string out_dir;    // empty: write nothing
  bool progress = false;  // progress line on stderr (when it is a terminal)
  std::string source;     // what was run, for the report ("scenario hybrid-120m seed 1")
  // How the run was invoked, recorded as report.json's "invocation" (the tool: its command
  // line and every flag's value, so that `subslam run --config report.json` repeats it).
  nlohmann::json invocation;

  // Every option struct's own check (the noise overrides are checked against the data set
  // they change, by RunPipeline).
  absl::Status Validate() const;
};

struct LocalMapSummary {
  int evaluated = 0;
  int inside = 0;             // joint NEES inside its two-sided 95% χ² bounds
  int pose_inside = 0;        // end-pose NEES inside the 3-dof bounds
  double nees_per_dof = 0.0;  // mean over maps of NEES / dof
  int landmarks = 0;          // features evaluated, over all maps
  int landmarks_inside = 0;   // their 2-dof marginal NEES inside the 95% bounds
  int false_alarms = 0;       // exported features whose detections were false alarms
};

// Why a run stopped before its end (RunResult::stop). The outputs hold everything up to
// the last good step.
struct RunStop {
  // The filter's pose or covariance became non-finite; a local map could not be exported
  // (SubmapSlam::export_failed); a join failed (SubmapSlam::join_failed).
  enum class Cause { kNonFiniteEstimate, kExportFailed, kJoinFailed };
  Cause cause = Cause::kNonFiniteEstimate;
  int step = 0;    // index of the first step not in the outputs (io::BuildSteps order)
  double t = 0.0;  // its time [s]
  std::string reason;
};

// report.json's name of a cause: non_finite_estimate, local_map_export_failed, join_failed.
const char* ToString(RunStop::Cause cause);

struct RunResult {
  std::string source;
  std::string frontend;
  int steps = 0;
  int scans = 0;
  long detections = 0;
  Trajectory online;
  Trajectory final_trajectory;
  std::vector<LandmarkEstimate> landmarks;
  double wall_seconds = 0.0;                            // estimator time (excludes reading and writing)
  std::vector<double> wall_seconds_by_tenth;            // cumulative, after each tenth of the steps
  std::vector<long> rss_kb_by_tenth;                    // resident memory after each tenth of the steps
  long peak_rss_kb = 0;                                 // process peak resident memory after the run
  std::optional<eval::TrajectoryErrors> errors;         // final trajectory vs true poses
  std::optional<eval::TrajectoryErrors> errors_online;  // joined local maps: the online one
  std::optional<eval::MapErrors> map_errors;            // vs true landmarks
  // Submap runs with a back-end: the global map against the truth by label (each global
  // landmark's majority true id over the local-map features joined into it).
  std::optional<eval::LabelledMapErrors> labelled_map_errors;
  // The same runs, when the local maps carry true ids: the joined association against
  // them (subslam join's report holds the same counts).
  std::optional<AssociationVsTruth> association;
  std::optional<eval::GpsComparison> gps_online;  // vs GPS, aligned
  std::optional<eval::GpsComparison> gps_final;
  // Local-map front-ends: the local maps (truth ids attached when the data set has
  // them), why each was closed, and their consistency against ground truth.
  std::vector<LocalSubmap> local_maps;
  std::vector<std::string> close_reasons;
  std::vector<backend::JoinSummary> joins;  // with a back-end: what each join did, in order
  std::optional<LocalMapSummary> local_map_summary;
  int impure_features = 0;    // exported features built from detections of ≥ 2 true landmarks
  io::InputScreening inputs;  // what the input rules found (and repaired)
  // Set when the run could not go on: the estimate became non-finite, or a local map could
  // not be exported or joined. The trajectories, the map and the report then stop at the
  // last good step. After a failed join the back-end's estimate is not used (a join that
  // failed part-way may have left it half-made): the final trajectory is the online one
  // and the map is empty.
  std::optional<RunStop> stop;
  bool join_failed = false;      // a join (or the joiner's Finish) failed: the back-end estimate is not used
  int non_finite_landmarks = 0;  // dropped from the map (a stopped run's broken estimate)
  // The map against the scans (RunOptions::map_confirmation; unset when off or when there
  // is no map or no scan), for the map before any unconfirmed landmark was dropped.
  std::optional<backend::LandmarkPersistence> map_confirmation;
  int unconfirmed_dropped = 0;
  double map_confirmation_seconds = 0.0;  // after the run (not in wall_seconds)
  nlohmann::json report;
};

// The online estimator RunPipeline drives for `options`, on the data set's motion and
// sensor models and initial pose with the noise overrides applied (the overrides'
// sensor_yaw turns recorded bearings, which the caller applies to the scans it feeds); a
// local-map front-end gives a SubmapSlam. Errors: invalid options or overrides, known
// association on a data set without true ids.
absl::StatusOr<std::unique_ptr<frontend::OnlineEstimator>> MakeOnlineEstimator(const io::Dataset& dataset,
                                                                               const RunOptions& options);

// Errors: invalid options or overrides, an output that cannot be written. A run that
// cannot go on is not an error: its result and outputs stop at the last good step, and
// RunResult::stop says where and why (report.json "health": "completed": false).
absl::StatusOr<RunResult> RunPipeline(io::Dataset dataset, const RunOptions& options);

// A short human-readable summary table of a result.
std::string SummaryTable(const RunResult& result);

}  // namespace subslam::pipeline

#endif  // SUBSLAM_PIPELINE_RUN_PIPELINE_H_
