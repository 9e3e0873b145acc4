// The human-readable summaries `subslam run` and `subslam join` print: one row per figure
// the inputs allow, in one style.
#include <map>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "subslam/core/conventions.h"
#include "subslam/pipeline/join_pipeline.h"
#include "subslam/pipeline/run_pipeline.h"

namespace subslam::pipeline {

namespace {

// The rows of a summary: "  key   value" lines.
class Rows {
 public:
  void Add(const std::string& key, const std::string& value) {
    absl::StrAppendFormat(&text_, "  %-34s %s\n", key, value);
  }
  const std::string& text() const { return text_; }

 private:
  std::string text_;
};

// The estimate against the ground truth: the trajectory, the map, the GPS.
void AddAccuracyRows(const RunResult& r, Rows* rows) {
  if (r.errors) {
    const eval::TrajectoryErrors& e = *r.errors;
    rows->Add("RMS position / heading",
              absl::StrFormat("%.3f m / %.3f deg", e.rms_position_m, RadToDeg(e.rms_heading_rad)));
    rows->Add("max / final position error",
              absl::StrFormat("%.3f m / %.3f m", e.max_position_error_m, e.final_position_error_m));
    rows->Add("mean pose NEES (3 dof)", absl::StrFormat("%.2f  (CI %.2f)", e.mean_nees, e.mean_consistency_index));
    rows->Add("steps with NEES in 95% bounds", absl::StrFormat("%.1f %%", 100 * e.fraction_nees_in_bounds));
    rows->Add("10-sigma failure test", e.failed ? "FAILED" : "passed");
  }
  if (r.errors_online) {
    rows->Add("online: RMS position / NEES in bounds",
              absl::StrFormat("%.3f m / %.1f %% (trajectory_online.csv)", r.errors_online->rms_position_m,
                              100 * r.errors_online->fraction_nees_in_bounds));
  }
  if (r.map_errors && r.map_errors->estimated > 0) {
    rows->Add("map: matched / spurious / duplicate",
              absl::StrFormat("%d / %d / %d, RMS %.3f m", r.map_errors->matched, r.map_errors->spurious,
                              r.map_errors->duplicates, r.map_errors->rms_m));
  }
  if (r.gps_final) {
    rows->Add("aligned RMS vs GPS (final)",
              absl::StrFormat("%.2f m (x %.2f, y %.2f; %d fixes, %d gross faults dropped)", r.gps_final->rms_m,
                              r.gps_final->rms_x_m, r.gps_final->rms_y_m, r.gps_final->matched_fixes,
                              r.gps_final->rejected_fixes));
  }
  if (r.gps_online) {
    rows->Add("aligned RMS vs GPS (online)", absl::StrFormat("%.2f m (trajectory_online.csv)", r.gps_online->rms_m));
  }
}

// The local maps: why they closed, their consistency, what they exported.
void AddLocalMapRows(const RunResult& r, Rows* rows) {
  if (!r.local_maps.empty()) {
    std::map<std::string, int> reasons;
    for (const std::string& reason : r.close_reasons) ++reasons[reason];
    std::string text;
    for (const auto& [reason, count] : reasons) absl::StrAppend(&text, text.empty() ? "" : ", ", reason, " ", count);
    rows->Add("local maps (closed by)", absl::StrCat(r.local_maps.size(), " (", text, ")"));
  }
  if (r.local_map_summary) {
    const LocalMapSummary& m = *r.local_map_summary;
    rows->Add("local maps: NEES in 95% bounds",
              absl::StrFormat("%d / %d joint, %d / %d end pose; mean NEES/dof %.2f", m.inside, m.evaluated,
                              m.pose_inside, m.evaluated, m.nees_per_dof));
    rows->Add("local maps: landmark NEES in bounds",
              absl::StrFormat("%d / %d (2-dof marginals)", m.landmarks_inside, m.landmarks));
    std::string held_back;
    if (r.report.contains("estimator_counters") &&
        r.report["estimator_counters"].contains("moving_features_not_exported")) {
      held_back = absl::StrFormat(" (%.0f features held back as moving)",
                                  r.report["estimator_counters"]["moving_features_not_exported"].get<double>());
    }
    rows->Add("local maps: false alarms exported", absl::StrCat(m.false_alarms, held_back));
    rows->Add("local maps: features mixing landmarks", absl::StrCat(r.impure_features));
  }
}

// What the back-end revised and calibrated.
void AddBackendRows(const RunResult& r, Rows* rows) {
  if (r.report.contains("estimator_counters") && r.report["estimator_counters"].contains("join_landmarks_merged")) {
    const nlohmann::json& c = r.report["estimator_counters"];
    rows->Add("back-end association revised",
              absl::StrFormat("%.0f landmarks merged, %.0f features split", c["join_landmarks_merged"].get<double>(),
                              c["join_features_split"].get<double>()));
  }
  if (r.report.contains("estimator_counters") && r.report["estimator_counters"].contains("sensor_yaw_correction")) {
    const nlohmann::json& c = r.report["estimator_counters"];
    rows->Add("sensor yaw, online calibration",
              absl::StrFormat("%+.4f rad (sigma %.4f) from %.0f feature pairs; %.0f maps joined turned",
                              c["sensor_yaw_correction"].get<double>(), c["sensor_yaw_correction_sigma"].get<double>(),
                              c["sensor_yaw_pairs"].get<double>(), c["sensor_yaw_maps_turned"].get<double>()));
  }
}

// report.json's health.
void AddHealthRows(const nlohmann::json& h, Rows* rows) {
  const auto n = [](const nlohmann::json& v) { return static_cast<long>(v.get<double>()); };
  const nlohmann::json& in = h["inputs"];
  rows->Add("inputs: spikes / gaps / repeated t",
            absl::StrFormat("%d / %d (longest step %.3g s) / %d; %d detections out of range",
                            in["control_spikes_replaced"].get<int>(), in["time_gaps"].get<int>(),
                            in["longest_step_interval_s"].get<double>(), in["repeated_control_times"].get<int>(),
                            in["detections_out_of_range"].get<long>()));
  if (h.contains("particles")) {
    const nlohmann::json& p = h["particles"];
    rows->Add("particles: min ESS / depleted",
              absl::StrFormat("%.3f N / %d updates; %d lineage collapses, %d weight collapses",
                              p["min_ess_ratio"].get<double>(), n(p["depleted_updates"]), n(p["lineage_collapses"]),
                              n(p["weight_collapses"])));
  }
  if (h.contains("divergence")) {
    const nlohmann::json& d = h["divergence"];
    rows->Add("innovation test: windows failed",
              absl::StrFormat("%d / %d (%d episodes, longest %d scans)", n(d["windows_failed"]), n(d["windows_tested"]),
                              n(d["episodes"]), n(d["longest_episode_scans"])));
  }
  if (h.contains("local_maps_against_the_map")) {
    const nlohmann::json& m = h["local_maps_against_the_map"];
    rows->Add("local maps against the map",
              absl::StrFormat("%s: d²/dof %.2f over %d dof; windows of joins failed %d / %d",
                              m["diverged"].get<bool>() ? "DIVERGED" : "consistent", m["d2_per_dof"].get<double>(),
                              n(m["dof"]), n(m["windows_failed"]), n(m["windows_tested"])));
  }
  if (h.contains("map_confirmation")) {
    const nlohmann::json& c = h["map_confirmation"];
    std::string curve;
    for (const nlohmann::json& d : c["detection_probability_by_range"]) {
      if (curve.empty()) {
        curve = absl::StrFormat("from %.3g m by %.3g m:", d["range_min_m"].get<double>(),
                                d["range_max_m"].get<double>() - d["range_min_m"].get<double>());
      }
      absl::StrAppend(&curve, absl::StrFormat(" %.2f", d["probability"].get<double>()));
    }
    rows->Add(
        "map confirmed by the scans",
        absl::StrFormat("%d of %d landmarks (chance %.3f per sighting)%s; P_D by range %s", n(c["confirmed"]),
                        n(c["landmarks"]), c["chance_pairing_probability"].get<double>(),
                        n(c["unconfirmed_dropped"]) > 0 ? absl::StrFormat(", %d dropped", n(c["unconfirmed_dropped"]))
                                                        : std::string(),
                        curve));
  }
  const nlohmann::json& nf = h["numerical_failures"];
  if (n(nf["filter"]) > 0 || n(nf["factor_updates_refactorised"]) > 0) {
    rows->Add("numerical failures", absl::StrFormat("%d in the filter (update skipped), %d factor updates refactorised",
                                                    n(nf["filter"]), n(nf["factor_updates_refactorised"])));
  }
  if (h.contains("joins")) {
    const nlohmann::json& j = h["joins"];
    rows->Add("joins: health",
              absl::StrFormat("%d failed, %d rejected, %d loop closures undone", n(j["failed"]),
                              n(j["rejected_and_joined_without_associations"]), n(j["loop_closures_undone"])));
  }
}

}  // namespace

std::string SummaryTable(const RunResult& r) {
  Rows rows;
  rows.Add("ran", absl::StrCat(r.frontend, " on ", r.source));
  if (r.stop) {
    rows.Add("STOPPED", absl::StrFormat("at step %d of %d (t = %.3f s): %s; outputs up to there", r.stop->step, r.steps,
                                        r.stop->t, r.stop->reason));
  }
  rows.Add("steps / scans / detections", absl::StrCat(r.steps, " / ", r.scans, " / ", r.detections));
  rows.Add("landmarks in map", absl::StrCat(r.landmarks.size()));
  AddAccuracyRows(r, &rows);
  AddLocalMapRows(r, &rows);
  AddBackendRows(r, &rows);
  if (r.report.contains("health")) AddHealthRows(r.report["health"], &rows);
  rows.Add("estimator time", absl::StrFormat("%.3f s", r.wall_seconds));
  rows.Add("peak memory", absl::StrFormat("%.1f MB", r.peak_rss_kb / 1024.0));
  return rows.text();
}

std::string JoinSummaryTable(const JoinResult& r) {
  Rows rows;
  const auto row = [&rows](const std::string& key, const std::string& value) { rows.Add(key, value); };
  const nlohmann::json& report = r.report;
  const nlohmann::json& counts = report["counts"];
  const nlohmann::json& metrics = report["metrics"];
  row("joined", absl::StrCat(r.local_maps, " local maps by ", report["configuration"]["backend"].get<std::string>()));
  row("anchors / landmarks in map", absl::StrCat(r.anchors.size(), " / ", r.landmarks.size()));
  const auto trajectory_row = [&](const char* key, const char* label) {
    if (!metrics.contains(key)) return;
    const nlohmann::json& e = metrics[key];
    row(label, absl::StrFormat("%.3f m / %.3f deg; NEES in 95%% bounds %.1f %%", e["rms_position_m"].get<double>(),
                               RadToDeg(e["rms_heading_rad"].get<double>()),
                               100 * e["fraction_steps_nees_in_95_bounds"].get<double>()));
  };
  trajectory_row("anchors", "anchors: RMS position / heading");
  trajectory_row("anchors_online", "online anchors: RMS pos. / heading");
  if (metrics.contains("map") && metrics["map"]["estimated"].get<int>() > 0) {
    const nlohmann::json& m = metrics["map"];
    row("map: matched / spurious / duplicate",
        absl::StrFormat("%d / %d / %d, RMS %.3f m", m["matched"].get<int>(), m["spurious"].get<int>(),
                        m["duplicates"].get<int>(), m["rms_m"].get<double>()));
  }
  const auto gps_row = [&](const char* key, const char* label) {
    if (!metrics.contains(key)) return;
    const nlohmann::json& g = metrics[key];
    row(label, absl::StrFormat("%.2f m (%d fixes, %d gross faults dropped)", g["aligned_rms_m"].get<double>(),
                               g["matched_fixes"].get<int>(), g["rejected_fixes"].get<int>()));
  };
  gps_row("gps_anchors", "aligned RMS vs GPS (anchors)");
  gps_row("gps_anchors_online", "aligned RMS vs GPS (online anchors)");
  if (metrics.contains("association_vs_truth_id")) {
    const AssociationVsTruth& a = r.association;
    row("association vs true ids",
        absl::StrFormat("%d true landmarks seen; %d missed, %d wrong merges; loop re-observations %d / %d missed",
                        a.correct, a.missed, a.wrong, a.loop_missed, a.loop_merged + a.loop_missed));
  }
  if (counts.contains("sensor_yaw_correction")) {
    row("sensor yaw, online calibration",
        absl::StrFormat("%+.4f rad (sigma %.4f)", counts["sensor_yaw_correction"].get<double>(),
                        counts["sensor_yaw_correction_sigma"].get<double>()));
  }
  row("time", absl::StrFormat("%.3f s joining", r.wall_seconds));
  return rows.text();
}

}  // namespace subslam::pipeline
