// The tool's jobs as requests built from its flags (apps/tool_flags.h,
// cli/frontend_flags.h, cli/backend_flags.h): the options each job runs with and where its
// input comes from, checked as the tool checks them, each bad value named by its flag.
// The tool's commands (tool_commands.cc) and the Python module (python/) build their jobs
// here, so that a job run from either is the same job, to the bit.
//
//   absl::StatusOr<RunRequest> request = RunRequestFromFlags();   // after the flags are set
//   absl::StatusOr<io::Dataset> dataset = ReadInput(request->input);
//   absl::StatusOr<pipeline::RunResult> result = pipeline::RunPipeline(*dataset, request->options);
//
// Building a request reads the flags and nothing else; reading the input and running the
// job read no flag, so a caller may set the flags, build the request, restore the flags and
// run the job on another thread.
#ifndef SUBSLAM_APPS_TOOL_JOBS_H_
#define SUBSLAM_APPS_TOOL_JOBS_H_

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "subslam/core/local_submap.h"
#include "subslam/io/dataset.h"
#include "subslam/pipeline/calibrate_pipeline.h"
#include "subslam/pipeline/join_pipeline.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/pipeline/solve_pipeline.h"
#include "subslam/posegraph/graph_format.h"
#include "subslam/sim/scenario.h"
#include "subslam/study/study.h"
#include "subslam/study/study_runner.h"

namespace subslam::tool {

// Where a job's data set comes from: a data-set directory (--dataset) or a simulated
// scenario (--scenario and its options), with a calibration fragment (--calibration) laid
// over the data set's own values. Both empty: no data set.
struct InputRequest {
  std::string dataset_dir;
  std::string scenario;
  sim::ScenarioOptions scenario_options;
  std::string calibration_file;

  bool empty() const { return dataset_dir.empty() && scenario.empty(); }
  // "dataset DIR" or "scenario NAME seed S", as reports name it.
  std::string Source() const;
};

// The input the flags name; `command` (run, join, calibrate) for the messages. Errors: both
// --dataset and --scenario, or (when `required`) neither; an invalid scenario option.
absl::StatusOr<InputRequest> InputRequestFromFlags(const std::string& command, bool required);

// Reads or simulates the data set and applies the calibration.
absl::StatusOr<io::Dataset> ReadInput(const InputRequest& input);

// The run options the flags give for `frontend` (input and output aside), validated: the
// front-end, back-end and noise-override flags. The part of a run that an online estimator
// needs (pipeline::MakeOnlineEstimator).
absl::StatusOr<pipeline::RunOptions> RunOptionsFromFlags(pipeline::Frontend frontend);

// `subslam run`: the input and the options, every flag the run would not read refused.
struct RunRequest {
  InputRequest input;
  pipeline::RunOptions options;  // out_dir, progress and source set; invocation left to the caller
};
// `input_given`: the caller holds the data set (the request's input is then empty and
// --dataset, --scenario and --calibration must be unset).
absl::StatusOr<RunRequest> RunRequestFromFlags(bool input_given = false);

// `subslam calibrate`: the input and the calibration's options.
struct CalibrateRequest {
  InputRequest input;
  pipeline::CalibrateOptions options;  // out_dir and source set; invocation left to the caller
};
absl::StatusOr<CalibrateRequest> CalibrateRequestFromFlags();

// `subslam join`: the recorded local maps' file (--submaps; may be empty when `submaps_required`
// is false, for a caller that has the maps in memory), the data set the maps were built on
// (optional: the initial pose and the ground truth) and the back-end.
struct JoinRequest {
  std::string submaps_path;
  InputRequest input;
  pipeline::JoinOptions options;  // out_dir set; invocation left to the caller
};
absl::StatusOr<JoinRequest> JoinRequestFromFlags(bool submaps_required = true);

// Joins `submaps` as the request says: the initial pose and the ground truth come from the
// request's data set, when it names one.
absl::StatusOr<pipeline::JoinResult> RunJoinRequest(const JoinRequest& request,
                                                    const std::vector<LocalSubmap>& submaps);

// `subslam solve`: the graph file, how to read it, and the solvers' options.
struct SolveRequest {
  std::string graph_path;
  posegraph::GraphReadOptions read;
  pipeline::SolveOptions options;  // out_dir and write_local_maps set; invocation and source left
};
// `graph_given`: the caller holds the graph (the request's path is then empty and
// --graph, --format and --noise must be unset).
absl::StatusOr<SolveRequest> SolveRequestFromFlags(bool graph_given = false);

// Reads the request's graph, recording in options.source what it is and how long reading took.
absl::StatusOr<posegraph::PoseGraph> ReadSolveGraph(SolveRequest* request);

// `subslam study NAME`: the study and its options (out_dir required).
struct StudyRequest {
  std::unique_ptr<study::Study> study;
  study::StudyOptions options;
};
absl::StatusOr<StudyRequest> StudyRequestFromFlags(const std::string& name);

}  // namespace subslam::tool

#endif  // SUBSLAM_APPS_TOOL_JOBS_H_
