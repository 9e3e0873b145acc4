#include "run_report.h"

#include <map>
#include <string>

#include "report_json.h"
#include "subslam/association/data_association.h"
#include "subslam/core/enum_names.h"

namespace subslam::pipeline {
namespace {

using nlohmann::json;

// report.json's "health": whether the run completed, the input rules' counts, and each
// failure kind the estimator watches for (docs/formats.md, "health").
json Health(const RunResult& r, const std::map<std::string, double>& counters) {
  const auto count = [&counters](const char* name) {
    const auto it = counters.find(name);
    return it == counters.end() ? 0.0 : it->second;
  };
  const auto has = [&counters](const char* name) { return counters.count(name) > 0; };
  json h = {{"completed", !r.stop.has_value()}};
  if (r.stop) {
    h["stopped"] = {{"cause", ToString(r.stop->cause)},
                    {"step", r.stop->step},
                    {"t", r.stop->t},
                    {"reason", r.stop->reason},
                    {"steps_in_outputs", r.online.size()},
                    {"final_trajectory_steps", r.final_trajectory.size()}};
  }
  h["inputs"] = {{"control_spikes_replaced", r.inputs.control_spikes},
                 {"time_gaps", r.inputs.time_gaps},
                 {"longest_step_interval_s", r.inputs.longest_gap_s},
                 {"median_step_interval_s", r.inputs.median_interval_s},
                 {"repeated_control_times", r.inputs.duplicate_control_times},
                 {"detections_out_of_range", r.inputs.detections_out_of_range}};
  if (has("min_ess_ratio")) {
    h["particles"] = {{"min_ess_ratio", count("min_ess_ratio")},
                      {"depleted_updates", count("depleted_updates")},
                      {"lineage_collapses", count("lineage_collapses")},
                      {"weight_collapses", count("weight_collapses")}};
  }
  if (has("innovation_windows_tested")) {
    h["divergence"] = {{"windows_tested", count("innovation_windows_tested")},
                       {"windows_failed", count("innovation_windows_failed")},
                       {"episodes", count("divergence_episodes")},
                       {"longest_episode_scans", count("longest_divergence_scans")}};
  }
  if (has("map_test_windows_tested")) {
    h["local_maps_against_the_map"] = {{"d2_per_dof", count("map_test_d2_per_dof")},
                                       {"windows_tested", count("map_test_windows_tested")},
                                       {"windows_failed", count("map_test_windows_failed")},
                                       {"dof", count("map_test_dof")},
                                       {"longest_episode_joins", count("map_test_longest_episode_joins")},
                                       {"diverged", count("map_test_diverged") > 0}};
  }
  h["numerical_failures"] = {{"filter", count("numerical_failures")},
                             {"factor_updates_refactorised", count("join_failed_updates")}};
  if (has("join_maps")) {
    h["joins"] = {{"joined", count("join_maps")},
                  {"failed", r.join_failed ? 1 : 0},
                  {"rejected_and_joined_without_associations", count("join_rejected")},
                  {"loop_closures_undone", count("join_loop_closures_unconfirmed")},
                  {"landmarks_merged", count("join_landmarks_merged")},
                  {"features_split", count("join_features_split")}};
  }
  h["non_finite_landmarks_dropped"] = r.non_finite_landmarks;
  if (r.map_confirmation) {
    const backend::LandmarkPersistence& c = *r.map_confirmation;
    json curve = json::array();
    for (const backend::DetectionRate& d : c.detection_probability) {
      if (d.expected == 0) continue;
      curve.push_back({{"range_min_m", d.range_min_m},
                       {"range_max_m", d.range_max_m},
                       {"expected", d.expected},
                       {"detected", d.detected},
                       {"probability", d.probability}});
    }
    h["map_confirmation"] = {{"landmarks", c.confirmed.size()},
                             {"confirmed", c.num_confirmed},
                             {"unconfirmed_dropped", r.unconfirmed_dropped},
                             {"chance_pairing_probability", c.chance_pairing_probability},
                             {"chance_pairing_density", c.chance_pairing_density},
                             {"scans", c.scans_used},
                             {"detection_probability_by_range", curve}};
  }
  return h;
}

}  // namespace

json RunReport(const io::Dataset& dataset, const RunOptions& options, const CheckedOptions& checked,
               const frontend::OnlineEstimator& estimator, const RunResult& r, json metrics) {
  const frontend::SeifOptions& seif = checked.seif;
  json stage_times = json::object();
  for (const auto& [stage, seconds] : estimator.stage_times()) stage_times[stage] = seconds;
  json counters = json::object();
  const std::map<std::string, double> estimator_counters = estimator.Counters();
  for (const auto& [name, value] : estimator_counters) counters[name] = value;
  const models::RangeBearingConfig& rb = dataset.sensor.range_bearing;
  json report = {
      {"format", "subslam-report/1"},
      {"source", r.source},
      {"dataset", dataset.name},
      {"configuration",
       {{"frontend", r.frontend},
        {"motion_model", io::ToString(dataset.motion.model)},
        {"sigma_v", dataset.motion.noise.sigma_u0},
        {"sigma_u1", dataset.motion.noise.sigma_u1},
        {"sigma_v_scale", dataset.motion.noise.scale_u0},
        {"sigma_u1_scale", dataset.motion.noise.scale_u1},
        {"sigma_range", rb.sigma_range_m},
        {"sigma_bearing", rb.sigma_bearing_rad},
        {"min_range", rb.min_range_m},
        {"max_range", rb.max_range_m},
        {"sensor_yaw", options.noise.sensor_yaw.value_or(0.0)},
        {"association", checked.known_association ? "known" : association::ToString(options.ekf.association)},
        {"gate_probability", options.ekf.landmarks.gate_probability},
        {"new_landmark_probability", options.ekf.landmarks.new_landmark_probability},
        {"existence_detection_probability", options.ekf.landmarks.existence.detection_probability},
        {"existence_false_alarm_probability", options.ekf.landmarks.existence.false_alarm_probability}}},
      {"counts",
       {{"steps", r.steps},
        {"scans", r.scans},
        {"detections", r.detections},
        {"submaps", r.local_maps.size()},
        {"landmarks", r.landmarks.size()}}},
      {"estimator_counters", counters},
      {"time_seconds",
       {{"total", r.wall_seconds},
        {"stages", stage_times},
        {"cumulative_by_tenth_of_steps", r.wall_seconds_by_tenth},
        {"map_confirmation", r.map_confirmation_seconds}}},
      {"peak_rss_kb", r.peak_rss_kb},
      {"rss_kb_by_tenth_of_steps", r.rss_kb_by_tenth},
      {"health", Health(r, estimator_counters)},
      {"metrics", std::move(metrics)}};

  if (options.backend.kind != Backend::kNone &&
      (options.frontend == Frontend::kRbpf || options.frontend == Frontend::kEkfLocal)) {
    // What the online and final figures depend on.
    report["configuration"]["backend"] = {
        {"kind", ToString(options.backend.kind)},
        {"background", options.backend.background},
        {"relinearize_heading_change", options.backend.eif.relinearize_heading_change},
        {"relinearize_linearization_chi2", options.backend.eif.relinearize_linearization_chi2},
        {"relinearize_every", options.backend.eif.relinearize_every},
        {"relinearize_at_end", EifRelinearizesAtEnd(options.backend)}};
  }
  if (options.frontend == Frontend::kSeif || options.frontend == Frontend::kIseif) {
    report["configuration"]["seif"] = {{"known_association", seif.landmarks.known_association},
                                       {"association", association::ToString(seif.association)},
                                       {"max_active_landmarks", seif.max_active_landmarks},
                                       {"mean_recovery", frontend::ToString(seif.recovery)},
                                       {"relaxation_sweeps", seif.relaxation_sweeps},
                                       {"relaxation_extra_landmarks", seif.relaxation_extra_landmarks},
                                       {"covariance_recovery", frontend::ToString(seif.covariance)},
                                       {"pose_covariance", frontend::ToString(seif.pose_covariance)},
                                       {"candidate_radius_m", seif.candidate_radius_m},
                                       {"blanket_max_landmarks", seif.blanket_max_landmarks},
                                       {"iterated", seif.iterated.enabled},
                                       {"iterated_period_scans", seif.iterated.period_scans},
                                       {"iterated_max_iterations", seif.iterated.max_iterations},
                                       {"iterated_stop_change", seif.iterated.stop_change},
                                       {"iterated_exact_recoveries", seif.iterated.exact_recoveries}};
  }
  if (options.frontend == Frontend::kFastSlam || options.frontend == Frontend::kRbpf) {
    const frontend::FastSlamOptions& f = options.fastslam;
    report["configuration"]["particle_filter"] = {{"particles", f.num_particles},
                                                  {"filter_seed", f.seed},
                                                  {"sample_association", f.sample_association},
                                                  {"landmark_update_iterations", f.landmark_update_iterations},
                                                  {"resample_ess_ratio", f.resample_ess_ratio},
                                                  {"sensor_yaw_sigma", f.sensor_yaw_sigma}};
  }
  if (options.frontend == Frontend::kRbpf || options.frontend == Frontend::kEkfLocal) {
    const frontend::SubmapPolicyOptions& p = options.policy;
    report["configuration"]["submap_policy"] = {{"min_duration_s", p.min_duration_s},
                                                {"max_duration_s", p.max_duration_s},
                                                {"max_features", p.max_features},
                                                {"min_ess_ratio", p.min_ess_ratio},
                                                {"min_lineage_diversity", p.min_lineage_diversity},
                                                {"max_pose_sigma_ratio", p.max_pose_sigma_ratio},
                                                {"max_feature_sigma_ratio", p.max_feature_sigma_ratio},
                                                {"density_min_features", p.density_min_features},
                                                {"density_min_visible", p.density_min_visible},
                                                {"delay_while_ambiguous", p.delay_while_ambiguous}};
  }
  report["build"] = BuildJson();
  if (!options.invocation.is_null()) report["invocation"] = options.invocation;
  return report;
}

}  // namespace subslam::pipeline
