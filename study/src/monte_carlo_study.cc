#include "monte_carlo_study.h"

#include <cmath>
#include <map>
#include <set>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "subslam/eval/nees.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/sim/simulator.h"
#include "table_statistics.h"

namespace subslam::study {
namespace {

using nlohmann::json;

std::string Bit(bool b) { return b ? "1" : "0"; }

// Every combination of the settings' values, the first setting varying slowest.
std::vector<std::vector<double>> Combinations(const std::vector<std::vector<double>>& settings) {
  std::vector<std::vector<double>> all = {{}};
  for (const std::vector<double>& values : settings) {
    std::vector<std::vector<double>> next;
    for (const std::vector<double>& prefix : all) {
      for (double v : values) {
        next.push_back(prefix);
        next.back().push_back(v);
      }
    }
    all = std::move(next);
  }
  return all;
}

class MonteCarloStudy final : public Study {
 public:
  explicit MonteCarloStudy(MonteCarloSpec spec) : spec_(std::move(spec)) {}

  std::string name() const override { return spec_.name; }
  std::string title() const override { return spec_.title; }
  int paper_trials() const override { return spec_.paper_trials; }
  std::vector<std::string> method_names() const override {
    std::vector<std::string> names = MethodNames(spec_.methods);
    for (const std::string& name : MethodNames(spec_.dataset_methods)) names.push_back(name);
    return names;
  }
  bool uses_dataset() const override { return !spec_.dataset_methods.empty(); }
  std::vector<std::string> setting_names() const override { return spec_.setting_names; }
  std::vector<std::string> metric_names() const override {
    return {"rms_online_m",     "rms_final_m",           "rms_x_m", "rms_y_m",   "rms_heading_rad", "final_error_m",
            "mean_nees_online", "nees_in_bounds_online", "success", "map_rms_m", "map_rms_x_m",     "map_rms_y_m",
            "local_maps"};
  }
  std::vector<std::string> series_names() const override { return {"t_s", "nees", "position_error_m"}; }
  std::vector<std::string> timing_names() const override {
    return {"estimator_s", "join_association_s", "join_update_s", "join_other_s"};
  }
  std::string paper_timings() const override { return spec_.paper_timings; }

  std::vector<StudyRun> Runs(int trials, const std::string& dataset_dir) const override {
    std::vector<StudyRun> runs;
    for (const std::vector<double>& setting : Combinations(spec_.settings)) {
      for (int trial = 1; trial <= trials; ++trial) {
        for (const StudyMethod& method : spec_.methods) {
          StudyRun run{static_cast<int>(runs.size()), method.name, {}, trial, static_cast<uint64_t>(trial), ""};
          for (size_t s = 0; s < setting.size(); ++s) run.setting.push_back({spec_.setting_names[s], setting[s]});
          runs.push_back(std::move(run));
        }
      }
    }
    if (!dataset_dir.empty()) {
      for (const StudyMethod& method : spec_.dataset_methods) {
        StudyRun run{static_cast<int>(runs.size()), method.name, {}, 1, 0, dataset_dir};
        for (size_t s = 0; s < spec_.setting_names.size(); ++s) run.setting.push_back({spec_.setting_names[s], NAN});
        runs.push_back(std::move(run));
      }
    }
    return runs;
  }

  absl::StatusOr<RunMeasurement> Execute(const StudyRun& run) const override {
    if (!run.dataset.empty()) return ExecuteOnDataset(run);
    const StudyMethod* method = FindMethod(spec_.methods, run.method);
    if (method == nullptr) return absl::InvalidArgumentError("not a run of this study");
    sim::ScenarioOptions scenario;
    scenario.seed = run.seed;
    std::vector<double> setting;
    for (const auto& [name, value] : run.setting) setting.push_back(value);
    if (spec_.apply_setting) spec_.apply_setting(setting, &scenario);
    absl::StatusOr<io::Dataset> dataset = sim::SimulateScenario(spec_.scenario, scenario);
    if (!dataset.ok()) return dataset.status();
    const std::vector<io::TimedPose> truth = dataset->truth_poses;
    absl::StatusOr<pipeline::RunResult> r = RunMethodWithTruth(*method, *std::move(dataset));
    if (!r.ok()) return r.status();
    const eval::TrajectoryErrors& online = OnlineErrors(*r);
    const eval::TrajectoryErrors& final_errors = *r->errors;
    const auto MapFigure = [&](double v) { return r->map_errors->matched > 0 ? FormatNumber(v) : std::string("nan"); };
    RunMeasurement m;
    m.metrics = {FormatNumber(online.rms_position_m),
                 FormatNumber(final_errors.rms_position_m),
                 FormatNumber(final_errors.rms_x_m),
                 FormatNumber(final_errors.rms_y_m),
                 FormatNumber(final_errors.rms_heading_rad),
                 FormatNumber(online.final_position_error_m),
                 FormatNumber(online.mean_nees),
                 FormatNumber(online.fraction_nees_in_bounds),
                 Bit(!online.failed),
                 MapFigure(r->map_errors->rms_m),
                 MapFigure(r->map_errors->rms_x_m),
                 MapFigure(r->map_errors->rms_y_m),
                 absl::StrCat(r->local_maps.size())};
    // The online pose every series_period_s (the first step at or after each multiple of
    // the period after the first step, whose pose is given): its NEES and position error.
    const Trajectory& trajectory = r->online;
    const double t0 = trajectory.empty() ? 0.0 : trajectory.front().t;
    int sample = 1;
    for (size_t k = 0; k < trajectory.size() && k < online.nees.size(); ++k) {
      const double nominal = sample * spec_.series_period_s;
      if (trajectory[k].t - t0 + 1e-9 < nominal) continue;
      const Pose2 true_pose = eval::InterpolatePose(truth, trajectory[k].t);
      const double error = (trajectory[k].pose.translation() - true_pose.translation()).norm();
      m.series.push_back({FormatNumber(nominal), FormatNumber(online.nees[k]), FormatNumber(error)});
      ++sample;
    }
    m.timings = JoinTimings(*r);
    for (const backend::JoinSummary& join : r->joins) m.join_seconds.push_back(join.seconds);
    return m;
  }

  // A run on the real data set: its error against the aligned GPS (x and y in the GPS
  // frame; the other metrics need a true pose, so nan).
  absl::StatusOr<RunMeasurement> ExecuteOnDataset(const StudyRun& run) const {
    const StudyMethod* method = FindMethod(spec_.dataset_methods, run.method);
    if (method == nullptr) return absl::InvalidArgumentError("not a data-set run of this study");
    absl::StatusOr<io::Dataset> dataset = io::ReadDataset(run.dataset);
    if (!dataset.ok()) return dataset.status();
    absl::StatusOr<pipeline::RunResult> r = RunMethod(*method, *std::move(dataset));
    if (!r.ok()) return r.status();
    if (!r->gps_final || !r->gps_online) {
      return absl::InvalidArgumentError(absl::StrCat(run.dataset, ": the data set has no GPS to measure against"));
    }
    const std::string nan = "nan";
    RunMeasurement m;
    m.metrics = {FormatNumber(r->gps_online->rms_m),
                 FormatNumber(r->gps_final->rms_m),
                 FormatNumber(r->gps_final->rms_x_m),
                 FormatNumber(r->gps_final->rms_y_m),
                 nan,
                 nan,
                 nan,
                 nan,
                 nan,
                 nan,
                 nan,
                 nan,
                 absl::StrCat(r->local_maps.size())};
    m.timings = JoinTimings(*r);
    return m;
  }

  // The estimator's time and its joining split into association (with the covariance
  // recovery it needs), the global map's update, and the rest of joining, from the run's
  // stage timers.
  static std::vector<double> JoinTimings(const pipeline::RunResult& r) {
    double association = 0.0, update = 0.0, other = 0.0;
    for (const auto& [stage, seconds] : r.report["time_seconds"]["stages"].items()) {
      if (stage.rfind("join_", 0) != 0) continue;
      const double s = seconds.get<double>();
      if (stage == "join_association" || stage == "join_covariance_recovery") {
        association += s;
      } else if (stage == "join_update") {
        update += s;
      } else {
        other += s;
      }
    }
    return {r.wall_seconds, association, update, other};
  }

  json Configuration() const override {
    std::string command = absl::StrCat("subslam run --scenario ", spec_.scenario, " --seed TRIAL");
    for (const std::string& setting : spec_.setting_names) {
      absl::StrAppend(&command, " --", setting, " ", absl::AsciiStrToUpper(setting));
    }
    json settings = json::object();
    for (size_t s = 0; s < spec_.settings.size(); ++s) settings[spec_.setting_names[s]] = spec_.settings[s];
    json config = {{"scenario", spec_.scenario},
                   {"settings", settings},
                   {"seeds",
                    "trial k (1-based) uses --seed k: its own world, noise and detections, the same for every "
                    "method"},
                   {"series", absl::StrFormat("the online pose every %s s: its NEES (3 dof) and position error",
                                              FormatNumber(spec_.series_period_s))},
                   {"methods", MethodsJson(spec_.methods, command)}};
    if (!spec_.dataset_methods.empty()) {
      config["dataset_methods"] = MethodsJson(spec_.dataset_methods, "subslam run --dataset DATASET");
    }
    return config;
  }

  absl::StatusOr<json> Summarize(const RunTable& runs, const RunTable& series) const override {
    json rows = json::array();
    for (const std::vector<double>& setting : Combinations(spec_.settings)) {
      for (const StudyMethod& method : spec_.methods) {
        std::vector<std::pair<std::string, std::string>> key = {{"method", method.name}};
        for (size_t s = 0; s < setting.size(); ++s) key.push_back({spec_.setting_names[s], FormatNumber(setting[s])});
        const std::vector<int> group = RowsWhere(runs, key);
        if (group.empty()) continue;
        absl::StatusOr<json> row = SummarizeGroup(runs, series, group, method.name, setting);
        if (!row.ok()) return row.status();
        rows.push_back(*std::move(row));
      }
    }
    for (const StudyMethod& method : spec_.dataset_methods) {
      const std::vector<int> group = RowsWhere(runs, {{"method", method.name}});
      if (group.empty()) continue;
      absl::StatusOr<std::vector<double>> online = Values(runs, group, "rms_online_m"),
                                          final_rms = Values(runs, group, "rms_final_m"),
                                          x = Values(runs, group, "rms_x_m"), y = Values(runs, group, "rms_y_m");
      for (const auto* v : {&online, &final_rms, &x, &y}) {
        if (!v->ok()) return v->status();
      }
      rows.push_back({{"method", method.name},
                      {"dataset", true},
                      {"trials", static_cast<int>(group.size())},
                      {"gps_rms_online_m", Median(*online)},
                      {"gps_rms_m", Median(*final_rms)},
                      {"gps_rms_x_m", Median(*x)},
                      {"gps_rms_y_m", Median(*y)},
                      {"paper", spec_.paper_dataset_finding ? spec_.paper_dataset_finding(method.name) : ""}});
    }
    if (rows.empty()) return absl::InvalidArgumentError("runs.csv holds no run of this study");
    return json{{"study", name()}, {"title", title()}, {"rows", rows}};
  }

  std::string SummaryMarkdown(const json& summary) const override {
    std::string md = absl::StrCat("# ", summary["title"].get<std::string>(), "\n\n");
    absl::StrAppend(&md, "Consistency: the pose NEES (3 dof) of the online estimate averaged over the runs every ",
                    FormatNumber(spec_.series_period_s),
                    " s (ANEES) against its two-sided 95 % χ² band for that many runs; the consistency index CI = "
                    "NEES / χ²₃(0.95) averaged over the runs; success: the 10σ test.\n\n");
    const std::string settings_header = Header(" | ");
    absl::StrAppend(&md, "| method", settings_header,
                    " | runs | ANEES inside the band | mean CI < 1 | max mean CI | 10σ "
                    "successes | local maps | the paper |\n",
                    Rule(8 + spec_.setting_names.size()));
    for (const json& row : summary["rows"]) {
      if (row.contains("dataset")) continue;
      absl::StrAppend(&md,
                      absl::StrFormat("| %s%s | %d | %.1f %% of %d times | %.1f %% | %.3g | %d / %d | %.0f | %s |\n",
                                      row["method"].get<std::string>(), SettingCells(row), row["trials"].get<int>(),
                                      100 * row["anees_inside_band"].get<double>(), row["anees_times"].get<int>(),
                                      100 * row["mean_ci_below_one"].get<double>(), row["max_mean_ci"].get<double>(),
                                      row["successes"].get<int>(), row["trials"].get<int>(),
                                      row["median_local_maps"].get<double>(), row["paper"].get<std::string>()));
    }
    absl::StrAppend(
        &md,
        "\nAccuracy, averaged over the runs (the final trajectory and map; online: the estimate as it "
        "was at each step, median over the runs):\n\n| method",
        settings_header,
        " | pose x [m] | pose y [m] | heading [°] | landmark x [m] | landmark y [m] | online RMS [m] | final "
        "RMS [m] |\n",
        Rule(8 + spec_.setting_names.size()));
    for (const json& row : summary["rows"]) {
      if (row.contains("dataset")) continue;
      absl::StrAppend(&md, "| ", row["method"].get<std::string>(), SettingCells(row));
      for (const char* key : {"mean_rms_x_m", "mean_rms_y_m", "mean_rms_heading_deg", "mean_map_rms_x_m",
                              "mean_map_rms_y_m", "median_rms_online_m", "median_rms_final_m"}) {
        const bool known = row[key].is_number() && !std::isnan(row[key].get<double>());  // null in summary.json
        absl::StrAppend(&md, " | ", known ? absl::StrFormat("%.3f", row[key].get<double>()) : "–");
      }
      absl::StrAppend(&md, " |\n");
    }
    bool dataset_header = false;
    for (const json& row : summary["rows"]) {
      if (!row.contains("dataset")) continue;
      if (!dataset_header) {
        absl::StrAppend(&md, "\n", spec_.dataset_title,
                        " (aligned RMS against the GPS, gross GPS faults dropped; docs/formats.md):\n\n| method | "
                        "final x [m] | final y [m] | final [m] | online [m] | the paper |\n| --- | --- | --- | --- | "
                        "--- | --- |\n");
        dataset_header = true;
      }
      absl::StrAppend(&md, absl::StrFormat("| %s | %.2f | %.2f | %.2f | %.2f | %s |\n",
                                           row["method"].get<std::string>(), row["gps_rms_x_m"].get<double>(),
                                           row["gps_rms_y_m"].get<double>(), row["gps_rms_m"].get<double>(),
                                           row["gps_rms_online_m"].get<double>(), row["paper"].get<std::string>()));
    }
    return md;
  }

 private:
  std::string Header(const std::string& separator) const {
    std::string header;
    for (const std::string& s : spec_.setting_names) absl::StrAppend(&header, separator, s);
    return header;
  }
  static std::string Rule(size_t columns) {
    std::string rule = "|";
    for (size_t c = 0; c < columns; ++c) absl::StrAppend(&rule, " --- |");
    return rule + "\n";
  }
  std::string SettingCells(const json& row) const {
    std::string cells;
    for (const std::string& s : spec_.setting_names) absl::StrAppend(&cells, " | ", FormatNumber(row[s].get<double>()));
    return cells;
  }

  absl::StatusOr<json> SummarizeGroup(const RunTable& runs, const RunTable& series, const std::vector<int>& group,
                                      const std::string& method, const std::vector<double>& setting) const {
    std::map<std::string, std::vector<double>> v;
    for (const char* column : {"rms_online_m", "rms_final_m", "rms_x_m", "rms_y_m", "rms_heading_rad", "map_rms_m",
                               "map_rms_x_m", "map_rms_y_m", "success", "local_maps"}) {
      absl::StatusOr<std::vector<double>> values = Values(runs, group, column);
      if (!values.ok()) return values.status();
      v[column] = *std::move(values);
    }
    // NaN (null in summary.json) where no run has the value, e.g. a map's error without a map.
    const auto mean = [](const std::vector<double>& x) {
      double sum = 0.0;
      int n = 0;
      for (double v : x) {
        if (std::isnan(v)) continue;
        sum += v;
        ++n;
      }
      return n > 0 ? sum / n : std::nan("");
    };
    // The series of the group's runs, per sample time (in time order).
    std::set<std::string> in_group;  // the group's run indices
    for (int r : group) in_group.insert(runs.rows()[r][0]);
    std::map<double, std::vector<std::pair<double, double>>> by_time;  // t → (nees, error) per run
    for (int r = 0; r < series.num_rows(); ++r) {
      if (!in_group.contains(series.rows()[r][0])) continue;
      absl::StatusOr<double> t = series.Number(r, "t_s"), nees = series.Number(r, "nees"),
                             error = series.Number(r, "position_error_m");
      for (const auto* x : {&t, &nees, &error}) {
        if (!x->ok()) return absl::InvalidArgumentError(absl::StrCat("series.csv: ", x->status().message()));
      }
      by_time[*t].push_back({*nees, *error});
    }
    json t_s = json::array(), anees = json::array(), low = json::array(), high = json::array(), mean_ci = json::array(),
         rms = json::array(), counted = json::array();
    int inside = 0, ci_below_one = 0, times = 0;
    double max_ci = 0.0;
    for (const auto& [t, values] : by_time) {
      double nees_sum = 0.0, ci_sum = 0.0, squared = 0.0;
      int n = 0;
      for (const auto& [nees, error] : values) {
        squared += error * error;
        if (std::isnan(nees)) continue;
        nees_sum += nees;
        ci_sum += eval::ConsistencyIndex(nees, 3);
        ++n;
      }
      if (n == 0) continue;  // no run has a covariance there
      const eval::NeesBounds band = eval::AverageNeesBounds(3, n);
      const double average = nees_sum / n, ci = ci_sum / n;
      t_s.push_back(t);
      anees.push_back(average);
      low.push_back(band.lower);
      high.push_back(band.upper);
      mean_ci.push_back(ci);
      rms.push_back(std::sqrt(squared / values.size()));
      counted.push_back(n);
      ++times;
      inside += band.Contains(average) ? 1 : 0;
      ci_below_one += ci < 1.0 ? 1 : 0;
      max_ci = std::max(max_ci, ci);
    }
    json row = {{"method", method}, {"trials", static_cast<int>(group.size())}};
    for (size_t s = 0; s < setting.size(); ++s) row[spec_.setting_names[s]] = setting[s];
    row.update({{"median_rms_online_m", Median(v["rms_online_m"])},
                {"median_rms_final_m", Median(v["rms_final_m"])},
                {"mean_rms_x_m", mean(v["rms_x_m"])},
                {"mean_rms_y_m", mean(v["rms_y_m"])},
                {"mean_rms_heading_deg", mean(v["rms_heading_rad"]) * 180.0 / M_PI},
                {"median_map_rms_m", Median(v["map_rms_m"])},
                {"mean_map_rms_x_m", mean(v["map_rms_x_m"])},
                {"mean_map_rms_y_m", mean(v["map_rms_y_m"])},
                {"successes", static_cast<int>(Sum(v["success"]))},
                {"median_local_maps", Median(v["local_maps"])},
                {"anees_times", times},
                {"anees_inside_band", times > 0 ? static_cast<double>(inside) / times : 0.0},
                {"mean_ci_below_one", times > 0 ? static_cast<double>(ci_below_one) / times : 0.0},
                {"max_mean_ci", max_ci},
                {"paper", spec_.paper_finding ? spec_.paper_finding(method, setting) : ""},
                {"curve",
                 {{"t_s", t_s},
                  {"anees", anees},
                  {"band_low", low},
                  {"band_high", high},
                  {"mean_ci", mean_ci},
                  {"rms_position_m", rms},
                  {"runs", counted}}}});
    return row;
  }

  MonteCarloSpec spec_;
};

}  // namespace

std::unique_ptr<Study> MakeMonteCarloStudy(MonteCarloSpec spec) {
  return std::make_unique<MonteCarloStudy>(std::move(spec));
}

}  // namespace subslam::study
