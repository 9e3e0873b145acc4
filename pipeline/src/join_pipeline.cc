#include "subslam/pipeline/join_pipeline.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <set>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/clock.h"
#include "joins_csv.h"
#include "report_json.h"
#include "subslam/eval/gps_alignment.h"
#include "subslam/eval/labelled_map_errors.h"
#include "subslam/eval/trajectory_errors.h"
#include "subslam/io/output_directory.h"
#include "subslam/io/run_output_writer.h"
#include "subslam/posegraph/graph_format.h"
#include "subslam/posegraph/submap_marginals_graph.h"

namespace subslam::pipeline {

AssociationVsTruth CountAssociationsAgainstTruth(const SubmapGraph& graph, const std::vector<LocalSubmap>& labelled) {
  AssociationVsTruth c;
  std::map<std::pair<int, int>, const LocalSubmapLandmark*> label_of;  // (map id, local id)
  for (const LocalSubmap& s : labelled) {
    for (const LocalSubmapLandmark& l : s.landmarks) label_of[{s.id, l.local_id}] = &l;
  }
  // Association against truth ids, from the final association table (factors in time
  // order): global landmark → true ids joined to it, and the reverse.
  std::map<int, std::set<int>> truths_of_global;
  std::map<int, std::set<int>> globals_of_truth;
  std::set<int> globals_with_mixed_feature;
  std::map<int, std::vector<std::vector<int>>> feature_truths_of_global;  // per global: each feature's true ids
  std::map<int, std::pair<int, int>> last_seen;                           // truth id → (local map index, global id)
  int map_index = 0;
  for (const SubmapFactor& f : graph.factors()) {
    for (int i = 0; i < f.submap.num_landmarks(); ++i) {
      const LocalSubmapLandmark* feature = &f.submap.landmarks[i];
      if (!labelled.empty()) {
        const auto it = label_of.find({f.submap.id, feature->local_id});
        if (it == label_of.end()) continue;
        feature = it->second;
      }
      const std::optional<int>& t = feature->truth_id;
      if (!t.has_value() || *t < 0) continue;
      const int g = f.landmark_of_feature[i];
      truths_of_global[g].insert(*t);
      const std::optional<int>& mixed = feature->truth_landmarks;
      if (mixed.has_value() && *mixed >= 2) globals_with_mixed_feature.insert(g);
      const std::vector<int>& ids = feature->truth_ids;
      feature_truths_of_global[g].push_back(ids.empty() ? std::vector<int>{*t} : ids);
      globals_of_truth[*t].insert(g);
      auto seen = last_seen.find(*t);
      if (seen != last_seen.end()) {
        const bool loop = map_index - seen->second.first > 2;
        const bool merged = seen->second.second == g;
        (loop ? (merged ? c.loop_merged : c.loop_missed) : (merged ? c.recent_merged : c.recent_missed)) += 1;
      }
      last_seen[*t] = {map_index, g};
    }
    ++map_index;
  }
  for (const auto& [g, truths] : truths_of_global) {
    c.wrong += static_cast<long>(truths.size()) - 1;
    if (globals_with_mixed_feature.count(g)) c.wrong_with_mixed_feature += static_cast<long>(truths.size()) - 1;
  }
  for (const auto& [g, features] : feature_truths_of_global) {
    // Union-find over the true ids, each feature linking its own: the components are the
    // groups of features that share a true landmark.
    std::map<int, int> parent;
    const auto find = [&parent](int id) {
      while (parent[id] != id) id = parent[id] = parent[parent[id]];
      return id;
    };
    for (const std::vector<int>& ids : features) {
      for (int id : ids) parent.emplace(id, id);
      for (int id : ids) parent[find(id)] = find(ids.front());
    }
    long groups = 0;
    for (const auto& [id, up] : parent) groups += find(id) == id ? 1 : 0;
    c.wrong_sharing_no_true_landmark += groups - 1;
  }
  for (const auto& [t, globals] : globals_of_truth) {
    c.missed += static_cast<long>(globals.size()) - 1;
    c.correct += 1;
  }
  return c;
}

namespace {

// Joins every local map in order, through the online yaw calibration as in a run: at the end
// of its warm-up it may ask for the maps so far to be joined again, turned, into an empty
// joiner. Records each join and each online anchor in `r`; `joining` is the time taken.
absl::Status JoinAll(const std::vector<LocalSubmap>& submaps, const JoinOptions& options,
                     backend::SensorYawCalibration* yaw_calibration, std::unique_ptr<backend::MapJoiner>* joiner,
                     JoinResult* r, absl::Duration* joining) {
  for (const LocalSubmap& built : submaps) {
    const absl::Time calibration_start = absl::Now();
    backend::SensorYawCalibration::Ready ready = yaw_calibration->Add(built);
    *joining += absl::Now() - calibration_start;
    if (ready.restart) {
      *joiner = MakeJoiner(options.backend, options.initial_pose);
      r->joins.clear();
      r->anchors_online.resize(1);
    }
    for (const LocalSubmap& s : ready.maps) {
      const absl::Time join_start = absl::Now();
      if (absl::Status st = (*joiner)->Join(s); !st.ok()) {
        return absl::Status(st.code(), absl::StrCat("joining local map ", s.id, ": ", st.message()));
      }
      *joining += absl::Now() - join_start;
      r->joins.push_back((*joiner)->last_join());
      r->anchors_online.push_back({s.t_end, (*joiner)->LastAnchor(), (*joiner)->LastAnchorCovariance()});
    }
  }
  return absl::OkStatus();
}

// The joined map against whatever ground truth the options carry.
nlohmann::json JoinMetrics(const backend::MapJoiner& joiner, const std::vector<LocalSubmap>& submaps,
                           const JoinOptions& options, const JoinResult& r) {
  nlohmann::json metrics = nlohmann::json::object();
  if (!options.truth_poses.empty()) {
    metrics["anchors"] = ErrorsJson(eval::ComputeTrajectoryErrors(r.anchors, options.truth_poses));
    metrics["anchors_online"] = ErrorsJson(eval::ComputeTrajectoryErrors(r.anchors_online, options.truth_poses));
  }
  if (!options.truth_landmarks.empty()) {
    const std::vector<io::TruthLandmark>& observed =
        options.observed_truth_landmarks.empty() ? options.truth_landmarks : options.observed_truth_landmarks;
    metrics["map"] =
        MapErrorsJson(eval::ComputeMapErrors(r.landmarks, observed), options.truth_landmarks.size(), observed.size());
    const eval::LabelledMapErrors labelled = eval::ComputeLabelledMapErrors(
        r.landmarks, eval::GlobalLandmarkTruthLabels(joiner.graph(), submaps, r.landmarks), options.truth_landmarks);
    if (labelled.labelled > 0) metrics["map_by_truth_label"] = LabelledMapErrorsJson(labelled);
  }
  if (!options.gps.empty()) {
    if (auto g = eval::CompareWithGps(r.anchors, options.gps); g.ok()) metrics["gps_anchors"] = GpsJson(*g);
    if (auto g = eval::CompareWithGps(r.anchors_online, options.gps); g.ok()) {
      metrics["gps_anchors_online"] = GpsJson(*g);
    }
  }
  const bool truth_ids = std::any_of(submaps.begin(), submaps.end(), [](const LocalSubmap& s) {
    return std::any_of(s.landmarks.begin(), s.landmarks.end(), [](const auto& f) { return f.truth_id.has_value(); });
  });
  if (truth_ids) metrics["association_vs_truth_id"] = AssociationVsTruthJson(r.association);
  return metrics;
}

// report.json of a join.
nlohmann::json JoinReport(const backend::MapJoiner& joiner, const std::vector<LocalSubmap>& submaps,
                          const JoinOptions& options, const backend::SensorYawCalibration& yaw_calibration,
                          const JoinResult& r, double joiner_covariance_seconds) {
  long covariance_repairs = 0;
  for (const LocalSubmap& s : submaps) covariance_repairs += s.covariance_repairs;
  nlohmann::json counts = {{"local_maps", r.local_maps},
                           {"anchors", joiner.num_anchors()},
                           {"landmarks", joiner.num_landmarks()},
                           {"covariance_repairs", covariance_repairs}};
  for (const auto& [name, value] : yaw_calibration.Counters()) counts[name] = value;
  for (const backend::JoinerCounters::Field& f : backend::JoinerCounters::Fields()) {
    counts[f.name] = joiner.counters().*f.member;
  }
  const backend::JoinerExtras joiner_extras = joiner.Extras();
  nlohmann::json extras = nlohmann::json::object();
  for (const auto& [name, value] : joiner_extras.figures) extras[name] = value;
  for (const auto& [name, value] : joiner_extras.notes) extras[name] = value;
  nlohmann::json stages = nlohmann::json::object();
  for (const auto& [stage, seconds] : joiner.stage_times()) stages[stage] = seconds;
  nlohmann::json report = {
      {"format", "subslam-join-report/1"},
      {"configuration",
       {{"backend", ToString(options.backend.kind)},
        {"known_association", options.backend.eif.association.known_association},
        {"anchor_search_radius_m", options.backend.eif.association.anchor_search_radius_m},
        {"landmark_search_radius_m", options.backend.eif.association.landmark_search_radius_m},
        {"gate_probability", options.backend.eif.association.gate_probability},
        {"relinearize_heading_change", options.backend.eif.relinearize_heading_change},
        {"relinearize_linearization_chi2", options.backend.eif.relinearize_linearization_chi2},
        {"relinearize_every", options.backend.eif.relinearize_every},
        {"relinearize_at_end", EifRelinearizesAtEnd(options.backend)}}},
      {"counts", counts},
      {"time_seconds",
       {{"total", r.wall_seconds}, {"stages", stages}, {"joiner_all_anchor_covariances", joiner_covariance_seconds}}},
      {"extras", extras},
      {"metrics", JoinMetrics(joiner, submaps, options, r)},
      {"build", BuildJson()}};
  if (!options.invocation.is_null()) report["invocation"] = options.invocation;
  return report;
}

// The join's output files (join_pipeline.h) in `out_dir`.
absl::Status WriteJoinOutputs(const std::string& out_dir, const backend::MapJoiner& joiner, const JoinOptions& options,
                              const JoinResult& r) {
  absl::StatusOr<std::filesystem::path> dir = io::PrepareOutputDirectory(out_dir, "join");
  if (!dir.ok()) return dir.status();
  const std::filesystem::path& out = *dir;
  if (auto s = io::WriteTrajectoryCsv((out / "anchors.csv").string(), r.anchors); !s.ok()) return s;
  if (auto s = io::WriteTrajectoryCsv((out / "anchors_online.csv").string(), r.anchors_online); !s.ok()) return s;
  if (auto s = io::WriteLandmarksCsv((out / "landmarks.csv").string(), r.landmarks); !s.ok()) return s;
  if (auto s = posegraph::WriteGraph(posegraph::SubmapMarginalsGraph(joiner.graph()), (out / "graph.g2o").string(),
                                     {.format = posegraph::GraphFormat::kG2o});
      !s.ok()) {
    return s;
  }
  if (auto s = io::WriteTextFile((out / "joins.csv").string(), JoinsCsv(r.joins)); !s.ok()) return s;
  if (auto s = io::WriteTumTrajectory((out / "anchors.tum").string(), r.anchors); !s.ok()) return s;
  if (!options.truth_poses.empty()) {
    if (auto s = io::WriteTruthTrajectoryCsv((out / "truth_trajectory.csv").string(), options.truth_poses); !s.ok()) {
      return s;
    }
  }
  if (!options.truth_landmarks.empty()) {
    if (auto s = io::WriteTruthLandmarksCsv((out / "truth_landmarks.csv").string(), options.truth_landmarks); !s.ok()) {
      return s;
    }
  }
  return io::WriteTextFile((out / "report.json").string(), r.report.dump(2) + "\n");
}

}  // namespace

absl::StatusOr<JoinResult> RunJoin(const std::vector<LocalSubmap>& submaps, const JoinOptions& options) {
  if (absl::Status s = options.backend.Validate(); !s.ok()) return s;
  if (options.backend.kind == Backend::kNone) return absl::InvalidArgumentError("join needs a back-end");
  if (submaps.empty()) return absl::InvalidArgumentError("no local maps to join");
  std::unique_ptr<backend::MapJoiner> joiner = MakeJoiner(options.backend, options.initial_pose);
  JoinResult r;
  r.anchors_online.push_back({submaps.front().t_start, options.initial_pose, Eigen::Matrix3d::Zero()});
  absl::Duration joining;
  backend::SensorYawCalibration yaw_calibration(options.backend.sensor_yaw);
  if (absl::Status s = JoinAll(submaps, options, &yaw_calibration, &joiner, &r, &joining); !s.ok()) return s;
  const absl::Time start = absl::Now() - joining;  // the online records are not timed
  if (absl::Status st = joiner->Finish(); !st.ok()) return st;
  r.wall_seconds = absl::ToDoubleSeconds(absl::Now() - start);
  // Marginal covariances of every anchor (timed: the joiner's bulk recovery).
  const absl::Time covariance_start = absl::Now();
  const std::vector<Eigen::Matrix3d> joiner_covariances = joiner->AnchorCovariances();
  const double joiner_covariance_seconds = absl::ToDoubleSeconds(absl::Now() - covariance_start);
  r.association = CountAssociationsAgainstTruth(joiner->graph());
  r.local_maps = static_cast<int>(submaps.size());
  r.anchor_times.push_back(submaps.front().t_start);
  for (const LocalSubmap& s : submaps) r.anchor_times.push_back(s.t_end);
  for (int k = 0; k < joiner->num_anchors(); ++k) {
    r.anchors.push_back({r.anchor_times[k], joiner->anchor(k), joiner_covariances[k]});
  }
  const std::vector<Eigen::Matrix2d> landmark_covariances = joiner->LandmarkCovariances();
  for (int j = 0; j < joiner->num_landmarks(); ++j) {
    r.landmarks.push_back({j, joiner->landmark(j), landmark_covariances[j]});
  }
  r.report = JoinReport(*joiner, submaps, options, yaw_calibration, r, joiner_covariance_seconds);
  if (!options.out_dir.empty()) {
    if (absl::Status s = WriteJoinOutputs(options.out_dir, *joiner, options, r); !s.ok()) return s;
  }
  return r;
}

}  // namespace subslam::pipeline
