#include "subslam/pipeline/solve_pipeline.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/time/clock.h"
#include "report_json.h"
#include "subslam/io/output_directory.h"
#include "subslam/io/run_output_writer.h"
#include "subslam/io/submaps_jsonl.h"
#include "subslam/posegraph/batch_solver.h"
#include "subslam/posegraph/graph_format.h"
#include "subslam/posegraph/submap_route.h"

namespace subslam::pipeline {
namespace {

// The process's peak resident set since the last reset (VmHWM), in MB; 0 when /proc
// does not say. Writing 5 to /proc/self/clear_refs resets it (Linux ≥ 4.0), so each
// method's peak is its own; where that fails, the figure is the peak so far.
void ResetPeakResidentMemory() {
  std::ofstream clear("/proc/self/clear_refs");
  if (clear) clear << "5";
}

double PeakResidentMemoryMb() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "VmHWM:") {
      double kb = 0.0;
      status >> kb;
      return kb / 1024.0;
    }
    status.ignore(1 << 20, '\n');
  }
  return 0.0;
}

nlohmann::json Counts(const posegraph::PoseGraph& graph) {
  return {{"poses", graph.poses.size()},
          {"points", graph.points.size()},
          {"odometry", graph.odometry.size()},
          {"point_measurements", graph.point_measurements.size()},
          {"bearing_range_measurements", graph.bearing_range_measurements.size()},
          {"bearing_measurements", graph.bearing_measurements.size()}};
}

nlohmann::json RouteDetails(const posegraph::SubmapRouteReport& r) {
  nlohmann::json stages;
  for (const auto& [name, seconds] : r.stage_times) stages[name] = seconds;
  return {{"local_maps", r.local_maps},
          {"local_map_seconds", r.local_map_seconds},
          {"join_seconds", r.join_seconds},
          {"relinearizations", r.counters.relinearizations},
          {"full_factorizations", r.counters.full_factorizations},
          {"stage_seconds", stages}};
}

// Whether a Ceres termination type means the solver met its convergence test.
bool CeresConverged(const std::string& termination) {
  return termination == "CONVERGENCE" || termination == "USER_SUCCESS";
}

// One method on its own copy of the graph, started at `start`.
SolveMethodResult RunMethod(const std::string& name, const posegraph::PoseGraph& start, const SolveOptions& options,
                            posegraph::PoseGraph* solution, std::vector<LocalSubmap>* local_maps) {
  SolveMethodResult m;
  m.name = name;
  *solution = start;
  ResetPeakResidentMemory();
  const absl::Time t0 = absl::Now();
  absl::Status status;
  if (name == "lm" || name == "dogleg" || name == "gn") {
    backend::CeresSolveOptions ceres = options.ceres;
    ceres.method = *backend::CeresMethodFromString(name);
    auto r = posegraph::SolveGraphWithCeres(solution, ceres);
    status = r.status();
    if (r.ok()) {
      m.iterations = r->iterations;
      m.converged = CeresConverged(r->termination);
      m.details = {{"termination", r->termination}};
    }
  } else {
    posegraph::SubmapRouteOptions route;
    route.poses_per_map = name == "eif" ? 1 : options.poses_per_map;
    route.tree = name != "eif" && options.tree_joining;
    route.eif = options.eif;
    auto r = posegraph::SolveBySubmaps(solution, route, local_maps);
    status = r.status();
    if (r.ok()) {
      m.iterations = static_cast<int>(r->counters.relinearizations);
      m.details = RouteDetails(*r);
      if (name == "submaps-lm") {
        const posegraph::GraphError before = posegraph::EvaluateError(*solution);
        backend::CeresSolveOptions ceres = options.ceres;
        ceres.method = backend::CeresMethod::kLevenbergMarquardt;
        auto polish = posegraph::SolveGraphWithCeres(solution, ceres);
        status = polish.status();
        if (polish.ok()) {
          m.iterations = polish->iterations;
          m.details["route_error"] = before.error;
          m.details["route_relinearizations"] = r->counters.relinearizations;
          m.details["termination"] = polish->termination;
          m.converged = CeresConverged(polish->termination);
        }
      }
    }
  }
  m.seconds = absl::ToDoubleSeconds(absl::Now() - t0);
  m.peak_rss_mb = PeakResidentMemoryMb();
  if (!status.ok()) {
    m.status = std::string(status.message());
    return m;
  }
  const posegraph::GraphError e = posegraph::EvaluateError(*solution);
  m.error = e.error;
  m.chi2 = e.chi2;
  return m;
}

}  // namespace

const std::vector<std::string>& SolveMethodNames() {
  static const auto* names = new std::vector<std::string>{"lm", "dogleg", "gn", "eif", "submaps", "submaps-lm"};
  return *names;
}

absl::Status SolveOptions::Validate() const {
  for (const std::string& name : methods) {
    if (std::find(SolveMethodNames().begin(), SolveMethodNames().end(), name) == SolveMethodNames().end()) {
      return absl::InvalidArgumentError(
          absl::StrCat("unknown solve method \"", name, "\" (", absl::StrJoin(SolveMethodNames(), ", "), ")"));
    }
  }
  if (poses_per_map < 1)
    return absl::InvalidArgumentError(absl::StrCat("poses_per_map must be >= 1, got ", poses_per_map));
  if (absl::Status s = ceres.Validate(); !s.ok()) return s;
  return eif.Validate();
}

absl::StatusOr<SolveResult> RunSolve(const posegraph::PoseGraph& graph, const SolveOptions& options) {
  std::vector<std::string> methods = options.methods.empty() ? SolveMethodNames() : options.methods;
  if (absl::Status s = options.Validate(); !s.ok()) return s;
  if (absl::Status s = graph.Validate(); !s.ok()) return s;
  posegraph::PoseGraph start = graph;
  if (options.initial_from_file) {
    if (!graph.HasEstimates()) {
      return absl::InvalidArgumentError(
          "--initial file: the graph file does not give every pose and point an estimate");
    }
  } else if (absl::Status s = posegraph::InitializeByDeadReckoning(&start); !s.ok()) {
    return s;
  }
  SolveResult result;
  const posegraph::GraphError initial = posegraph::EvaluateError(start);
  result.initial_error = initial.error;
  result.initial_chi2 = initial.chi2;
  if (!options.out_dir.empty()) {
    if (auto dir = io::PrepareOutputDirectory(options.out_dir, "solve"); !dir.ok()) return dir.status();
  }
  nlohmann::json entries = nlohmann::json::array();
  for (const std::string& name : methods) {
    posegraph::PoseGraph solution;
    std::vector<LocalSubmap> local_maps;
    SolveMethodResult m = RunMethod(name, start, options, &solution, options.write_local_maps ? &local_maps : nullptr);
    if (m.status == "ok" && !options.out_dir.empty() && !local_maps.empty()) {
      const std::string path = (std::filesystem::path(options.out_dir) / (name + "_submaps.jsonl")).string();
      if (absl::Status s = io::WriteSubmapsJsonl(path, local_maps); !s.ok()) return s;
    }
    if (m.status == "ok" && !options.out_dir.empty()) {
      posegraph::GraphWriteOptions write;
      write.format = posegraph::GraphFormat::kG2o;
      write.bearing_range_as_points = true;
      const std::string path = (std::filesystem::path(options.out_dir) / (name + ".g2o")).string();
      if (absl::Status s = posegraph::WriteGraph(solution, path, write); !s.ok()) return s;
    }
    nlohmann::json entry = {
        {"name", m.name}, {"status", m.status},         {"converged", m.converged}, {"error", m.error},
        {"chi2", m.chi2}, {"iterations", m.iterations}, {"seconds", m.seconds},     {"peak_rss_mb", m.peak_rss_mb}};
    if (!m.details.is_null()) entry["details"] = m.details;
    entries.push_back(entry);
    result.methods.push_back(std::move(m));
  }
  result.report = {{"job", "solve"},
                   {"graph", options.source},
                   {"counts", Counts(graph)},
                   {"initial", options.initial_from_file ? "file" : "dead-reckoning"},
                   {"initial_error", result.initial_error},
                   {"initial_chi2", result.initial_chi2},
                   {"poses_per_map", options.poses_per_map},
                   {"methods", entries},
                   {"build", BuildJson()}};
  if (!options.invocation.is_null()) result.report["invocation"] = options.invocation;
  if (!options.out_dir.empty()) {
    const std::string path = (std::filesystem::path(options.out_dir) / "report.json").string();
    if (absl::Status s = io::WriteTextFile(path, result.report.dump(2) + "\n"); !s.ok()) return s;
  }
  return result;
}

std::string SolveTable(const SolveResult& result) {
  std::string out = absl::StrFormat("start: error %.6g, chi2 %.6g\n", result.initial_error, result.initial_chi2);
  absl::StrAppendFormat(&out, "%-11s %14s %14s %10s %9s %9s  %s\n", "method", "error", "chi2", "iterations", "seconds",
                        "peak MB", "status");
  for (const SolveMethodResult& m : result.methods) {
    if (m.status != "ok") {
      absl::StrAppendFormat(&out, "%-11s %14s %14s %10s %9.3f %9.1f  %s\n", m.name, "-", "-", "-", m.seconds,
                            m.peak_rss_mb, m.status);
      continue;
    }
    absl::StrAppendFormat(
        &out, "%-11s %14.4f %14.4f %10d %9.3f %9.1f  %s\n", m.name, m.error, m.chi2, m.iterations, m.seconds,
        m.peak_rss_mb,
        m.converged ? "converged" : absl::StrCat("NOT CONVERGED: stopped at the iteration limit (--max_iterations)"));
  }
  return out;
}

}  // namespace subslam::pipeline
