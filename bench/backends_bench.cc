// Every back-end on the same recorded local maps, side by side; the total-time curves of
// single-map EKF-SLAM against local mapping plus sequential or tree joining (Figure 9 of
// Combined SLAM); and the growth of the joining cost with the number of local maps.
//
//   build/bench/backends_bench [--scenario combined-2km --seed 1 | --dataset DIR]
//       [--frontend ekf|rbpf] [--known_association] [--backends eif,ceres,ekf,tree-ekf,tree-eif,tree-ceres]
//       [--growth_km 1,2,4,8,16] [back-end flags: --single_linearization, --relinearize_*,
//       --eif_ordering, --join_*, … as `subslam` takes them, docs/cli.md] [--out results.json]
//
// Side by side: the local maps are built once (front-end, no back-end), then each
// back-end joins them with the same association options (RunJoin); printed: anchors
// against truth (RMS, mean NEES, share in the 95% bounds) or, on a real data set, the
// aligned RMS against GPS; wrong merges; joining time (all joins, association and
// covariance recovery included, plus the final solve or fold). Figure 9: cumulative
// time at each tenth of the run. Growth: `random` worlds of constant landmark density
// (side ∝ √length) driven 1, 2, 4, … km; EKF local maps; total joining time per back-end.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "backend_flags.h"
#include "keep_freed_memory_flag.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/eval/gps_alignment.h"
#include "subslam/eval/trajectory_errors.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/pipeline/join_pipeline.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/sim/simulator.h"

ABSL_FLAG(std::string, scenario, "combined-2km", "simulated scenario (ignored with --dataset)");
ABSL_FLAG(uint64_t, seed, 1, "scenario seed");
ABSL_FLAG(std::string, dataset, "", "a data-set directory instead of a scenario (e.g. Victoria Park)");
ABSL_FLAG(std::string, frontend, "ekf", "local maps from: ekf | rbpf");
ABSL_FLAG(std::string, backends, "eif,ceres,ekf,tree-ekf,tree-eif,tree-ceres", "back-ends, comma-separated");
ABSL_FLAG(std::string, growth_km, "1,2,4,8,16", "random-world path lengths for the growth table (empty: skip)");
ABSL_FLAG(std::string, growth_backends, "eif,ekf,tree-ekf,tree-eif", "back-ends of the growth table");
ABSL_FLAG(double, growth_dense_max_km, 4.0,
          "growth table: dense back-ends (ekf, tree-ekf) only up to this path length (their covariance is O(N^2))");
ABSL_FLAG(std::string, out, "", "write the results as JSON here");

namespace {

using subslam::pipeline::Backend;

std::vector<std::string> SplitList(const std::string& list) { return absl::StrSplit(list, ',', absl::SkipEmpty()); }

struct Input {
  subslam::io::Dataset dataset;
  std::vector<subslam::LocalSubmap> maps;
  std::vector<double> local_mapping_by_tenth;  // cumulative wall time of the front-end run
  double run_seconds = 0.0;
};

absl::StatusOr<Input> Record(subslam::io::Dataset dataset, subslam::pipeline::Frontend frontend) {
  Input in;
  subslam::pipeline::RunOptions options;
  options.frontend = frontend;
  absl::StatusOr<subslam::pipeline::RunResult> r = subslam::pipeline::RunPipeline(dataset, options);
  if (!r.ok()) return r.status();
  in.dataset = std::move(dataset);
  in.maps = r->local_maps;
  in.local_mapping_by_tenth = r->wall_seconds_by_tenth;
  in.run_seconds = r->wall_seconds;
  return in;
}

// The back-end `kind` as the shared back-end flags configure it (--join_*,
// --relinearize_*, --single_linearization, --eif_ordering, --known_association, …; see
// docs/cli.md), checked in main.
subslam::pipeline::BackendOptions Options(Backend kind) {
  subslam::pipeline::BackendOptions o = *subslam::cli::BackendOptionsFromFlags();
  o.kind = kind;
  return o;
}

// The size of an EIF's information form after the last join.
struct InformationSize {
  long state = 0;           // variables
  long lambda_entries = 0;  // stored entries of Λ (both triangles)
  long factor_entries = 0;  // entries of its LDLᵀ factor
};

// Cumulative joining time after each local map (and Finish at the end, added to the last);
// the joiner's stage times in `stages` and, for the EIF, its size in `size`, if given.
std::vector<double> TimeEachJoin(const std::vector<subslam::LocalSubmap>& maps, Backend kind, const subslam::Pose2& p0,
                                 std::map<std::string, double>* stages = nullptr, InformationSize* size = nullptr) {
  std::unique_ptr<subslam::backend::MapJoiner> j = subslam::pipeline::MakeJoiner(Options(kind), p0);
  std::vector<double> out;
  const absl::Time start = absl::Now();
  for (const subslam::LocalSubmap& s : maps) {
    if (!j->Join(s).ok()) return {};
    out.push_back(absl::ToDoubleSeconds(absl::Now() - start));
  }
  if (!j->Finish().ok()) return {};
  out.back() = absl::ToDoubleSeconds(absl::Now() - start);
  if (stages != nullptr) *stages = j->stage_times();
  if (const auto* eif = dynamic_cast<const subslam::backend::EifJoiner*>(j.get()); eif != nullptr && size != nullptr) {
    size->state = eif->state_dimension();
    size->lambda_entries = static_cast<long>(eif->information().nonZeros());
    size->factor_entries = eif->factor_nonzeros();
  }
  return out;
}

nlohmann::json SideBySide(const Input& in, const std::vector<Backend>& kinds) {
  nlohmann::json rows = nlohmann::json::array();
  const bool truth = !in.dataset.truth_poses.empty();
  std::printf("\n%zu local maps; side by side (%s association)\n", in.maps.size(),
              absl::GetFlag(FLAGS_known_association) ? "known" : "JCBB");
  std::printf("%-9s %10s %10s %9s %10s %8s %8s %9s %12s\n", "backend", truth ? "anchor_rms" : "gps_rms_m", "mean_nees",
              "in_95%", "landmarks", "wrong", "loop", "join_ms", "per_join_ms");
  for (Backend kind : kinds) {
    subslam::pipeline::JoinOptions options;
    options.backend = Options(kind);
    options.initial_pose = in.dataset.initial_pose;
    options.truth_poses = in.dataset.truth_poses;
    options.truth_landmarks = in.dataset.truth_landmarks;
    options.observed_truth_landmarks = subslam::eval::ObservedTruthLandmarks(in.dataset);
    absl::StatusOr<subslam::pipeline::JoinResult> r = subslam::pipeline::RunJoin(in.maps, options);
    if (!r.ok()) {
      std::printf("%-9s failed: %s\n", subslam::pipeline::ToString(kind), std::string(r.status().message()).c_str());
      continue;
    }
    double error = NAN, nees = NAN, inside = NAN;
    if (truth) {
      const subslam::eval::TrajectoryErrors e =
          subslam::eval::ComputeTrajectoryErrors(r->anchors, in.dataset.truth_poses);
      error = e.rms_position_m;
      nees = e.mean_nees;
      inside = e.fraction_nees_in_bounds;
    } else if (!in.dataset.gps.empty()) {
      auto g = subslam::eval::CompareWithGps(r->anchors, in.dataset.gps);
      if (g.ok()) error = g->rms_m;
    }
    std::printf("%-9s %10.3f %10.2f %8.1f%% %10zu %8ld %4ld/%-3ld %9.1f %12.3f\n", subslam::pipeline::ToString(kind),
                error, nees, 100.0 * inside, r->landmarks.size(), r->association.wrong, r->association.loop_merged,
                r->association.loop_merged + r->association.loop_missed, 1e3 * r->wall_seconds,
                1e3 * r->wall_seconds / std::max<size_t>(1, in.maps.size()));
    rows.push_back({{"backend", subslam::pipeline::ToString(kind)},
                    {truth ? "anchor_rms_m" : "gps_rms_m", error},
                    {"mean_anchor_nees", nees},
                    {"anchors_in_95_bounds", inside},
                    {"landmarks", r->landmarks.size()},
                    {"wrong_merges", r->association.wrong},
                    {"wrong_merges_sharing_no_true_landmark", r->association.wrong_sharing_no_true_landmark},
                    {"loop_merged", r->association.loop_merged},
                    {"loop_reobservations", r->association.loop_merged + r->association.loop_missed},
                    {"join_seconds", r->wall_seconds},
                    {"stages", r->report["time_seconds"]["stages"]}});
  }
  return rows;
}

nlohmann::json Figure9(const Input& in, const std::vector<Backend>& kinds) {
  // Single-map EKF-SLAM on the same data.
  subslam::pipeline::RunOptions slam;
  slam.frontend = subslam::pipeline::Frontend::kEkfSlam;
  absl::StatusOr<subslam::pipeline::RunResult> single = subslam::pipeline::RunPipeline(in.dataset, slam);
  if (!single.ok()) return nullptr;
  const double t0 = in.maps.front().t_start, t1 = in.maps.back().t_end;
  std::map<std::string, std::vector<double>> joins;
  for (Backend kind : kinds) {
    if (kind == Backend::kCeres) continue;
    joins[subslam::pipeline::ToString(kind)] = TimeEachJoin(in.maps, kind, in.dataset.initial_pose);
  }
  std::printf("\nFigure 9: cumulative seconds at each tenth of the run (local mapping + joining)\n");
  std::printf("%5s %11s %13s", "tenth", "ekf-slam", "local_maps");
  for (const auto& [name, _] : joins) std::printf(" %10s", ("+" + name).c_str());
  std::printf("\n");
  nlohmann::json rows = nlohmann::json::array();
  for (int k = 1; k <= 10; ++k) {
    const double t = t0 + (t1 - t0) * k / 10.0;
    const double slam_s = single->wall_seconds_by_tenth.size() >= 10 ? single->wall_seconds_by_tenth[k - 1] : NAN;
    const double maps_s = in.local_mapping_by_tenth.size() >= 10 ? in.local_mapping_by_tenth[k - 1] : NAN;
    std::printf("%5d %11.3f %13.3f", k, slam_s, maps_s);
    nlohmann::json row = {{"tenth", k}, {"ekf_slam_s", slam_s}, {"local_mapping_s", maps_s}};
    for (const auto& [name, cumulative] : joins) {
      double s = 0.0;
      for (size_t i = 0; i < in.maps.size() && i < cumulative.size(); ++i) {
        if (in.maps[i].t_end <= t + 1e-9) s = cumulative[i];
      }
      std::printf(" %10.3f", maps_s + s);
      row["local_mapping_plus_" + name + "_s"] = maps_s + s;
    }
    std::printf("\n");
    rows.push_back(row);
  }
  return rows;
}

nlohmann::json Growth(const std::vector<double>& lengths_km, const std::vector<Backend>& kinds) {
  std::printf("\nJoining cost against the number of local maps (random worlds, constant density)\n");
  std::printf("%8s %6s %9s", "path_km", "maps", "landmarks");
  for (Backend kind : kinds) {
    std::printf(" %11s %9s %13s", (std::string(subslam::pipeline::ToString(kind)) + "_s").c_str(), "/nlog2n",
                "last10%_ms/j");
  }
  std::printf("   (eif: factorisation / state recovery [s]; Λ and L entries per local map)\n");
  nlohmann::json rows = nlohmann::json::array();
  for (double km : lengths_km) {
    subslam::sim::ScenarioOptions o;
    o.seed = absl::GetFlag(FLAGS_seed);
    o.random_path_length_m = 1000.0 * km;
    o.random_world_size_m = 200.0 * std::sqrt(km);
    o.random_landmarks = static_cast<int>(std::lround(300.0 * km));
    absl::StatusOr<subslam::io::Dataset> d = subslam::sim::SimulateScenario("random", o);
    if (!d.ok()) break;
    absl::StatusOr<Input> in = Record(*std::move(d), subslam::pipeline::Frontend::kEkfLocal);
    if (!in.ok()) break;
    const double n = static_cast<double>(in->maps.size());
    std::printf("%8.0f %6zu %9zu", km, in->maps.size(), in->dataset.truth_landmarks.size());
    nlohmann::json row = {
        {"path_km", km}, {"local_maps", in->maps.size()}, {"true_landmarks", in->dataset.truth_landmarks.size()}};
    for (Backend kind : kinds) {
      const bool dense = kind == Backend::kEkf || kind == Backend::kTreeEkf;
      if (dense && km > absl::GetFlag(FLAGS_growth_dense_max_km)) {
        std::printf(" %11s %9s %13s", "-", "-", "-");
        continue;
      }
      std::map<std::string, double> stages;
      InformationSize size;
      const std::vector<double> t = TimeEachJoin(in->maps, kind, in->dataset.initial_pose, &stages, &size);
      const double total = t.empty() ? NAN : t.back();
      row[std::string(subslam::pipeline::ToString(kind)) + "_stages"] = stages;
      double last_tenth_ms = NAN;
      if (t.size() >= 10) {  // per-join time in the last tenth of the joins
        const size_t a = t.size() - t.size() / 10;
        last_tenth_ms = 1e3 * (t.back() - t[a - 1]) / static_cast<double>(t.size() - a);
        row[std::string(subslam::pipeline::ToString(kind)) + "_last_tenth_ms_per_join"] = last_tenth_ms;
      }
      std::printf(" %11.4f %9.2e %13.2f", total, total / (n * std::log2(std::max(2.0, n))), last_tenth_ms);
      row[std::string(subslam::pipeline::ToString(kind)) + "_s"] = total;
      if (kind == Backend::kEif) {
        std::printf("   (%.3f / %.3f; %.0f / %.0f)", stages["factorization"],
                    stages["recovery"] + stages["recovery_check"], static_cast<double>(size.lambda_entries) / n,
                    static_cast<double>(size.factor_entries) / n);
        row["eif_state_dimension"] = size.state;
        row["eif_lambda_entries"] = size.lambda_entries;
        row["eif_factor_entries"] = size.factor_entries;
      }
    }
    std::printf("\n");
    rows.push_back(row);
  }
  return rows;
}

// A comma-separated list of back-ends (none excluded); false, with a message, on a bad name.
bool ParseBackends(const std::string& list, std::vector<Backend>* out) {
  for (const std::string& name : SplitList(list)) {
    auto b = subslam::pipeline::BackendFromString(name);
    if (!b.ok() || *b == Backend::kNone) {
      std::fprintf(stderr, "unknown back-end %s\n", name.c_str());
      return false;
    }
    out->push_back(*b);
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  absl::ParseCommandLine(argc, argv);
  subslam::pipeline::ApplyKeepFreedMemoryFlag();
  std::vector<Backend> kinds, growth_kinds;
  if (!ParseBackends(absl::GetFlag(FLAGS_backends), &kinds) ||
      !ParseBackends(absl::GetFlag(FLAGS_growth_backends), &growth_kinds)) {
    return 2;
  }
  if (absl::StatusOr<subslam::pipeline::BackendOptions> backend = subslam::cli::BackendOptionsFromFlags();
      !backend.ok()) {
    std::fprintf(stderr, "%s\n", std::string(backend.status().message()).c_str());
    return 2;
  }
  absl::StatusOr<subslam::pipeline::Frontend> frontend =
      subslam::pipeline::FrontendFromString(absl::GetFlag(FLAGS_frontend));
  if (!frontend.ok()) {
    std::fprintf(stderr, "%s\n", std::string(frontend.status().message()).c_str());
    return 2;
  }
  absl::StatusOr<subslam::io::Dataset> dataset = absl::NotFoundError("");
  std::string source;
  if (!absl::GetFlag(FLAGS_dataset).empty()) {
    dataset = subslam::io::ReadDataset(absl::GetFlag(FLAGS_dataset));
    source = absl::GetFlag(FLAGS_dataset);
  } else {
    subslam::sim::ScenarioOptions o;
    o.seed = absl::GetFlag(FLAGS_seed);
    dataset = subslam::sim::SimulateScenario(absl::GetFlag(FLAGS_scenario), o);
    source = absl::GetFlag(FLAGS_scenario) + " seed " + std::to_string(o.seed);
  }
  if (!dataset.ok()) {
    std::fprintf(stderr, "%s\n", std::string(dataset.status().message()).c_str());
    return 1;
  }
  absl::StatusOr<Input> in = Record(*std::move(dataset), *frontend);
  if (!in.ok() || in->maps.empty()) {
    std::fprintf(stderr, "recording the local maps failed\n");
    return 1;
  }
  std::printf("%s, %s local maps (front-end %.2f s)\n", source.c_str(), absl::GetFlag(FLAGS_frontend).c_str(),
              in->run_seconds);
  nlohmann::json results = {
      {"source", source}, {"frontend", absl::GetFlag(FLAGS_frontend)}, {"local_maps", in->maps.size()}};
  results["side_by_side"] = SideBySide(*in, kinds);
  results["figure9"] = Figure9(*in, kinds);
  std::vector<double> lengths;
  for (const std::string& s : SplitList(absl::GetFlag(FLAGS_growth_km))) {
    lengths.push_back(std::stod(s));
  }
  if (!lengths.empty()) results["growth"] = Growth(lengths, growth_kinds);
  if (!absl::GetFlag(FLAGS_out).empty()) std::ofstream(absl::GetFlag(FLAGS_out)) << results.dump(2) << "\n";
  return 0;
}
