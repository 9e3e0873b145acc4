// subslam — command-line tool.
//
//   subslam simulate --scenario NAME [--seed S] --out DIR [scenario flags]
//   subslam run (--dataset DIR | --scenario NAME [--seed S]) --frontend odometry|ekfslam|fastslam|seif|iseif|rbpf|ekf
//               --out DIR [estimator and noise flags]
//   subslam study NAME --out DIR [--trials N] [--methods A,B] [--workers W] [--shard K/N] [--dataset DIR]
//   subslam study merge DIR... --out DIR
//   subslam solve --graph FILE [--format g2o|toro|isam|gtsam] [--noise …] [--methods A,B] --out DIR
//   subslam plot DIR...
//   subslam scenarios
//
// Every flag is listed by `subslam --help`.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/time/clock.h"
#include "cli_reference.h"
#include "backend_flags.h"
#include "frontend_flags.h"
#include "flags_read_by_command.h"
#include "keep_freed_memory_flag.h"
#include "subslam/eval/trajectory_errors.h"
#include "subslam/pipeline/join_pipeline.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/pipeline/solve_pipeline.h"
#include "subslam/posegraph/dataset_graph.h"
#include "subslam/posegraph/graph_format.h"
#include "subslam/io/submaps_jsonl.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/io/dataset_writer.h"
#include "subslam/sim/simulator.h"
#include "subslam/study/study.h"
#include "subslam/study/study_runner.h"

// Flag defaults come from the option structs, so the tool and the library agree.
namespace {
const subslam::sim::ScenarioOptions kScenarioDefaults;
}  // namespace

ABSL_FLAG(std::string, dataset, "", "data-set directory holding dataset.json");
ABSL_FLAG(std::string, scenario, "", "simulated scenario name (see `subslam scenarios`)");
ABSL_FLAG(uint64_t, seed, kScenarioDefaults.seed, "scenario seed (noise, detections, clutter)");
ABSL_FLAG(std::optional<uint64_t>, world_seed, std::nullopt,
          "scenario world seed (landmarks, path jitter); default: --seed");
ABSL_FLAG(std::optional<double>, alpha, std::nullopt,
          "simulated detection probability alpha (default 1.0)");
ABSL_FLAG(std::optional<double>, beta, std::nullopt,
          "simulated false-alarm probability beta per visible feature (default 0.0)");
ABSL_FLAG(std::optional<double>, duration, std::nullopt, "truncate the simulation [s]");
ABSL_FLAG(int, fmj_case, kScenarioDefaults.fmj_case, "fmj-ellipse: case 1 (even landmarks) or 2 (uneven)");
ABSL_FLAG(double, world_size, kScenarioDefaults.random_world_size_m, "random scenario: world side [m]");
ABSL_FLAG(int, landmarks, kScenarioDefaults.random_landmarks, "random scenario: number of landmarks");
ABSL_FLAG(double, path_length, kScenarioDefaults.random_path_length_m, "random scenario: distance driven [m]");
ABSL_FLAG(double, lattice_spacing, kScenarioDefaults.random_lattice_spacing_m,
          "random scenario: landmarks on a square lattice of this spacing [m] instead of "
          "--landmarks uniform ones (0: off)");
ABSL_FLAG(double, noise_scale, kScenarioDefaults.random_noise_scale, "random scenario: multiplies every sigma");
ABSL_FLAG(bool, signature, kScenarioDefaults.with_signature, "simulated detections carry a noisy signature");
ABSL_FLAG(std::string, out, "", "output directory");
ABSL_FLAG(std::string, frontend, subslam::pipeline::ToString(subslam::pipeline::RunOptions{}.frontend),
          "odometry | ekfslam | fastslam | seif | iseif | rbpf | ekf");
ABSL_FLAG(std::string, submaps, "", "join: the local maps (submaps.jsonl)");
ABSL_FLAG(std::optional<double>, sigma_v, std::nullopt, "override speed noise sigma [m/s]");
ABSL_FLAG(std::optional<double>, sigma_u1, std::nullopt,
          "override turn-rate [rad/s] or steering [rad] noise sigma");
ABSL_FLAG(std::optional<double>, sigma_range, std::nullopt, "override range sigma [m]");
ABSL_FLAG(std::optional<double>, sigma_bearing, std::nullopt, "override bearing sigma [rad]");
ABSL_FLAG(std::optional<double>, max_range, std::nullopt, "ignore detections beyond [m]");
ABSL_FLAG(std::optional<double>, sensor_yaw, std::nullopt,
          "add this to every bearing [rad]: the sensor's yaw on the vehicle, a calibration "
          "(Victoria Park: -0.0182, bench/sensor_yaw_calibration); given, it is taken as calibrated "
          "and the back-end's online yaw calibration is off unless --sensor_yaw_calibration=true");
ABSL_FLAG(int, trials, 0, "study: trials per method and setting (0: the paper's)");
ABSL_FLAG(int, workers, 0, "study: runs at a time, one thread each (0: every core)");
ABSL_FLAG(std::vector<std::string>, methods, {}, "study: only these methods, comma-separated (default: all)");
ABSL_FLAG(std::string, shard, "1/1", "study: run slice K of N (K/N); `subslam study merge` combines the slices");
ABSL_FLAG(bool, plots, true, "study: draw the study's figures when it is complete (`subslam plot`)");
ABSL_FLAG(std::string, graph, "", "solve: the graph file (g2o, TORO, iSAM or GTSAM text)");
ABSL_FLAG(std::string, format, "",
          "solve: the graph file's format, g2o | toro | isam | gtsam (default: from the extension: .g2o, "
          ".graph/.toro, .isam)");
ABSL_FLAG(std::string, noise, "",
          "solve: read the file's noise numbers as covariance | information | sqrt-information (default: the "
          "format's: g2o and toro information, isam sqrt-information, gtsam covariance)");
ABSL_FLAG(std::string, initial, "dead-reckoning",
          "solve: start from dead-reckoning | file (the file's vertex estimates)");
ABSL_FLAG(int, poses_per_map, subslam::pipeline::SolveOptions{}.poses_per_map,
          "solve: poses per local map of the submap route (methods submaps, submaps-lm)");
ABSL_FLAG(bool, tree_joining, subslam::pipeline::SolveOptions{}.tree_joining,
          "solve: the submap route (submaps, submaps-lm) joins its local maps pairwise in a binary tree; false: in "
          "order into one map");
ABSL_FLAG(bool, write_local_maps, false,
          "solve: also write the submap routes' local maps (METHOD_submaps.jsonl) for `subslam join`");
ABSL_FLAG(bool, progress, true, "show a progress line on a terminal");
ABSL_FLAG(bool, quiet, false, "do not print the summary table");

namespace {

using subslam::sim::ScenarioOptions;

ScenarioOptions ScenarioOptionsFromFlags() {
  ScenarioOptions o;
  o.seed = absl::GetFlag(FLAGS_seed);
  o.world_seed = absl::GetFlag(FLAGS_world_seed);
  o.detection_probability = absl::GetFlag(FLAGS_alpha);
  o.false_alarm_probability = absl::GetFlag(FLAGS_beta);
  o.duration_s = absl::GetFlag(FLAGS_duration);
  o.fmj_case = absl::GetFlag(FLAGS_fmj_case);
  o.random_world_size_m = absl::GetFlag(FLAGS_world_size);
  o.random_landmarks = absl::GetFlag(FLAGS_landmarks);
  o.random_path_length_m = absl::GetFlag(FLAGS_path_length);
  o.random_noise_scale = absl::GetFlag(FLAGS_noise_scale);
  o.random_lattice_spacing_m = absl::GetFlag(FLAGS_lattice_spacing);
  o.with_signature = absl::GetFlag(FLAGS_signature);
  return o;
}

int Fail(const absl::Status& status) {
  std::fprintf(stderr, "subslam: error: %s\n", std::string(status.message()).c_str());
  return 1;
}

int Simulate() {
  const std::string name = absl::GetFlag(FLAGS_scenario);
  const std::string out = absl::GetFlag(FLAGS_out);
  if (name.empty() || out.empty()) {
    return Fail(absl::InvalidArgumentError("simulate needs --scenario and --out"));
  }
  const ScenarioOptions options = ScenarioOptionsFromFlags();
  auto config = subslam::sim::MakeScenario(name, options);
  if (!config.ok()) return Fail(config.status());
  auto dataset = subslam::sim::Simulate(*config, options.seed);
  if (!dataset.ok()) return Fail(dataset.status());
  subslam::io::SimulationInfo info{name, options.seed, config->detection_probability,
                                   config->false_alarm_probability};
  if (auto s = subslam::io::WriteDataset(*dataset, out, &info); !s.ok()) return Fail(s);
  // The known-association graph beside it, in every graph format (docs/formats.md).
  if (auto s = subslam::posegraph::WriteDatasetGraphs(*dataset, out); !s.ok()) return Fail(s);
  std::printf("wrote %s: %zu controls, %zu scans, %zu detections, %zu landmarks -> %s (and graph.{isam,g2o,toro})\n",
              name.c_str(), dataset->controls.size(), dataset->scans.size(),
              dataset->NumDetections(), dataset->truth_landmarks.size(), out.c_str());
  return 0;
}

int Join() {
  const std::string path = absl::GetFlag(FLAGS_submaps);
  if (path.empty()) return Fail(absl::InvalidArgumentError("join needs --submaps FILE"));
  auto backend = subslam::cli::BackendOptionsFromFlags();
  if (!backend.ok()) return Fail(backend.status());
  if (backend->kind == subslam::pipeline::Backend::kNone) {
    return Fail(absl::InvalidArgumentError("join needs --backend eif, ceres, ekf, tree-ekf, tree-eif or tree-ceres"));
  }
  auto submaps = subslam::io::ReadSubmapsJsonl(path);
  if (!submaps.ok()) return Fail(submaps.status());
  subslam::pipeline::JoinOptions options;
  options.backend = *backend;
  options.out_dir = absl::GetFlag(FLAGS_out);
  // The initial pose and the ground truth come from the data set or the scenario the
  // local maps were built on, when given.
  const std::string dataset_dir = absl::GetFlag(FLAGS_dataset);
  const std::string scenario = absl::GetFlag(FLAGS_scenario);
  absl::StatusOr<subslam::io::Dataset> dataset = absl::NotFoundError("");
  if (!dataset_dir.empty()) {
    dataset = subslam::io::ReadDataset(dataset_dir);
  } else if (!scenario.empty()) {
    dataset = subslam::sim::SimulateScenario(scenario, ScenarioOptionsFromFlags());
  }
  if (!dataset_dir.empty() || !scenario.empty()) {
    if (!dataset.ok()) return Fail(dataset.status());
    options.initial_pose = dataset->initial_pose;
    options.truth_poses = dataset->truth_poses;
    options.truth_landmarks = dataset->truth_landmarks;
    options.observed_truth_landmarks = subslam::eval::ObservedTruthLandmarks(*dataset);
  }
  auto r = subslam::pipeline::RunJoin(*submaps, options);
  if (!r.ok()) return Fail(r.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam join summary\n%s", r->report.dump(2).c_str());
    std::printf("\n");
    if (!options.out_dir.empty()) {
      std::printf("outputs: %s/{anchors,landmarks}.csv, graph.g2o, report.json\n", options.out_dir.c_str());
    }
  }
  return 0;
}

int Run() {
  const std::string dataset_dir = absl::GetFlag(FLAGS_dataset);
  const std::string scenario = absl::GetFlag(FLAGS_scenario);
  if (dataset_dir.empty() == scenario.empty()) {
    return Fail(absl::InvalidArgumentError("run needs exactly one of --dataset or --scenario"));
  }
  subslam::pipeline::RunOptions options;
  auto frontend = subslam::pipeline::FrontendFromString(absl::GetFlag(FLAGS_frontend));
  if (!frontend.ok()) return Fail(frontend.status());
  options.frontend = *frontend;
  if (absl::Status st = subslam::cli::SetFrontendOptionsFromFlags(&options); !st.ok()) return Fail(st);
  auto backend = subslam::cli::BackendOptionsFromFlags(absl::GetFlag(FLAGS_sensor_yaw).has_value());
  if (!backend.ok()) return Fail(backend.status());
  options.backend = *backend;
  options.noise.sigma_v = absl::GetFlag(FLAGS_sigma_v);
  options.noise.sigma_u1 = absl::GetFlag(FLAGS_sigma_u1);
  options.noise.sigma_range = absl::GetFlag(FLAGS_sigma_range);
  options.noise.sigma_bearing = absl::GetFlag(FLAGS_sigma_bearing);
  options.noise.max_range = absl::GetFlag(FLAGS_max_range);
  options.noise.sensor_yaw = absl::GetFlag(FLAGS_sensor_yaw);
  options.out_dir = absl::GetFlag(FLAGS_out);
  options.progress = absl::GetFlag(FLAGS_progress);

  absl::StatusOr<subslam::io::Dataset> dataset;
  if (!dataset_dir.empty()) {
    dataset = subslam::io::ReadDataset(dataset_dir);
    options.source = absl::StrCat("dataset ", dataset_dir);
  } else {
    const ScenarioOptions scenario_options = ScenarioOptionsFromFlags();
    dataset = subslam::sim::SimulateScenario(scenario, scenario_options);
    options.source = absl::StrCat("scenario ", scenario, " seed ", scenario_options.seed);
  }
  if (!dataset.ok()) return Fail(dataset.status());
  auto result = subslam::pipeline::RunPipeline(*std::move(dataset), options);
  if (!result.ok()) return Fail(result.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam run summary\n%s", subslam::pipeline::SummaryTable(*result).c_str());
    if (!options.out_dir.empty()) {
      const bool local_maps = !result->local_maps.empty();
      std::printf("  %-34s %s/{trajectory_online,trajectory_final,landmarks}.csv, report.json%s\n",
                  "outputs", options.out_dir.c_str(), local_maps ? ", submaps.jsonl" : "");
    }
  }
  if (result->stop) {  // the outputs are written up to the last good step
    std::fprintf(stderr, "subslam: error: the run stopped at step %d of %d (t = %.6f s): %s%s\n", result->stop->step,
                 result->steps, result->stop->t, result->stop->reason.c_str(),
                 options.out_dir.empty() ? "" : "; the outputs hold the run up to there");
    return 1;
  }
  return 0;
}

int Plot(const std::vector<std::string>& dirs, bool list_files);

// `subslam solve --graph FILE --out DIR`: every chosen solver on one graph.
int Solve() {
  const std::string path = absl::GetFlag(FLAGS_graph);
  if (path.empty()) return Fail(absl::InvalidArgumentError("solve needs --graph FILE"));
  subslam::posegraph::GraphReadOptions read;
  if (const std::string f = absl::GetFlag(FLAGS_format); !f.empty()) {
    auto format = subslam::posegraph::GraphFormatFromString(f);
    if (!format.ok()) return Fail(format.status());
    read.format = *format;
  } else {
    auto format = subslam::posegraph::GraphFormatFromPath(path);
    if (!format.ok()) return Fail(format.status());
    read.format = *format;
  }
  if (const std::string n = absl::GetFlag(FLAGS_noise); !n.empty()) {
    auto noise = subslam::posegraph::NoiseConventionFromString(n);
    if (!noise.ok()) return Fail(noise.status());
    read.noise = *noise;
  }
  const absl::Time t0 = absl::Now();
  auto graph = subslam::posegraph::ReadGraph(path, read);
  if (!graph.ok()) return Fail(graph.status());
  const double read_seconds = absl::ToDoubleSeconds(absl::Now() - t0);
  subslam::pipeline::SolveOptions options;
  options.methods = absl::GetFlag(FLAGS_methods);
  const std::string initial = absl::GetFlag(FLAGS_initial);
  if (initial != "dead-reckoning" && initial != "file") {
    return Fail(absl::InvalidArgumentError("--initial must be dead-reckoning or file"));
  }
  options.initial_from_file = initial == "file";
  options.poses_per_map = absl::GetFlag(FLAGS_poses_per_map);
  options.tree_joining = absl::GetFlag(FLAGS_tree_joining);
  auto backend = subslam::cli::BackendOptionsFromFlags();
  if (!backend.ok()) return Fail(backend.status());
  options.eif = backend->eif;
  options.ceres.method = backend->ceres.method;
  options.ceres.loss = backend->ceres.loss;
  options.ceres.loss_scale = backend->ceres.loss_scale;
  options.out_dir = absl::GetFlag(FLAGS_out);
  options.write_local_maps = absl::GetFlag(FLAGS_write_local_maps);
  const subslam::posegraph::NoiseConvention noise =
      read.noise.value_or(subslam::posegraph::DefaultNoise(*read.format));
  options.source = {{"file", path},
                    {"format", subslam::posegraph::ToString(*read.format)},
                    {"noise", subslam::posegraph::ToString(noise)},
                    {"read_seconds", read_seconds}};
  auto result = subslam::pipeline::RunSolve(*graph, options);
  if (!result.ok()) return Fail(result.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam solve: %s (%s, noise as %s): %zu poses, %zu points, %d measurements; read in %.3f s\n%s",
                path.c_str(), subslam::posegraph::ToString(*read.format), subslam::posegraph::ToString(noise),
                graph->poses.size(), graph->points.size(), graph->num_measurements(), read_seconds,
                subslam::pipeline::SolveTable(*result).c_str());
    if (!options.out_dir.empty()) {
      std::printf("outputs: %s/{report.json,METHOD.g2o}%s\n", options.out_dir.c_str(),
                  absl::GetFlag(FLAGS_plots) ? ", plots/" : "");
    }
  }
  if (!options.out_dir.empty() && absl::GetFlag(FLAGS_plots)) return Plot({options.out_dir}, /*list_files=*/false);
  return 0;
}

// scripts/plot.py: SUBSLAM_PLOT_SCRIPT if set; else beside an installed tool
// (<prefix>/share/subslam/plot.py); else the source tree's.
std::string PlotScript() {
  if (const char* path = std::getenv("SUBSLAM_PLOT_SCRIPT"); path != nullptr && *path != '\0') return path;
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::filesystem::path installed = exe.parent_path().parent_path() / "share" / "subslam" / "plot.py";
    if (std::filesystem::exists(installed)) return installed.string();
  }
  return SUBSLAM_SOURCE_PLOT_SCRIPT;
}

std::string ShellQuoted(const std::string& text) {
  std::string quoted = "'";
  for (char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

// `subslam plot DIR...`: the figures of run, join and study directories (scripts/plot.py,
// run by Debian's Python with python3-matplotlib).
int Plot(const std::vector<std::string>& dirs, bool list_files) {
  if (dirs.empty()) return Fail(absl::InvalidArgumentError("plot needs the output directories to draw"));
  const std::string script = PlotScript();
  if (!std::filesystem::exists(script)) {
    return Fail(absl::NotFoundError(absl::StrCat("the plot script ", script, " is missing (set SUBSLAM_PLOT_SCRIPT)")));
  }
  std::string command = absl::StrCat("/usr/bin/python3 ", ShellQuoted(script));
  for (const std::string& dir : dirs) absl::StrAppend(&command, " ", ShellQuoted(dir));
  if (!list_files) absl::StrAppend(&command, " > /dev/null");
  std::fflush(stdout);
  const int status = std::system(command.c_str());
  if (status != 0) {
    return Fail(absl::InternalError(absl::StrCat("plotting with ", script, " failed (its message is above; it runs "
                                                 "/usr/bin/python3 with python3-matplotlib)")));
  }
  return 0;
}

// `subslam study NAME` or `subslam study merge DIR...`.
int Study(const std::vector<char*>& args) {
  if (args.size() < 3) {
    return Fail(absl::InvalidArgumentError(absl::StrCat(
        "study needs a name (", absl::StrJoin(subslam::study::StudyNames(), ", "), ") or merge DIR...")));
  }
  const std::string out = absl::GetFlag(FLAGS_out);
  // A study runs each method with its paper's settings (`--methods` chooses among them):
  // a front-end or back-end flag would change nothing, so it is refused.
  constexpr std::string_view kWhy = "each method runs with its paper's settings, recorded in its command";
  if (std::string(args[2]) == "merge") {
    if (absl::Status s = subslam::cli::CheckOnlyFlagsReadBy("study merge", {"out", "quiet", "plots", "keep_freed_memory"}, kWhy);
        !s.ok()) {
      return Fail(s);
    }
    std::vector<std::string> dirs(args.begin() + 3, args.end());
    if (absl::Status s = subslam::study::MergeStudy(dirs, out); !s.ok()) return Fail(s);
    if (!absl::GetFlag(FLAGS_quiet)) std::printf("merged %zu slices -> %s/summary.md\n", dirs.size(), out.c_str());
    return absl::GetFlag(FLAGS_plots) ? Plot({out}, /*list_files=*/false) : 0;
  }
  if (args.size() != 3) return Fail(absl::InvalidArgumentError("study takes one study name"));
  if (absl::Status s = subslam::cli::CheckOnlyFlagsReadBy(
          "study", {"out", "trials", "workers", "methods", "dataset", "shard", "progress", "quiet", "plots",
                    "keep_freed_memory"},
          kWhy);
      !s.ok()) {
    return Fail(s);
  }
  auto study = subslam::study::MakeStudy(args[2]);
  if (!study.ok()) return Fail(study.status());
  subslam::study::StudyOptions options;
  options.trials = absl::GetFlag(FLAGS_trials);
  options.workers = absl::GetFlag(FLAGS_workers);
  options.methods = absl::GetFlag(FLAGS_methods);
  options.dataset_dir = absl::GetFlag(FLAGS_dataset);
  auto shard = subslam::study::ShardFromString(absl::GetFlag(FLAGS_shard));
  if (!shard.ok()) return Fail(shard.status());
  options.shard = *shard;
  options.out_dir = out;
  options.progress = absl::GetFlag(FLAGS_progress);
  if (absl::Status s = subslam::study::RunStudy(**study, options); !s.ok()) return Fail(s);
  if (!absl::GetFlag(FLAGS_quiet)) {
    if (options.shard.count == 1) {
      std::FILE* f = std::fopen((out + "/summary.md").c_str(), "r");
      for (int c; f != nullptr && (c = std::fgetc(f)) != EOF;) std::putchar(c);
      if (f != nullptr) std::fclose(f);
      std::printf("\noutputs: %s/{summary.md,summary.json,runs.csv,timings.csv,config.json}%s\n", out.c_str(),
                  absl::GetFlag(FLAGS_plots) ? ", plots/" : "");
    } else {
      std::printf("slice %d/%d -> %s/runs.csv; combine the slices with `subslam study merge DIR... --out DIR`\n",
                  options.shard.index, options.shard.count, out.c_str());
    }
  }
  if (options.shard.count == 1 && absl::GetFlag(FLAGS_plots)) return Plot({out}, /*list_files=*/false);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(subslam::pipeline::CliUsage());
  std::vector<char*> args = absl::ParseCommandLine(argc, argv);
  subslam::pipeline::ApplyKeepFreedMemoryFlag();
  if (args.size() >= 2 && std::string(args[1]) == "study") return Study(args);
  if (args.size() >= 2 && std::string(args[1]) == "plot") {
    if (absl::Status s = subslam::cli::CheckOnlyFlagsReadBy("plot", {"quiet", "keep_freed_memory"},
                                                            "it draws what the output directories hold");
        !s.ok()) {
      return Fail(s);
    }
    return Plot(std::vector<std::string>(args.begin() + 2, args.end()), !absl::GetFlag(FLAGS_quiet));
  }
  if (args.size() != 2) {
    std::fprintf(stderr, "%s\n", absl::ProgramUsageMessage().data());
    return 2;
  }
  const std::string command = args[1];
  if (command == "simulate") return Simulate();
  if (command == "run") return Run();
  if (command == "join") return Join();
  if (command == "solve") return Solve();
  if (command == "cli-reference") {
    std::printf("%s", subslam::pipeline::CliReferenceMarkdown().c_str());
    return 0;
  }
  if (command == "scenarios") {
    std::printf("%s\n", absl::StrJoin(subslam::sim::ScenarioNames(), "\n").c_str());
    return 0;
  }
  std::fprintf(stderr, "subslam: unknown command \"%s\"\n%s\n", command.c_str(),
               absl::ProgramUsageMessage().data());
  return 2;
}
