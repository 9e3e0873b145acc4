// A paper's experiment as a list of independent runs (docs/reproducing.md).
//
// A study names its methods and settings, expands them into runs (method × setting ×
// trial, each trial with its own seed), measures one run at a time, and summarises the
// per-run table into the paper's table. A run's result depends only on its method,
// setting and seed — never on which process or thread ran it, or in what order — so the
// runs can be spread over cores (StudyRunner) or machines (`--shard K/N`, then
// MergeStudy) and the summary is byte for byte the same.
#ifndef SUBSLAM_STUDY_STUDY_H_
#define SUBSLAM_STUDY_STUDY_H_

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "subslam/study/run_table.h"

namespace subslam::study {

struct StudyRun {
  int index = 0;                                        // position in Study::Runs(), the key of runs.csv
  std::string method;                                   // e.g. "hybrid"
  std::vector<std::pair<std::string, double>> setting;  // in Study::setting_names() order
  int trial = 0;                                        // 1-based
  uint64_t seed = 0;                                    // the scenario seed of this trial (the world and the noise)
  std::string dataset;                                  // a real data set's directory, for runs on one (else empty)
};

// What one run measured: values of Study::metric_names() (deterministic: runs.csv), rows
// of Study::series_names() (values over the run's time, deterministic: series.csv), and
// values of Study::timing_names() and the time of each join (wall-clock seconds:
// timings.csv and join_times.csv, not in the summary).
struct RunMeasurement {
  std::vector<std::string> metrics;
  std::vector<std::vector<std::string>> series;
  std::vector<double> timings;
  std::vector<double> join_seconds;  // wall-clock time of each join, in order (join_times.csv)
};

class Study {
 public:
  virtual ~Study() = default;

  virtual std::string name() const = 0;
  // The paper (by title), its table or section, and what the study measures.
  virtual std::string title() const = 0;
  virtual int paper_trials() const = 0;  // trials per method and setting in the paper
  virtual std::vector<std::string> method_names() const = 0;
  virtual std::vector<std::string> setting_names() const = 0;
  virtual std::vector<std::string> metric_names() const = 0;
  virtual std::vector<std::string> series_names() const { return {}; }
  virtual std::vector<std::string> timing_names() const { return {}; }
  // What the paper reports for the timings, for timings.md (empty: nothing).
  virtual std::string paper_timings() const { return ""; }

  // Whether the study has runs on a real data set (given as `dataset_dir` to Runs()).
  virtual bool uses_dataset() const { return false; }
  // Every run of the study with `trials` trials per method and setting, and, when the
  // study uses one and `dataset_dir` is not empty, its runs on that data set.
  virtual std::vector<StudyRun> Runs(int trials, const std::string& dataset_dir) const = 0;
  virtual absl::StatusOr<RunMeasurement> Execute(const StudyRun& run) const = 0;

  // The exact configuration (config.json): each method's options as the equivalent
  // `subslam run` flags, and how a trial's seed and world are chosen.
  virtual nlohmann::json Configuration() const = 0;

  // The study's table from the per-run table and the series (a table with no columns
  // when the study has none): summary.json (a list "rows", one object per method and
  // setting) and its Markdown rendering (summary.md).
  virtual absl::StatusOr<nlohmann::json> Summarize(const RunTable& runs, const RunTable& series) const = 0;
  virtual std::string SummaryMarkdown(const nlohmann::json& summary) const = 0;
};

// The studies by name: hybridslam, … (StudyNames()).
std::vector<std::string> StudyNames();
absl::StatusOr<std::unique_ptr<Study>> MakeStudy(const std::string& name);

}  // namespace subslam::study

#endif  // SUBSLAM_STUDY_STUDY_H_
