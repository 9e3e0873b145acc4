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
#include "tool_jobs.h"

namespace subslam::tool {
namespace {

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
  absl::StatusOr<InputRequest> input = InputRequestFromFlags("simulate", /*required=*/true);
  if (!input.ok()) return Fail(input.status());
  const sim::ScenarioOptions* options = &input->scenario_options;
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
  absl::StatusOr<RunRequest> request = RunRequestFromFlags();
  if (!request.ok()) return Fail(request.status());
  pipeline::RunOptions& options = request->options;
  options.invocation = invocation;
  const std::string& out = options.out_dir;
  absl::StatusOr<io::Dataset> dataset = ReadInput(request->input);
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
  absl::StatusOr<CalibrateRequest> request = CalibrateRequestFromFlags();
  if (!request.ok()) return Fail(request.status());
  pipeline::CalibrateOptions& options = request->options;
  options.invocation = invocation;
  const std::string& out = options.out_dir;
  absl::StatusOr<io::Dataset> dataset = ReadInput(request->input);
  if (!dataset.ok()) return Fail(dataset.status());
  auto result = pipeline::RunCalibration(*std::move(dataset), options);
  if (!result.ok()) return Fail(result.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam calibrate summary (data set's value -> estimate)\n%s",
                pipeline::CalibrationTable(*result).c_str());
    PrintOutputs(out, "calibration.json");
  }
  return 0;
}

int Join(const nlohmann::json& invocation) {
  absl::StatusOr<JoinRequest> request = JoinRequestFromFlags();
  if (!request.ok()) return Fail(request.status());
  request->options.invocation = invocation;
  const pipeline::JoinOptions& options = request->options;
  auto submaps = io::ReadSubmapsJsonl(request->submaps_path);
  if (!submaps.ok()) return Fail(submaps.status());
  auto r = RunJoinRequest(*request, *submaps);
  if (!r.ok()) return Fail(r.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam join summary\n%s", pipeline::JoinSummaryTable(*r).c_str());
    PrintOutputs(options.out_dir, "{anchors,anchors_online,landmarks,joins}.csv, graph.g2o, report.json");
  }
  return 0;
}

int Solve(const nlohmann::json& invocation) {
  absl::StatusOr<SolveRequest> request = SolveRequestFromFlags();
  if (!request.ok()) return Fail(request.status());
  pipeline::SolveOptions& options = request->options;
  options.invocation = invocation;
  auto graph = ReadSolveGraph(&*request);
  if (!graph.ok()) return Fail(graph.status());
  const std::string& path = request->graph_path;
  const posegraph::GraphReadOptions& read = request->read;
  const posegraph::NoiseConvention noise = read.noise.value_or(posegraph::DefaultNoise(*read.format));
  const double read_seconds = options.source["read_seconds"];
  auto result = pipeline::RunSolve(*graph, options);
  if (!result.ok()) return Fail(result.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam solve summary\n  %-34s %s (%s, noise as %s)\n  %-34s %zu / %zu / %d; read in %.3f s\n%s",
                "graph", path.c_str(), posegraph::ToString(*read.format), posegraph::ToString(noise),
                "poses / points / measurements", graph->poses.size(), graph->points.size(), graph->num_measurements(),
                read_seconds, pipeline::SolveTable(*result).c_str());
    PrintOutputs(options.out_dir,
                 absl::StrCat("{report.json,METHOD.g2o", absl::GetFlag(FLAGS_plots) ? ",plots/}" : "}"));
  }
  if (!options.out_dir.empty() && absl::GetFlag(FLAGS_plots)) return Plot({options.out_dir});
  return 0;
}

}  // namespace subslam::tool
