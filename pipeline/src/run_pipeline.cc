#include "subslam/pipeline/run_pipeline.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <future>
#include <optional>
#include <system_error>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/time/clock.h"
#include "joins_csv.h"
#include "report_json.h"
#include "run_report.h"
#include "subslam/core/check.h"
#include "subslam/core/enum_names.h"
#include "subslam/eval/labelled_map_errors.h"
#include "subslam/eval/local_map_errors.h"
#include "subslam/frontend/dead_reckoning.h"
#include "subslam/frontend/ekf_local_mapper.h"
#include "subslam/io/output_directory.h"
#include "subslam/io/run_output_writer.h"
#include "subslam/io/steps.h"
#include "subslam/io/submaps_jsonl.h"
#include "subslam/models/gating.h"
#include "subslam/pipeline/submap_slam.h"

namespace subslam::pipeline {
namespace {

using nlohmann::json;

long PeakRssKb() {
  struct rusage usage {};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

// The process's resident memory now (kB), from /proc/self/statm; 0 where there is none.
long CurrentRssKb() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (f == nullptr) return 0;
  long size = 0, resident = 0;
  const int read = std::fscanf(f, "%ld %ld", &size, &resident);
  std::fclose(f);
  return read == 2 ? resident * (sysconf(_SC_PAGESIZE) / 1024) : 0;
}

class Progress {
 public:
  Progress(bool enabled, size_t total) : enabled_(enabled && isatty(STDERR_FILENO)), total_(total) {}
  void Tick(size_t done, double t) {
    if (!enabled_ || (done & 255) != 0) return;
    const absl::Time now = absl::Now();
    if (now - start_ < absl::Seconds(2) || now - last_ < absl::Milliseconds(200)) return;
    last_ = now;
    const double fraction = static_cast<double>(done) / total_;
    const int width = 30, filled = static_cast<int>(fraction * width);
    std::fprintf(stderr, "\r[%s%s] %5.1f%%  step %zu/%zu  t=%.1f s", std::string(filled, '#').c_str(),
                 std::string(width - filled, ' ').c_str(), 100 * fraction, done, total_, t);
    std::fflush(stderr);
    shown_ = true;
  }
  ~Progress() {
    if (shown_) std::fprintf(stderr, "\r%80s\r", "");
  }

 private:
  bool enabled_;
  size_t total_;
  bool shown_ = false;
  absl::Time start_ = absl::Now(), last_ = absl::InfinitePast();
};

// Labels each local-map feature with the majority true id of the detections voted to it
// (evaluation only: the estimators never see truth ids).
class TruthVotes {
 public:
  void Add(int map_id, const std::vector<int>& features, const Scan& scan) {
    for (size_t k = 0; k < features.size() && k < scan.detections.size(); ++k) {
      const int truth = scan.detections[k].truth_id;
      if (features[k] < 0 || truth == kUnknownTruthId) continue;
      ++votes_[{map_id, features[k]}][truth];
    }
  }
  // Returns how many of the map's exported features mix detections of several true
  // landmarks (the front-end merged them).
  int Label(LocalSubmap* s) const {
    int impure = 0;
    for (LocalSubmapLandmark& l : s->landmarks) {
      auto it = votes_.find({s->id, l.local_id});
      if (it == votes_.end()) continue;
      const auto best = std::max_element(it->second.begin(), it->second.end(),
                                         [](const auto& a, const auto& b) { return a.second < b.second; });
      l.truth_id = best->first;
      int true_landmarks = 0;
      l.truth_ids.clear();
      for (const auto& [truth, count] : it->second) {  // ascending ids
        if (truth < 0) continue;
        ++true_landmarks;
        l.truth_ids.push_back(truth);
      }
      l.truth_landmarks = true_landmarks;
      impure += true_landmarks > 1 ? 1 : 0;
    }
    return impure;
  }

 private:
  std::map<std::pair<int, int>, std::map<int, int>> votes_;
};

// Runs `write` on another thread, or — if none can be had — when its result is asked for.
template <typename Write>
std::future<absl::Status> WriteInBackground(Write write) {
  try {
    return std::async(std::launch::async, write);  // a copy: `write` stays whole if this throws
  } catch (const std::system_error&) {
    return std::async(std::launch::deferred, std::move(write));
  }
}

// The SEIF options of the front-end: ISEIF turns the iterated update on.
frontend::SeifOptions SeifOptionsOf(const RunOptions& options) {
  frontend::SeifOptions seif = options.seif;
  seif.iterated.enabled = options.frontend == Frontend::kIseif;
  return seif;
}

absl::StatusOr<CheckedOptions> CheckOptions(const io::Dataset& dataset, const RunOptions& options) {
  if (absl::Status s = options.Validate(); !s.ok()) return s;
  CheckedOptions checked;
  checked.seif = SeifOptionsOf(options);
  checked.known_association = checked.seif.landmarks.known_association || options.ekf.landmarks.known_association ||
                              options.fastslam.landmarks.known_association ||
                              options.backend.eif.association.known_association ||
                              options.backend.ekf.association.known_association;
  if (checked.known_association && !dataset.sensor.has_truth_id) {
    return absl::InvalidArgumentError(
        absl::StrCat("known association needs detections with true ids; data set \"", dataset.name, "\" has none"));
  }
  return checked;
}

// The estimator of the chosen front-end; `chain` is set to it for the local-map
// front-ends (the submap pipeline), else to nullptr.
std::unique_ptr<frontend::OnlineEstimator> MakeEstimator(const io::Dataset& dataset, const RunOptions& options,
                                                         const frontend::SeifOptions& seif, SubmapSlam** chain) {
  *chain = nullptr;
  switch (options.frontend) {
    case Frontend::kOdometry:
      return std::make_unique<frontend::DeadReckoning>(dataset.motion.MakeModel(), dataset.initial_pose);
    case Frontend::kRbpf:
    case Frontend::kEkfLocal: {
      const double t0 = dataset.controls.empty() ? 0.0 : dataset.controls.front().t;
      std::unique_ptr<frontend::LocalMapper> mapper;
      if (options.frontend == Frontend::kRbpf) {
        mapper = std::make_unique<frontend::RbpfLocalMapper>(dataset.motion.MakeModel(), dataset.sensor.range_bearing,
                                                             options.fastslam, options.policy, t0);
      } else {
        mapper = std::make_unique<frontend::EkfLocalMapper>(dataset.motion.MakeModel(), dataset.sensor.range_bearing,
                                                            options.ekf, options.policy, t0,
                                                            options.fastslam.moment_matching.min_existence);
      }
      auto slam = std::make_unique<SubmapSlam>(std::move(mapper), dataset.initial_pose, options.backend);
      *chain = slam.get();
      return slam;
    }
    case Frontend::kSeif:
    case Frontend::kIseif:
      return std::make_unique<frontend::SeifSlam>(dataset.motion.MakeModel(), dataset.sensor.range_bearing,
                                                  dataset.initial_pose, seif);
    case Frontend::kFastSlam:
      return std::make_unique<frontend::FastSlam>(dataset.motion.MakeModel(), dataset.sensor.range_bearing,
                                                  dataset.initial_pose, options.fastslam);
    case Frontend::kEkfSlam:
      break;
  }
  return std::make_unique<frontend::EkfSlam>(dataset.motion.MakeModel(), dataset.sensor.range_bearing,
                                             dataset.initial_pose, options.ekf);
}

// Drives the estimator over the steps: the online trajectory, the wall time after each
// tenth of the run, and (submap pipeline) the truth votes of each scan's features and the
// final joins. Fills r's counts, online trajectory and times. Stops early (r->stop) at the
// first step whose estimate is not finite, or once a join has failed.
void Drive(frontend::OnlineEstimator& estimator, SubmapSlam* chain, const io::Dataset& dataset, bool show_progress,
           RunResult* r, TruthVotes* truth_votes) {
  const std::vector<io::Step> steps = io::BuildSteps(dataset);
  r->steps = static_cast<int>(steps.size());
  r->scans = static_cast<int>(dataset.scans.size());
  r->detections = static_cast<long>(dataset.NumDetections());
  r->online.reserve(steps.size());
  Progress progress(show_progress, steps.size());
  const auto chain_cause = [chain] {
    return chain->export_failed() ? RunStop::Cause::kExportFailed : RunStop::Cause::kJoinFailed;
  };
  const absl::Time start = absl::Now();
  for (size_t k = 0; k < steps.size(); ++k) {
    const io::Step& step = steps[k];
    estimator.Predict(step.control, step.dt);
    if (step.scan_index >= 0) {
      const Scan& scan = dataset.scans[step.scan_index];
      const absl::Status updated = estimator.Update(scan);
      // The reader refuses malformed scans; a chain's failed join or export is taken below.
      SUBSLAM_CHECK(updated.ok() || chain != nullptr) << updated;
      if (chain != nullptr) truth_votes->Add(chain->last_scan_map_id(), chain->last_scan_features(), scan);
    }
    // A failed join or export leaves the online pose without its anchor: stop before it.
    if (chain != nullptr && (chain->join_failed() || chain->export_failed())) {
      r->stop = RunStop{chain_cause(), static_cast<int>(k), step.t, ""};
      break;
    }
    const PoseEstimate now{step.t, estimator.pose(), estimator.pose_covariance()};
    if (!now.pose.vector().allFinite() || !now.covariance.allFinite()) {
      r->stop = RunStop{RunStop::Cause::kNonFiniteEstimate, static_cast<int>(k), step.t,
                        absl::StrFormat("the estimate is not finite after step %d (t = %.6f s)", k, step.t)};
      break;
    }
    r->online.push_back(now);
    if (chain != nullptr) chain->RecordStep(step.t);
    progress.Tick(k, step.t);
    // Wall time at the end of each tenth of the run: flat increments mean the time
    // per step does not grow with the length of the run.
    if ((k + 1) * 10 / steps.size() != k * 10 / steps.size()) {
      r->wall_seconds_by_tenth.push_back(absl::ToDoubleSeconds(absl::Now() - start));
      r->rss_kb_by_tenth.push_back(CurrentRssKb());
    }
  }
  if (chain != nullptr) {
    // Joins the open map; after a failed join it returns that join's error.
    const absl::Status st = chain->Finish();
    r->join_failed = chain->join_failed();
    if (!st.ok()) {
      if (!r->stop) {
        r->stop = RunStop{chain_cause(), r->steps, steps.empty() ? 0.0 : steps.back().t, ""};
      }
      if (r->stop->reason.empty()) r->stop->reason = std::string(st.message());
    }
  }
  r->wall_seconds = absl::ToDoubleSeconds(absl::Now() - start);
}

// Each local map's NEES against the truth (the true end pose and features in the true
// start frame), summarised, with one row per map.
json EvaluateLocalMaps(const io::Dataset& dataset, RunResult* r) {
  json per_map = json::array();
  LocalMapSummary summary;
  for (const LocalSubmap& s : r->local_maps) {
    const std::optional<eval::LocalMapNees> e = eval::EvaluateLocalMap(s, dataset.truth_poses, dataset.truth_landmarks);
    if (!e) continue;
    ++summary.evaluated;
    summary.inside += e->inside() ? 1 : 0;
    summary.pose_inside +=
        e->pose_nees <= models::ChiSquareQuantile(0.975, 3) && e->pose_nees >= models::ChiSquareQuantile(0.025, 3) ? 1
                                                                                                                   : 0;
    summary.nees_per_dof += e->nees / e->dof;
    summary.false_alarms += e->false_alarms;
    for (double nees : e->landmark_nees) {
      ++summary.landmarks;
      summary.landmarks_inside +=
          nees >= models::ChiSquareQuantile(0.025, 2) && nees <= models::ChiSquareQuantile(0.975, 2) ? 1 : 0;
    }
    per_map.push_back({{"id", e->id},
                       {"nees", e->nees},
                       {"dof", e->dof},
                       {"pose_nees", e->pose_nees},
                       {"landmarks", e->landmarks_evaluated},
                       {"false_alarms", e->false_alarms},
                       {"inside_95", e->inside()}});
  }
  if (summary.evaluated > 0) summary.nees_per_dof /= summary.evaluated;
  r->local_map_summary = summary;
  return {{"evaluated", summary.evaluated},
          {"nees_inside_95", summary.inside},
          {"pose_nees_inside_95", summary.pose_inside},
          {"mean_nees_per_dof", summary.nees_per_dof},
          {"landmarks_evaluated", summary.landmarks},
          {"landmark_marginal_nees_inside_95", summary.landmarks_inside},
          {"false_alarms_exported", summary.false_alarms},
          {"features_mixing_true_landmarks", r->impure_features},
          {"per_map", per_map}};
}

// The metrics the data set's ground truth allows (report.json's "metrics"), also kept in r.
json Evaluate(const io::Dataset& dataset, const RunOptions& options, const SubmapSlam* chain, RunResult* r) {
  json metrics = json::object();
  if (!dataset.truth_poses.empty()) {
    r->errors = eval::ComputeTrajectoryErrors(r->final_trajectory, dataset.truth_poses);
    metrics["trajectory"] = ErrorsJson(*r->errors);
    if (chain != nullptr && options.backend.kind != Backend::kNone) {  // else final = online
      r->errors_online = eval::ComputeTrajectoryErrors(r->online, dataset.truth_poses);
      metrics["trajectory_online"] = ErrorsJson(*r->errors_online);
    }
  }
  if (!dataset.truth_landmarks.empty()) {
    const std::vector<io::TruthLandmark> observed = eval::ObservedTruthLandmarks(dataset);
    r->map_errors = eval::ComputeMapErrors(r->landmarks, observed);
    metrics["map"] = MapErrorsJson(*r->map_errors, dataset.truth_landmarks.size(), observed.size());
    if (chain != nullptr && chain->joiner() != nullptr) {
      r->labelled_map_errors = eval::ComputeLabelledMapErrors(
          r->landmarks, eval::GlobalLandmarkTruthLabels(chain->joiner()->graph(), r->local_maps, r->landmarks),
          dataset.truth_landmarks);
      if (r->labelled_map_errors->labelled > 0) {  // the local maps carry true ids
        metrics["map_by_truth_label"] = LabelledMapErrorsJson(*r->labelled_map_errors);
        r->association = CountAssociationsAgainstTruth(chain->joiner()->graph(), r->local_maps);
        metrics["association_vs_truth_id"] = AssociationVsTruthJson(*r->association);
      }
    }
  }
  if (!dataset.gps.empty()) {
    auto online = eval::CompareWithGps(r->online, dataset.gps);
    auto final_cmp = eval::CompareWithGps(r->final_trajectory, dataset.gps);
    if (online.ok()) {
      r->gps_online = *online;
      metrics["gps_online"] = GpsJson(*online);
    }
    if (final_cmp.ok()) {
      r->gps_final = *final_cmp;
      metrics["gps_final"] = GpsJson(*final_cmp);
    }
  }
  if (!r->local_maps.empty() && !dataset.truth_poses.empty()) metrics["local_maps"] = EvaluateLocalMaps(dataset, r);
  return metrics;
}

// The per-step pose errors against the truth (pose_errors.csv): t, then for the online and
// the final trajectory the position error [m], heading error [rad] and NEES (nan where the
// covariance is singular).
std::string PoseErrorsCsv(const RunResult& r, const std::vector<io::TimedPose>& truth) {
  const eval::TrajectoryErrors& online = r.errors_online ? *r.errors_online : *r.errors;
  std::string text =
      "t,online_position_error_m,online_heading_error_rad,online_nees,final_position_error_m,"
      "final_heading_error_rad,final_nees\n";
  text.reserve(r.online.size() * 90);
  for (size_t k = 0; k < r.online.size() && k < r.final_trajectory.size(); ++k) {
    const Pose2 t = eval::InterpolatePose(truth, r.online[k].t);
    const auto errors = [&](const PoseEstimate& e, const eval::TrajectoryErrors& m) {
      return absl::StrFormat("%.6g,%.6g,%.6g", (e.pose.translation() - t.translation()).norm(),
                             std::abs(WrapAngle(e.pose.theta - t.theta)), k < m.nees.size() ? m.nees[k] : NAN);
    };
    absl::StrAppend(&text, absl::StrFormat("%.6f", r.online[k].t), ",", errors(r.online[k], online), ",",
                    errors(r.final_trajectory[k], *r.errors), "\n");
  }
  return text;
}

// Writes the outputs other than the online trajectory (already being written by
// `online_written`) into `out`: the final trajectory and the local maps on one thread, the
// TUM files on another; the map, the ground truth, the errors, the joins and the report here.
absl::Status WriteOutputs(const std::filesystem::path& out, const RunResult& r, const io::Dataset& dataset,
                          const SubmapSlam* chain, std::future<absl::Status> online_written) {
  // The files are independent, and formatting the trajectories is most of the time. The
  // report is serialised first (nlohmann's serialiser reads the C locale, not to be shared).
  const std::string report_text = r.report.dump(2) + "\n";
  const bool local_maps = chain != nullptr;
  std::future<absl::Status> final_written = WriteInBackground([&r, &out, local_maps] {
    absl::Status s = io::WriteTrajectoryCsv((out / "trajectory_final.csv").string(), r.final_trajectory);
    if (s.ok() && local_maps) s = io::WriteSubmapsJsonl((out / "submaps.jsonl").string(), r.local_maps);
    return s;
  });
  std::future<absl::Status> tum_written = WriteInBackground([&r, &out] {
    absl::Status s = io::WriteTumTrajectory((out / "trajectory_online.tum").string(), r.online);
    if (s.ok()) s = io::WriteTumTrajectory((out / "trajectory_final.tum").string(), r.final_trajectory);
    return s;
  });
  std::vector<absl::Status> here;
  here.push_back(io::WriteLandmarksCsv((out / "landmarks.csv").string(), r.landmarks));
  if (!dataset.truth_poses.empty()) {
    here.push_back(io::WriteTruthTrajectoryCsv((out / "truth_trajectory.csv").string(), dataset.truth_poses));
    here.push_back(io::WriteTumTrajectory((out / "truth.tum").string(), dataset.truth_poses));
    if (r.errors)
      here.push_back(io::WriteTextFile((out / "pose_errors.csv").string(), PoseErrorsCsv(r, dataset.truth_poses)));
  }
  if (!dataset.truth_landmarks.empty()) {
    here.push_back(io::WriteTruthLandmarksCsv((out / "truth_landmarks.csv").string(), dataset.truth_landmarks));
  }
  if (r.gps_final) {
    // The fixes in the final trajectory's frame, by the alignment the metric found.
    const Pose2 estimate_T_gps = Inverse(r.gps_final->gps_T_estimate);
    std::vector<io::TimedPoint> aligned = dataset.gps;
    for (io::TimedPoint& fix : aligned) {
      const Pose2 p = Compose(estimate_T_gps, Pose2{fix.p.x(), fix.p.y(), 0.0});
      fix.p = {p.x, p.y};
    }
    std::vector<bool> rejected(aligned.size(), false);
    for (int i : eval::GrossGpsFaults(dataset.gps)) rejected[i] = true;
    here.push_back(io::WriteGpsCsv((out / "gps_aligned.csv").string(), aligned, rejected));
  }
  if (chain != nullptr && chain->joiner() != nullptr) {
    here.push_back(io::WriteTextFile((out / "joins.csv").string(), JoinsCsv(r.joins)));
  }
  here.push_back(io::WriteTextFile((out / "report.json").string(), report_text));
  here.push_back(online_written.get());
  here.push_back(final_written.get());
  here.push_back(tum_written.get());
  for (const absl::Status& st : here) {
    if (!st.ok()) return st;
  }
  return absl::OkStatus();
}

}  // namespace

namespace {
constexpr EnumName<Frontend> kFrontendNames[] = {{Frontend::kOdometry, "odometry"}, {Frontend::kEkfSlam, "ekfslam"},
                                                 {Frontend::kFastSlam, "fastslam"}, {Frontend::kSeif, "seif"},
                                                 {Frontend::kIseif, "iseif"},       {Frontend::kRbpf, "rbpf"},
                                                 {Frontend::kEkfLocal, "ekf"}};
}  // namespace

const char* ToString(Frontend frontend) { return NameOf(kFrontendNames, frontend); }

const char* ToString(RunStop::Cause cause) {
  switch (cause) {
    case RunStop::Cause::kExportFailed:
      return "local_map_export_failed";
    case RunStop::Cause::kJoinFailed:
      return "join_failed";
    case RunStop::Cause::kNonFiniteEstimate:
      break;
  }
  return "non_finite_estimate";
}

absl::StatusOr<Frontend> FrontendFromString(const std::string& name) {
  return ParseEnum(kFrontendNames, name, "front-end");
}

namespace {

// The final map against the run's scans (MapConfirmationOptions), and the unconfirmed
// landmarks dropped when asked.
void ConfirmMap(const io::Dataset& dataset, const MapConfirmationOptions& options, RunResult* r) {
  if (!options.enabled || r->landmarks.empty() || dataset.scans.empty()) return;
  const absl::Time start = absl::Now();
  r->map_confirmation = backend::AssessLandmarkPersistence(r->landmarks, r->final_trajectory, dataset.scans,
                                                           dataset.sensor.range_bearing, options.test);
  r->map_confirmation_seconds = absl::ToDoubleSeconds(absl::Now() - start);
  if (!options.drop_unconfirmed) return;
  std::vector<LandmarkEstimate> kept;
  for (size_t i = 0; i < r->landmarks.size(); ++i) {
    if (r->map_confirmation->confirmed[i]) kept.push_back(r->landmarks[i]);
  }
  r->unconfirmed_dropped = static_cast<int>(r->landmarks.size() - kept.size());
  r->landmarks = std::move(kept);
}

}  // namespace

absl::Status RunOptions::Validate() const {
  if (absl::Status s = ekf.Validate(); !s.ok()) return s;
  if (absl::Status s = fastslam.Validate(); !s.ok()) return s;
  if (absl::Status s = policy.Validate(); !s.ok()) return s;
  if (absl::Status s = backend.Validate(); !s.ok()) return s;
  if (absl::Status s = SeifOptionsOf(*this).Validate(); !s.ok()) return s;
  if (absl::Status s = map_confirmation.Validate(); !s.ok()) return s;
  return inputs.Validate();
}

absl::Status NoiseOverrides::ApplyTo(io::Dataset* d) const {
  auto positive = [](const std::optional<double>& v, const char* name) -> absl::Status {
    if (v.has_value() && !(std::isfinite(*v) && *v > 0.0)) {
      return absl::InvalidArgumentError(absl::StrCat("--", name, " must be > 0, got ", *v));
    }
    return absl::OkStatus();
  };
  for (const auto& [v, name] : {std::pair{sigma_v, "sigma_v"},
                                {sigma_u1, "sigma_u1"},
                                {sigma_range, "sigma_range"},
                                {sigma_bearing, "sigma_bearing"},
                                {max_range, "max_range"}}) {
    if (absl::Status s = positive(v, name); !s.ok()) return s;
  }
  if (sigma_v) d->motion.noise.sigma_u0 = *sigma_v;
  if (sigma_u1) d->motion.noise.sigma_u1 = *sigma_u1;
  if (sigma_range) d->sensor.range_bearing.sigma_range_m = *sigma_range;
  if (sigma_bearing) d->sensor.range_bearing.sigma_bearing_rad = *sigma_bearing;
  if (max_range) d->sensor.range_bearing.max_range_m = *max_range;
  if (sensor_yaw) {
    if (!std::isfinite(*sensor_yaw)) return absl::InvalidArgumentError("--sensor_yaw must be finite");
    for (Scan& scan : d->scans) {
      for (Detection& det : scan.detections) det.bearing_rad = WrapAngle(det.bearing_rad + *sensor_yaw);
    }
  }
  return d->sensor.range_bearing.Validate();
}

absl::StatusOr<std::unique_ptr<frontend::OnlineEstimator>> MakeOnlineEstimator(const io::Dataset& dataset,
                                                                               const RunOptions& options) {
  io::Dataset models;  // the models and the start: the recorded data are not needed
  models.name = dataset.name;
  models.initial_pose = dataset.initial_pose;
  models.motion = dataset.motion;
  models.sensor = dataset.sensor;
  if (!dataset.controls.empty()) models.controls.push_back(dataset.controls.front());  // the mappers' start time
  if (absl::Status s = options.noise.ApplyTo(&models); !s.ok()) return s;
  absl::StatusOr<CheckedOptions> checked = CheckOptions(models, options);
  if (!checked.ok()) return checked.status();
  SubmapSlam* chain = nullptr;
  return MakeEstimator(models, options, checked->seif, &chain);
}

absl::StatusOr<RunResult> RunPipeline(io::Dataset dataset, const RunOptions& options) {
  if (absl::Status s = options.noise.ApplyTo(&dataset); !s.ok()) return s;
  absl::StatusOr<CheckedOptions> checked = CheckOptions(dataset, options);
  if (!checked.ok()) return checked.status();
  SubmapSlam* chain = nullptr;
  std::unique_ptr<frontend::OnlineEstimator> estimator = MakeEstimator(dataset, options, checked->seif, &chain);
  RunResult r;
  r.source = options.source.empty() ? dataset.name : options.source;
  r.frontend = estimator->Name();
  TruthVotes truth_votes;
  r.inputs = io::ScreenInputs(options.inputs, &dataset);
  Drive(*estimator, chain, dataset, options.progress, &r, &truth_votes);
  // The online trajectory is complete: it is written on another thread while the final
  // one, the map and the metrics are computed (Victoria Park: 69,000 rows).
  std::optional<std::filesystem::path> out_dir;
  std::future<absl::Status> online_written;
  if (!options.out_dir.empty()) {
    absl::StatusOr<std::filesystem::path> dir = io::PrepareOutputDirectory(options.out_dir, "run");
    if (!dir.ok()) return dir.status();
    out_dir = *dir;
    online_written = WriteInBackground(
        [&r, path = (*out_dir / "trajectory_online.csv").string()] { return io::WriteTrajectoryCsv(path, r.online); });
  }
  // Single-map filters have nothing to re-express; the submap pipeline re-expresses
  // every step with the final anchors. After a failed join the back-end's estimate is not
  // used (a join that failed part-way may have left it half-made): the final trajectory
  // is the online one, and the map is empty.
  r.final_trajectory = chain != nullptr && !r.join_failed ? chain->FinalTrajectory() : r.online;
  if (!r.join_failed) r.landmarks = estimator->Map();
  if (r.stop) {  // a broken estimate's landmarks are not part of the map
    const size_t before = r.landmarks.size();
    std::erase_if(r.landmarks,
                  [](const LandmarkEstimate& l) { return !l.position.allFinite() || !l.covariance.allFinite(); });
    r.non_finite_landmarks = static_cast<int>(before - r.landmarks.size());
  }
  ConfirmMap(dataset, options.map_confirmation, &r);
  if (chain != nullptr) {  // the local maps move into the result (held once)
    for (frontend::ClosedLocalMap& c : chain->TakeLocalMaps()) {
      r.impure_features += truth_votes.Label(&c.submap);
      r.local_maps.push_back(std::move(c.submap));
      r.close_reasons.push_back(frontend::ToString(c.reason));
    }
    r.joins = chain->joins();
  }
  r.peak_rss_kb = PeakRssKb();
  json metrics = Evaluate(dataset, options, chain, &r);
  r.report = RunReport(dataset, options, *checked, *estimator, r, std::move(metrics));
  if (out_dir.has_value()) {
    if (absl::Status st = WriteOutputs(*out_dir, r, dataset, chain, std::move(online_written)); !st.ok()) {
      return st;
    }
  }
  return r;
}

}  // namespace subslam::pipeline
