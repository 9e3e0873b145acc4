#include "tool_jobs.h"

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/time/clock.h"
#include "backend_flags.h"
#include "command_flags.h"
#include "flag_errors.h"
#include "frontend_flags.h"
#include "subslam/eval/trajectory_errors.h"
#include "subslam/io/calibration_fragment.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/sim/simulator.h"
#include "tool_flags.h"

namespace subslam::tool {
namespace {

sim::ScenarioOptions ScenarioOptionsFromFlags() {
  sim::ScenarioOptions o;
  o.seed = absl::GetFlag(FLAGS_seed);
  o.world_seed = absl::GetFlag(FLAGS_world_seed);
  o.detection_probability = absl::GetFlag(FLAGS_alpha);
  o.false_alarm_probability = absl::GetFlag(FLAGS_beta);
  o.duration_s = absl::GetFlag(FLAGS_duration);
  o.moving_objects = absl::GetFlag(FLAGS_moving_objects);
  o.fmj_case = absl::GetFlag(FLAGS_fmj_case);
  o.random_world_size_m = absl::GetFlag(FLAGS_world_size);
  o.random_landmarks = absl::GetFlag(FLAGS_landmarks);
  o.random_path_length_m = absl::GetFlag(FLAGS_path_length);
  o.random_noise_scale = absl::GetFlag(FLAGS_noise_scale);
  o.random_lattice_spacing_m = absl::GetFlag(FLAGS_lattice_spacing);
  o.with_signature = absl::GetFlag(FLAGS_signature);
  return o;
}

// The output directory must not be the input data set's own.
absl::Status CheckOutIsNotInput(const std::string& out, const std::string& input) {
  if (out.empty() || input.empty()) return absl::OkStatus();
  std::error_code ec;
  std::filesystem::path in(input);
  if (in.filename() == "dataset.json") in = in.parent_path();
  if (std::filesystem::exists(out, ec) && std::filesystem::equivalent(out, in, ec)) {
    return absl::InvalidArgumentError(absl::StrCat("--out ", out, " is the input's own directory; choose another"));
  }
  return absl::OkStatus();
}

// --trials and --workers: unset, or at least 1.
absl::Status CheckPositive(const std::optional<int>& value, const char* flag) {
  if (value.has_value() && *value < 1) {
    return absl::InvalidArgumentError(absl::StrCat("--", flag, " must be >= 1, got ", *value));
  }
  return absl::OkStatus();
}

absl::StatusOr<pipeline::Backend> BackendFlag() {
  auto backend = pipeline::BackendFromString(absl::GetFlag(FLAGS_backend));
  if (!backend.ok()) return absl::InvalidArgumentError(absl::StrCat("--backend: ", backend.status().message()));
  return backend;
}

// The solvers' options the flags give, validated.
absl::Status SetSolveOptionsFromFlags(pipeline::SolveOptions* options) {
  options->methods = absl::GetFlag(FLAGS_methods);
  options->initial_from_file = absl::GetFlag(FLAGS_initial) == "file";
  options->poses_per_map = absl::GetFlag(FLAGS_poses_per_map);
  options->tree_joining = absl::GetFlag(FLAGS_tree_joining);
  auto backend = cli::BackendOptionsFromFlags();
  if (!backend.ok()) return backend.status();
  options->eif = backend->eif;
  options->ceres.method = backend->ceres.method;
  options->ceres.loss = backend->ceres.loss;
  options->ceres.loss_scale = backend->ceres.loss_scale;
  options->ceres.max_iterations = absl::GetFlag(FLAGS_max_iterations);
  return options->Validate();
}

}  // namespace

std::string InputRequest::Source() const {
  return dataset_dir.empty() ? absl::StrCat("scenario ", scenario, " seed ", scenario_options.seed)
                             : absl::StrCat("dataset ", dataset_dir);
}

absl::StatusOr<InputRequest> InputRequestFromFlags(const std::string& command, bool required) {
  InputRequest input;
  input.dataset_dir = absl::GetFlag(FLAGS_dataset);
  input.scenario = absl::GetFlag(FLAGS_scenario);
  input.calibration_file = absl::GetFlag(FLAGS_calibration);
  if (!input.dataset_dir.empty() && !input.scenario.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat(command, required ? " needs exactly" : " takes at most", " one of --dataset or --scenario"));
  }
  if (required && input.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(command, " needs exactly one of --dataset or --scenario"));
  }
  if (!input.scenario.empty()) {
    if (absl::Status s = cli::CheckNamingFlags([] { return ScenarioOptionsFromFlags().Validate(); }); !s.ok()) {
      return s;
    }
    input.scenario_options = ScenarioOptionsFromFlags();
  }
  return input;
}

absl::StatusOr<io::Dataset> ReadInput(const InputRequest& input) {
  absl::StatusOr<io::Dataset> dataset = input.dataset_dir.empty()
                                            ? sim::SimulateScenario(input.scenario, input.scenario_options)
                                            : io::ReadDataset(input.dataset_dir);
  if (!dataset.ok()) return dataset.status();
  if (!input.calibration_file.empty()) {
    if (absl::Status s = io::ApplyCalibrationFile(input.calibration_file, &*dataset); !s.ok()) return s;
  }
  return dataset;
}

absl::StatusOr<pipeline::RunOptions> RunOptionsFromFlags(pipeline::Frontend frontend) {
  pipeline::RunOptions options;
  options.frontend = frontend;
  if (absl::Status st = cli::SetFrontendOptionsFromFlags(&options); !st.ok()) return st;
  auto backend = cli::BackendOptionsFromFlags(absl::GetFlag(FLAGS_sensor_yaw).has_value());
  if (!backend.ok()) return backend.status();
  options.backend = *backend;
  options.noise.sigma_v = absl::GetFlag(FLAGS_sigma_v);
  options.noise.sigma_u1 = absl::GetFlag(FLAGS_sigma_u1);
  options.noise.sigma_range = absl::GetFlag(FLAGS_sigma_range);
  options.noise.sigma_bearing = absl::GetFlag(FLAGS_sigma_bearing);
  options.noise.max_range = absl::GetFlag(FLAGS_max_range);
  options.noise.sensor_yaw = absl::GetFlag(FLAGS_sensor_yaw);
  if (absl::Status st = options.Validate(); !st.ok()) return st;
  return options;
}

absl::StatusOr<RunRequest> RunRequestFromFlags(bool input_given) {
  RunRequest request;
  auto input = InputRequestFromFlags("run", /*required=*/!input_given);
  if (!input.ok()) return input.status();
  request.input = *std::move(input);
  if (input_given && (!request.input.empty() || !request.input.calibration_file.empty())) {
    return absl::InvalidArgumentError(
        "run was given its data set: --dataset, --scenario and --calibration must be unset");
  }
  auto frontend = pipeline::FrontendFromString(absl::GetFlag(FLAGS_frontend));
  if (!frontend.ok()) return absl::InvalidArgumentError(absl::StrCat("--frontend: ", frontend.status().message()));
  auto backend = BackendFlag();
  if (!backend.ok()) return backend.status();
  const bool local_maps = *frontend == pipeline::Frontend::kRbpf || *frontend == pipeline::Frontend::kEkfLocal;
  cli::CommandContext context{.command = "run", .frontend = *frontend, .scenario = !request.input.scenario.empty()};
  if (local_maps) context.backend = *backend;
  if (absl::Status s = cli::CheckFlagsRead(context); !s.ok()) return s;
  const std::string out = absl::GetFlag(FLAGS_out);
  if (absl::Status s = CheckOutIsNotInput(out, request.input.dataset_dir); !s.ok()) return s;
  if (absl::Status s = cli::CheckNamingFlags([&] { return RunOptionsFromFlags(*frontend).status(); }); !s.ok()) {
    return s;
  }
  request.options = *RunOptionsFromFlags(*frontend);
  request.options.out_dir = out;
  request.options.progress = absl::GetFlag(FLAGS_progress);
  if (!input_given) request.options.source = request.input.Source();
  return request;
}

absl::StatusOr<CalibrateRequest> CalibrateRequestFromFlags() {
  CalibrateRequest request;
  auto input = InputRequestFromFlags("calibrate", /*required=*/true);
  if (!input.ok()) return input.status();
  request.input = *std::move(input);
  if (absl::Status s = cli::CheckFlagsRead({.command = "calibrate", .scenario = !request.input.scenario.empty()});
      !s.ok()) {
    return s;
  }
  request.options.out_dir = absl::GetFlag(FLAGS_out);
  if (absl::Status s = CheckOutIsNotInput(request.options.out_dir, request.input.dataset_dir); !s.ok()) return s;
  request.options.calibration.known_association = absl::GetFlag(FLAGS_known_association);
  request.options.source = request.input.Source();
  return request;
}

absl::StatusOr<JoinRequest> JoinRequestFromFlags(bool submaps_required) {
  JoinRequest request;
  request.submaps_path = absl::GetFlag(FLAGS_submaps);
  if (submaps_required && request.submaps_path.empty()) return absl::InvalidArgumentError("join needs --submaps FILE");
  auto kind = BackendFlag();
  if (!kind.ok()) return kind.status();
  if (*kind == pipeline::Backend::kNone) {
    return absl::InvalidArgumentError("join needs --backend eif, ceres, ekf, tree-ekf, tree-eif or tree-ceres");
  }
  auto input = InputRequestFromFlags("join", /*required=*/false);
  if (!input.ok()) return input.status();
  request.input = *std::move(input);
  const cli::CommandContext context{.command = "join", .backend = *kind, .scenario = !request.input.scenario.empty()};
  if (absl::Status s = cli::CheckFlagsRead(context); !s.ok()) return s;
  if (absl::Status s = cli::CheckNamingFlags([] { return cli::BackendOptionsFromFlags().status(); }); !s.ok()) {
    return s;
  }
  request.options.backend = *cli::BackendOptionsFromFlags();
  request.options.out_dir = absl::GetFlag(FLAGS_out);
  return request;
}

absl::StatusOr<pipeline::JoinResult> RunJoinRequest(const JoinRequest& request,
                                                    const std::vector<LocalSubmap>& submaps) {
  pipeline::JoinOptions options = request.options;
  // The initial pose and the ground truth come from the data set or the scenario the
  // local maps were built on, when given.
  if (!request.input.empty()) {
    absl::StatusOr<io::Dataset> dataset = ReadInput(request.input);
    if (!dataset.ok()) return dataset.status();
    options.initial_pose = dataset->initial_pose;
    options.truth_poses = dataset->truth_poses;
    options.truth_landmarks = dataset->truth_landmarks;
    options.observed_truth_landmarks = eval::ObservedTruthLandmarks(*dataset);
    options.gps = dataset->gps;
  }
  return pipeline::RunJoin(submaps, options);
}

absl::StatusOr<SolveRequest> SolveRequestFromFlags(bool graph_given) {
  SolveRequest request;
  request.graph_path = absl::GetFlag(FLAGS_graph);
  const std::string format_name = absl::GetFlag(FLAGS_format);
  if (graph_given) {
    if (!request.graph_path.empty() || !format_name.empty() || !absl::GetFlag(FLAGS_noise).empty()) {
      return absl::InvalidArgumentError("solve was given its graph: --graph, --format and --noise must be unset");
    }
  } else if (request.graph_path.empty()) {
    return absl::InvalidArgumentError("solve needs --graph FILE");
  }
  if (absl::Status s = cli::CheckFlagsRead({.command = "solve"}); !s.ok()) return s;
  if (!graph_given) {
    auto format = format_name.empty() ? posegraph::GraphFormatFromPath(request.graph_path)
                                      : posegraph::GraphFormatFromString(format_name);
    if (!format.ok()) return absl::InvalidArgumentError(absl::StrCat("--format: ", format.status().message()));
    request.read.format = *format;
  }
  if (const std::string n = absl::GetFlag(FLAGS_noise); !n.empty()) {
    auto noise = posegraph::NoiseConventionFromString(n);
    if (!noise.ok()) return absl::InvalidArgumentError(absl::StrCat("--noise: ", noise.status().message()));
    request.read.noise = *noise;
  }
  const std::string initial = absl::GetFlag(FLAGS_initial);
  if (initial != "dead-reckoning" && initial != "file") {
    return absl::InvalidArgumentError(absl::StrCat("--initial must be dead-reckoning or file, got \"", initial, "\""));
  }
  if (absl::Status s = cli::CheckNamingFlags([] {
        pipeline::SolveOptions options;
        return SetSolveOptionsFromFlags(&options);
      });
      !s.ok()) {
    return s;
  }
  if (absl::Status s = SetSolveOptionsFromFlags(&request.options); !s.ok()) return s;
  request.options.out_dir = absl::GetFlag(FLAGS_out);
  request.options.write_local_maps = absl::GetFlag(FLAGS_write_local_maps);
  return request;
}

absl::StatusOr<posegraph::PoseGraph> ReadSolveGraph(SolveRequest* request) {
  const absl::Time t0 = absl::Now();
  auto graph = posegraph::ReadGraph(request->graph_path, request->read);
  if (!graph.ok()) return graph.status();
  const double read_seconds = absl::ToDoubleSeconds(absl::Now() - t0);
  const posegraph::NoiseConvention noise = request->read.noise.value_or(posegraph::DefaultNoise(*request->read.format));
  request->options.source = {{"file", request->graph_path},
                             {"format", posegraph::ToString(*request->read.format)},
                             {"noise", posegraph::ToString(noise)},
                             {"read_seconds", read_seconds}};
  return graph;
}

absl::StatusOr<StudyRequest> StudyRequestFromFlags(const std::string& name) {
  // A study runs each method with its paper's settings (`--methods` chooses among them):
  // a front-end or back-end flag would change nothing, so it is refused.
  if (absl::Status s = cli::CheckFlagsRead({.command = "study"}); !s.ok()) return s;
  if (absl::Status s = CheckPositive(absl::GetFlag(FLAGS_trials), "trials"); !s.ok()) return s;
  if (absl::Status s = CheckPositive(absl::GetFlag(FLAGS_workers), "workers"); !s.ok()) return s;
  auto made = study::MakeStudy(name);
  if (!made.ok()) return made.status();
  StudyRequest request;
  request.study = *std::move(made);
  request.options.trials = absl::GetFlag(FLAGS_trials).value_or(0);
  request.options.workers = absl::GetFlag(FLAGS_workers).value_or(0);
  request.options.methods = absl::GetFlag(FLAGS_methods);
  request.options.dataset_dir = absl::GetFlag(FLAGS_dataset);
  auto shard = study::ShardFromString(absl::GetFlag(FLAGS_shard));
  if (!shard.ok()) return absl::InvalidArgumentError(absl::StrCat("--shard: ", shard.status().message()));
  request.options.shard = *shard;
  request.options.out_dir = absl::GetFlag(FLAGS_out);
  request.options.progress = absl::GetFlag(FLAGS_progress);
  if (request.options.out_dir.empty()) return absl::InvalidArgumentError("a study needs an output directory (--out)");
  return request;
}

}  // namespace subslam::tool
