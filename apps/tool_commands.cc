#include "tool_commands.h"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
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
#include "subslam/io/dataset_writer.h"
#include "subslam/io/output_directory.h"
#include "subslam/io/submaps_jsonl.h"
#include "subslam/pipeline/calibrate_pipeline.h"
#include "subslam/pipeline/join_pipeline.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/pipeline/solve_pipeline.h"
#include "subslam/posegraph/dataset_graph.h"
#include "subslam/posegraph/graph_format.h"
#include "subslam/sim/simulator.h"
#include "subslam/study/study.h"
#include "subslam/study/study_runner.h"
#include "tool_flags.h"

namespace subslam::tool {
namespace {

using sim::ScenarioOptions;


ScenarioOptions ScenarioOptionsFromFlags() {
  ScenarioOptions o;
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

// The scenario options the flags give, each bad value named by its flag.
absl::StatusOr<ScenarioOptions> CheckedScenarioOptions() {
  if (absl::Status s = cli::CheckNamingFlags([] { return ScenarioOptionsFromFlags().Validate(); }); !s.ok()) return s;
  return ScenarioOptionsFromFlags();
}

// The input of run, join and calibrate: the data set or the simulated scenario, with the
// calibration of --calibration laid over its own values.
absl::StatusOr<io::Dataset> InputDataset(const std::string& dataset_dir, const std::string& scenario) {
  absl::StatusOr<io::Dataset> dataset;
  if (!dataset_dir.empty()) {
    dataset = io::ReadDataset(dataset_dir);
  } else {
    absl::StatusOr<ScenarioOptions> options = CheckedScenarioOptions();
    if (!options.ok()) return options.status();
    dataset = sim::SimulateScenario(scenario, *options);
  }
  if (!dataset.ok()) return dataset.status();
  if (const std::string file = absl::GetFlag(FLAGS_calibration); !file.empty()) {
    if (absl::Status s = io::ApplyCalibrationFile(file, &*dataset); !s.ok()) return s;
  }
  return dataset;
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

absl::StatusOr<pipeline::Backend> BackendFlag() {
  return pipeline::BackendFromString(absl::GetFlag(FLAGS_backend));
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

void PrintOutputs(const std::string& out, const std::string& files) {
  if (!out.empty()) std::printf("  %-34s %s/%s\n", "outputs", out.c_str(), files.c_str());
}

}  // namespace

int Fail(const std::string& message) {
  std::fprintf(stderr, "subslam: error: %s\n", message.c_str());
  return 1;
}

int Fail(const absl::Status& status) { return Fail(std::string(status.message())); }

int Simulate() {
  const std::string name = absl::GetFlag(FLAGS_scenario);
  const std::string out = absl::GetFlag(FLAGS_out);
  if (name.empty() || out.empty()) return Fail("simulate needs --scenario and --out");
  if (absl::Status s = cli::CheckFlagsRead({.command = "simulate", .scenario = true}); !s.ok()) return Fail(s);
  absl::StatusOr<ScenarioOptions> options = CheckedScenarioOptions();
  if (!options.ok()) return Fail(options.status());
  auto config = sim::MakeScenario(name, *options);
  if (!config.ok()) return Fail(config.status());
  auto dataset = sim::Simulate(*config, options->seed);
  if (!dataset.ok()) return Fail(dataset.status());
  if (auto dir = io::PrepareOutputDirectory(out, "simulate"); !dir.ok()) return Fail(dir.status());
  io::SimulationInfo info{name, options->seed, config->detection_probability, config->false_alarm_probability};
  if (auto s = io::WriteDataset(*dataset, out, &info); !s.ok()) return Fail(s);
  // The known-association graph beside it in the iSAM, g2o and TORO formats (docs/formats.md).
  if (auto s = posegraph::WriteDatasetGraphs(*dataset, out); !s.ok()) return Fail(s);
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("wrote %s: %zu controls, %zu scans, %zu detections, %zu landmarks -> %s (and graph.{isam,g2o,toro})\n",
                name.c_str(), dataset->controls.size(), dataset->scans.size(), dataset->NumDetections(),
                dataset->truth_landmarks.size(), out.c_str());
  }
  return 0;
}

int Run(const nlohmann::json& invocation) {
  const std::string dataset_dir = absl::GetFlag(FLAGS_dataset);
  const std::string scenario = absl::GetFlag(FLAGS_scenario);
  if (dataset_dir.empty() == scenario.empty()) return Fail("run needs exactly one of --dataset or --scenario");
  auto frontend = pipeline::FrontendFromString(absl::GetFlag(FLAGS_frontend));
  if (!frontend.ok()) return Fail(absl::StrCat("--frontend: ", frontend.status().message()));
  auto backend = BackendFlag();
  if (!backend.ok()) return Fail(absl::StrCat("--backend: ", backend.status().message()));
  const bool local_maps = *frontend == pipeline::Frontend::kRbpf || *frontend == pipeline::Frontend::kEkfLocal;
  cli::CommandContext context{.command = "run", .frontend = *frontend, .scenario = !scenario.empty()};
  if (local_maps) context.backend = *backend;
  if (absl::Status s = cli::CheckFlagsRead(context); !s.ok()) return Fail(s);
  const std::string out = absl::GetFlag(FLAGS_out);
  if (absl::Status s = CheckOutIsNotInput(out, dataset_dir); !s.ok()) return Fail(s);
  if (absl::Status s = cli::CheckNamingFlags([&] { return RunOptionsFromFlags(*frontend).status(); }); !s.ok()) {
    return Fail(s);
  }
  pipeline::RunOptions options = *RunOptionsFromFlags(*frontend);
  options.out_dir = out;
  options.progress = absl::GetFlag(FLAGS_progress);
  options.invocation = invocation;
  options.source = dataset_dir.empty() ? absl::StrCat("scenario ", scenario, " seed ", absl::GetFlag(FLAGS_seed))
                                       : absl::StrCat("dataset ", dataset_dir);
  absl::StatusOr<io::Dataset> dataset = InputDataset(dataset_dir, scenario);
  if (!dataset.ok()) return Fail(dataset.status());
  auto result = pipeline::RunPipeline(*std::move(dataset), options);
  if (!result.ok()) return Fail(result.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam run summary\n%s", pipeline::SummaryTable(*result).c_str());
    PrintOutputs(out, absl::StrCat("{trajectory_online,trajectory_final,landmarks}.csv, report.json",
                                   result->local_maps.empty() ? "" : ", submaps.jsonl"));
  }
  if (result->stop) {  // the outputs are written up to the last good step
    std::fprintf(stderr, "subslam: error: the run stopped at step %d of %d (t = %.6f s): %s%s\n", result->stop->step,
                 result->steps, result->stop->t, result->stop->reason.c_str(),
                 out.empty() ? "" : "; the outputs hold the run up to there");
    return 1;
  }
  return 0;
}

int Calibrate(const nlohmann::json& invocation) {
  const std::string dataset_dir = absl::GetFlag(FLAGS_dataset);
  const std::string scenario = absl::GetFlag(FLAGS_scenario);
  if (dataset_dir.empty() == scenario.empty()) return Fail("calibrate needs exactly one of --dataset or --scenario");
  if (absl::Status s = cli::CheckFlagsRead({.command = "calibrate", .scenario = !scenario.empty()}); !s.ok()) {
    return Fail(s);
  }
  const std::string out = absl::GetFlag(FLAGS_out);
  if (absl::Status s = CheckOutIsNotInput(out, dataset_dir); !s.ok()) return Fail(s);
  pipeline::CalibrateOptions options;
  options.calibration.known_association = absl::GetFlag(FLAGS_known_association);
  options.out_dir = out;
  options.invocation = invocation;
  options.source = dataset_dir.empty() ? absl::StrCat("scenario ", scenario, " seed ", absl::GetFlag(FLAGS_seed))
                                       : absl::StrCat("dataset ", dataset_dir);
  absl::StatusOr<io::Dataset> dataset = InputDataset(dataset_dir, scenario);
  if (!dataset.ok()) return Fail(dataset.status());
  auto result = pipeline::RunCalibration(*std::move(dataset), options);
  if (!result.ok()) return Fail(result.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam calibrate summary (data set's value -> estimate)\n%s", pipeline::CalibrationTable(*result).c_str());
    PrintOutputs(out, "calibration.json");
  }
  return 0;
}

int Join(const nlohmann::json& invocation) {
  const std::string path = absl::GetFlag(FLAGS_submaps);
  if (path.empty()) return Fail("join needs --submaps FILE");
  auto kind = BackendFlag();
  if (!kind.ok()) return Fail(absl::StrCat("--backend: ", kind.status().message()));
  if (*kind == pipeline::Backend::kNone) {
    return Fail("join needs --backend eif, ceres, ekf, tree-ekf, tree-eif or tree-ceres");
  }
  const std::string dataset_dir = absl::GetFlag(FLAGS_dataset);
  const std::string scenario = absl::GetFlag(FLAGS_scenario);
  if (!dataset_dir.empty() && !scenario.empty()) return Fail("join takes at most one of --dataset or --scenario");
  const cli::CommandContext context{.command = "join", .backend = *kind, .scenario = !scenario.empty()};
  if (absl::Status s = cli::CheckFlagsRead(context); !s.ok()) return Fail(s);
  if (absl::Status s = cli::CheckNamingFlags([] { return cli::BackendOptionsFromFlags().status(); }); !s.ok()) {
    return Fail(s);
  }
  auto submaps = io::ReadSubmapsJsonl(path);
  if (!submaps.ok()) return Fail(submaps.status());
  pipeline::JoinOptions options;
  options.backend = *cli::BackendOptionsFromFlags();
  options.out_dir = absl::GetFlag(FLAGS_out);
  options.invocation = invocation;
  // The initial pose and the ground truth come from the data set or the scenario the
  // local maps were built on, when given.
  if (!dataset_dir.empty() || !scenario.empty()) {
    absl::StatusOr<io::Dataset> dataset = InputDataset(dataset_dir, scenario);
    if (!dataset.ok()) return Fail(dataset.status());
    options.initial_pose = dataset->initial_pose;
    options.truth_poses = dataset->truth_poses;
    options.truth_landmarks = dataset->truth_landmarks;
    options.observed_truth_landmarks = eval::ObservedTruthLandmarks(*dataset);
    options.gps = dataset->gps;
  }
  auto r = pipeline::RunJoin(*submaps, options);
  if (!r.ok()) return Fail(r.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam join summary\n%s", pipeline::JoinSummaryTable(*r).c_str());
    PrintOutputs(options.out_dir, "{anchors,anchors_online,landmarks,joins}.csv, graph.g2o, report.json");
  }
  return 0;
}

int Solve(const nlohmann::json& invocation) {
  const std::string path = absl::GetFlag(FLAGS_graph);
  if (path.empty()) return Fail("solve needs --graph FILE");
  if (absl::Status s = cli::CheckFlagsRead({.command = "solve"}); !s.ok()) return Fail(s);
  posegraph::GraphReadOptions read;
  const std::string format_name = absl::GetFlag(FLAGS_format);
  auto format = format_name.empty() ? posegraph::GraphFormatFromPath(path)
                                    : posegraph::GraphFormatFromString(format_name);
  if (!format.ok()) return Fail(absl::StrCat("--format: ", format.status().message()));
  read.format = *format;
  if (const std::string n = absl::GetFlag(FLAGS_noise); !n.empty()) {
    auto noise = posegraph::NoiseConventionFromString(n);
    if (!noise.ok()) return Fail(absl::StrCat("--noise: ", noise.status().message()));
    read.noise = *noise;
  }
  const std::string initial = absl::GetFlag(FLAGS_initial);
  if (initial != "dead-reckoning" && initial != "file") {
    return Fail(absl::StrCat("--initial must be dead-reckoning or file, got \"", initial, "\""));
  }
  pipeline::SolveOptions options;
  const auto options_from_flags = [&]() -> absl::Status {
    options.methods = absl::GetFlag(FLAGS_methods);
    options.initial_from_file = initial == "file";
    options.poses_per_map = absl::GetFlag(FLAGS_poses_per_map);
    options.tree_joining = absl::GetFlag(FLAGS_tree_joining);
    auto backend = cli::BackendOptionsFromFlags();
    if (!backend.ok()) return backend.status();
    options.eif = backend->eif;
    options.ceres.method = backend->ceres.method;
    options.ceres.loss = backend->ceres.loss;
    options.ceres.loss_scale = backend->ceres.loss_scale;
    options.ceres.max_iterations = absl::GetFlag(FLAGS_max_iterations);
    return options.Validate();
  };
  if (absl::Status s = cli::CheckNamingFlags(options_from_flags); !s.ok()) return Fail(s);
  if (absl::Status s = options_from_flags(); !s.ok()) return Fail(s);
  const absl::Time t0 = absl::Now();
  auto graph = posegraph::ReadGraph(path, read);
  if (!graph.ok()) return Fail(graph.status());
  const double read_seconds = absl::ToDoubleSeconds(absl::Now() - t0);
  options.out_dir = absl::GetFlag(FLAGS_out);
  options.write_local_maps = absl::GetFlag(FLAGS_write_local_maps);
  options.invocation = invocation;
  const posegraph::NoiseConvention noise = read.noise.value_or(posegraph::DefaultNoise(*read.format));
  options.source = {{"file", path},
                    {"format", posegraph::ToString(*read.format)},
                    {"noise", posegraph::ToString(noise)},
                    {"read_seconds", read_seconds}};
  auto result = pipeline::RunSolve(*graph, options);
  if (!result.ok()) return Fail(result.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam solve summary\n  %-34s %s (%s, noise as %s)\n  %-34s %zu / %zu / %d; read in %.3f s\n%s",
                "graph", path.c_str(), posegraph::ToString(*read.format), posegraph::ToString(noise),
                "poses / points / measurements", graph->poses.size(), graph->points.size(),
                graph->num_measurements(), read_seconds, pipeline::SolveTable(*result).c_str());
    PrintOutputs(options.out_dir, absl::StrCat("{report.json,METHOD.g2o", absl::GetFlag(FLAGS_plots) ? ",plots/}" : "}"));
  }
  if (!options.out_dir.empty() && absl::GetFlag(FLAGS_plots)) return Plot({options.out_dir});
  return 0;
}

}  // namespace subslam::tool
