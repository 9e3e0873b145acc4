// SEIF / ISEIF studies (Iterative Sparse Extended Information Filter, §3):
//
//  1. Monte Carlo on a scenario (default iseif-circle, 50 seeds): EKF-SLAM, SEIF and
//     ISEIF side by side — the mean over runs of the per-run RMS of pose x, y, heading
//     and of landmark x, y (the paper's Table 2), the pose NEES averaged over the runs
//     at every step against its two-sided 95% bounds (Bar-Shalom's average NEES: for 3
//     dof and 50 runs [2.36, 3.72]) — its mean over the steps and the share of steps
//     inside — and the total estimator time.
//  2. Growth: SEIF's time per step on `random` worlds of constant landmark density and
//     growing size, first and last tenth of each run (flat = constant time).
//
//   seif_bench [--runs 50] [--filters ekfslam,seif,iseif] [--known_association]
//              [--seif_pose_covariance exact] [front-end flags as `subslam run` takes them]
//              [--growth_landmarks 300,1200,4800] [--out FILE]
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "backend_flags.h"  // --known_association
#include "frontend_flags.h"
#include "keep_freed_memory_flag.h"
#include "subslam/eval/nees.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/sim/simulator.h"

ABSL_FLAG(std::string, scenario, "iseif-circle", "the Monte Carlo scenario");
ABSL_FLAG(int, runs, 50, "Monte Carlo runs (seeds first_seed … first_seed + runs − 1)");
ABSL_FLAG(uint64_t, first_seed, 1, "first seed");
ABSL_FLAG(std::string, filters, "ekfslam,seif,iseif", "filters, comma-separated");
ABSL_FLAG(std::string, growth_landmarks, "300,1200,4800,19200",
          "random-world sizes (landmarks) for the growth table (empty: skip)");
ABSL_FLAG(std::string, growth_filters, "seif,iseif", "filters of the growth table");
ABSL_FLAG(int, growth_ekf_max_landmarks, 1200, "run ekfslam in the growth table up to this size");
ABSL_FLAG(std::string, out, "", "write the results as JSON here");

namespace {

using nlohmann::json;
using subslam::pipeline::Frontend;

std::vector<std::string> SplitList(const std::string& s) {
  std::vector<std::string> out;
  for (absl::string_view part : absl::StrSplit(s, ',', absl::SkipEmpty())) out.emplace_back(part);
  return out;
}

// The run options of a filter named on the command line, with the front-end flags applied
// as `subslam run` applies them (--seif_*, --iseif_*, --known_association, …; docs/cli.md);
// RunPipeline validates the values. EKF-SLAM, the reference, always associates by nearest
// neighbour.
absl::StatusOr<subslam::pipeline::RunOptions> OptionsFor(const std::string& name) {
  subslam::pipeline::RunOptions o;
  absl::StatusOr<Frontend> frontend = subslam::pipeline::FrontendFromString(name);
  if (!frontend.ok()) return frontend.status();
  o.frontend = *frontend;
  if (absl::Status st = subslam::cli::SetFrontendOptionsFromFlags(&o); !st.ok()) return st;
  o.ekf.landmarks.known_association = false;
  return o;
}

struct MonteCarloRow {
  std::string filter;
  int runs = 0;
  double rms_x = 0, rms_y = 0, rms_heading_deg = 0, landmark_rms_x = 0, landmark_rms_y = 0;
  double mean_average_nees = 0, steps_inside = 0;
  double seconds = 0;
  int failed_runs = 0;
  double iterations_per_update = 0;
  std::vector<double> nees_sum;
  std::vector<int> nees_count;
};

json RowJson(const MonteCarloRow& r) {
  return {{"filter", r.filter},
          {"runs", r.runs},
          {"rms_x_m", r.rms_x},
          {"rms_y_m", r.rms_y},
          {"rms_heading_deg", r.rms_heading_deg},
          {"landmark_rms_x_m", r.landmark_rms_x},
          {"landmark_rms_y_m", r.landmark_rms_y},
          {"mean_average_nees", r.mean_average_nees},
          {"steps_inside_95", r.steps_inside},
          {"total_seconds", r.seconds},
          {"failed_runs", r.failed_runs},
          {"iterations_per_iterated_update", r.iterations_per_update}};
}

}  // namespace

// One filter's Monte Carlo over `runs` seeds of `scenario`: the mean RMS errors, the
// average NEES against its bounds, failures, time and ISEIF's iterations per update.
static absl::StatusOr<MonteCarloRow> RunMonteCarlo(const std::string& name, const std::string& scenario, int runs) {
  const absl::StatusOr<subslam::pipeline::RunOptions> options = OptionsFor(name);
  if (!options.ok()) return options.status();
  MonteCarloRow row;
  row.filter = name;
  double iterations = 0, iterated_updates = 0;
  for (int k = 0; k < runs; ++k) {
    subslam::sim::ScenarioOptions so;
    so.seed = absl::GetFlag(FLAGS_first_seed) + k;
    absl::StatusOr<subslam::io::Dataset> d = subslam::sim::SimulateScenario(scenario, so);
    if (!d.ok()) return d.status();
    absl::StatusOr<subslam::pipeline::RunResult> r = subslam::pipeline::RunPipeline(*std::move(d), *options);
    if (!r.ok()) {
      return absl::Status(r.status().code(), absl::StrCat(name, " seed ", so.seed, ": ", r.status().message()));
    }
    ++row.runs;
    row.rms_x += r->errors->rms_x_m;
    row.rms_y += r->errors->rms_y_m;
    row.rms_heading_deg += r->errors->rms_heading_rad * 180.0 / M_PI;
    row.landmark_rms_x += r->map_errors->rms_x_m;
    row.landmark_rms_y += r->map_errors->rms_y_m;
    row.seconds += r->wall_seconds;
    row.failed_runs += r->errors->failed ? 1 : 0;
    const std::vector<double>& nees = r->errors->nees;
    if (row.nees_sum.size() < nees.size()) {
      row.nees_sum.resize(nees.size(), 0.0);
      row.nees_count.resize(nees.size(), 0);
    }
    for (size_t s = 0; s < nees.size(); ++s) {
      if (!std::isfinite(nees[s])) continue;
      row.nees_sum[s] += nees[s];
      ++row.nees_count[s];
    }
    const json& counters = r->report["estimator_counters"];
    if (counters.contains("iterations")) {
      iterations += counters["iterations"].get<double>();
      iterated_updates += counters["iterated_updates"].get<double>();
    }
  }
  for (double* v : {&row.rms_x, &row.rms_y, &row.rms_heading_deg, &row.landmark_rms_x, &row.landmark_rms_y}) {
    *v /= row.runs;
  }
  // Average NEES over the runs at each step where every run has one (the bounds
  // are for exactly `runs` samples).
  const subslam::eval::NeesBounds bounds = subslam::eval::AverageNeesBounds(3, row.runs);
  int steps = 0, inside = 0;
  double sum = 0;
  for (size_t s = 0; s < row.nees_sum.size(); ++s) {
    if (row.nees_count[s] != row.runs) continue;
    const double average = row.nees_sum[s] / row.runs;
    ++steps;
    sum += average;
    inside += bounds.Contains(average) ? 1 : 0;
  }
  row.mean_average_nees = steps > 0 ? sum / steps : std::numeric_limits<double>::quiet_NaN();
  row.steps_inside = steps > 0 ? static_cast<double>(inside) / steps : 0.0;
  row.iterations_per_update = iterated_updates > 0 ? iterations / iterated_updates : 0.0;
  return row;
}

// SEIF's time per step on `random` worlds of constant density (300 landmarks per
// 200 m × 200 m) and growing size: printed, and the rows in `out`.
static absl::Status RunGrowth(const std::vector<std::string>& sizes, json* out) {
  std::printf("\nrandom worlds, 300 landmarks per 200 m x 200 m, path 5 x the world side, seed 1\n");
  std::printf(
      "| filter | landmarks | world [m] | steps | map size | time [s] | us/step | "
      "us/step first tenth | us/step last tenth |\n");
  std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  json growth = json::array();
  std::vector<std::string> filters = SplitList(absl::GetFlag(FLAGS_growth_filters));
  for (const std::string& size_text : sizes) {
    int landmarks = 0;
    if (!absl::SimpleAtoi(size_text, &landmarks) || landmarks <= 0) {
      return absl::InvalidArgumentError(absl::StrCat("bad --growth_landmarks entry \"", size_text, "\""));
    }
    subslam::sim::ScenarioOptions so;
    so.random_landmarks = landmarks;
    so.random_world_size_m = 200.0 * std::sqrt(landmarks / 300.0);
    so.random_path_length_m = 5.0 * so.random_world_size_m;
    absl::StatusOr<subslam::io::Dataset> d = subslam::sim::SimulateScenario("random", so);
    if (!d.ok()) return d.status();
    std::vector<std::string> row_filters = filters;
    if (landmarks <= absl::GetFlag(FLAGS_growth_ekf_max_landmarks)) row_filters.push_back("ekfslam");
    for (const std::string& name : row_filters) {
      const absl::StatusOr<subslam::pipeline::RunOptions> options = OptionsFor(name);
      if (!options.ok()) return options.status();
      absl::StatusOr<subslam::pipeline::RunResult> r = subslam::pipeline::RunPipeline(*d, *options);
      if (!r.ok()) return absl::Status(r.status().code(), absl::StrCat(name, ": ", r.status().message()));
      const std::vector<double>& tenth = r->wall_seconds_by_tenth;
      const double per_tenth_steps = r->steps / 10.0;
      const double first = tenth.empty() ? 0 : tenth.front() / per_tenth_steps * 1e6;
      const double last = tenth.size() < 2 ? 0 : (tenth.back() - tenth[tenth.size() - 2]) / per_tenth_steps * 1e6;
      std::printf("| %s | %d | %.0f | %d | %zu | %.3f | %.1f | %.1f | %.1f |\n", name.c_str(), landmarks,
                  so.random_world_size_m, r->steps, r->landmarks.size(), r->wall_seconds,
                  r->wall_seconds / r->steps * 1e6, first, last);
      growth.push_back({{"filter", name},
                        {"landmarks", landmarks},
                        {"world_m", so.random_world_size_m},
                        {"steps", r->steps},
                        {"map_size", r->landmarks.size()},
                        {"seconds", r->wall_seconds},
                        {"us_per_step_first_tenth", first},
                        {"us_per_step_last_tenth", last}});
    }
  }
  *out = growth;
  return absl::OkStatus();
}

int main(int argc, char** argv) {
  absl::ParseCommandLine(argc, argv);
  subslam::pipeline::ApplyKeepFreedMemoryFlag();
  const int runs = absl::GetFlag(FLAGS_runs);
  const std::string scenario = absl::GetFlag(FLAGS_scenario);
  json out = json::object();

  // 1. Monte Carlo.
  std::vector<MonteCarloRow> rows;
  for (const std::string& name : SplitList(absl::GetFlag(FLAGS_filters))) {
    absl::StatusOr<MonteCarloRow> row = RunMonteCarlo(name, scenario, runs);
    if (!row.ok()) {
      std::fprintf(stderr, "%s\n", std::string(row.status().message()).c_str());
      return 1;
    }
    rows.push_back(*row);
    std::fprintf(stderr, "%s done: %.1f s\n", name.c_str(), row->seconds);
  }
  if (!rows.empty()) {
    const subslam::eval::NeesBounds bounds = subslam::eval::AverageNeesBounds(3, runs);
    std::printf("%s, %d runs (seeds %llu-%llu), %s association; average-NEES bounds [%.2f, %.2f]\n", scenario.c_str(),
                runs, static_cast<unsigned long long>(absl::GetFlag(FLAGS_first_seed)),
                static_cast<unsigned long long>(absl::GetFlag(FLAGS_first_seed) + runs - 1),
                absl::GetFlag(FLAGS_known_association) ? "known (seif/iseif)" : "unknown (NN)", bounds.lower,
                bounds.upper);
    std::printf(
        "| filter | pose x [m] | pose y [m] | heading [deg] | landmark x [m] | landmark y [m] | "
        "mean avg NEES | steps in bounds | failed runs | iterations/update | total time [s] |\n");
    std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    json mc = json::array();
    for (const MonteCarloRow& r : rows) {
      std::printf("| %s | %.3f | %.3f | %.3f | %.3f | %.3f | %.2f | %.1f%% | %d | %.2f | %.2f |\n", r.filter.c_str(),
                  r.rms_x, r.rms_y, r.rms_heading_deg, r.landmark_rms_x, r.landmark_rms_y, r.mean_average_nees,
                  100 * r.steps_inside, r.failed_runs, r.iterations_per_update, r.seconds);
      mc.push_back(RowJson(r));
    }
    out["monte_carlo"] = {
        {"scenario", scenario}, {"runs", runs}, {"rows", mc}, {"nees_bounds", {bounds.lower, bounds.upper}}};
  }

  // 2. Growth on random worlds of constant density.
  const std::vector<std::string> sizes = SplitList(absl::GetFlag(FLAGS_growth_landmarks));
  if (!sizes.empty()) {
    json growth;
    if (absl::Status st = RunGrowth(sizes, &growth); !st.ok()) {
      std::fprintf(stderr, "%s\n", std::string(st.message()).c_str());
      return 1;
    }
    out["growth"] = growth;
  }
  if (const std::string path = absl::GetFlag(FLAGS_out); !path.empty()) {
    std::ofstream f(path);
    f << out.dump(2) << "\n";
    if (!f) {
      std::fprintf(stderr, "cannot write %s\n", path.c_str());
      return 1;
    }
  }
  return 0;
}
