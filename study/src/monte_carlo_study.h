// A Monte Carlo consistency study: methods run on a simulated scenario over trials (and,
// optionally, settings of the scenario) — and, for some, on a real data set — measured by the pose NEES of the online
// estimate averaged over the runs against time with its χ² band, the consistency index, RMS errors of the pose and the
// map, and the joining times. Combined SLAM §7, Fast Map Joining §IV and ISEIF §4 are studies of this shape
// (combined_slam_study.cc, fmj_study.cc, iseif_study.cc).
#ifndef SUBSLAM_STUDY_SRC_MONTE_CARLO_STUDY_H_
#define SUBSLAM_STUDY_SRC_MONTE_CARLO_STUDY_H_

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "study_method.h"
#include "subslam/sim/scenario.h"
#include "subslam/study/study.h"

namespace subslam::study {

struct MonteCarloSpec {
  std::string name;
  std::string title;
  std::string scenario;  // sim::ScenarioNames()
  int paper_trials = 50;
  // Settings: names, and the list of values each setting takes (one vector per setting
  // of the study, in setting_names order); `apply_setting` puts them into the scenario.
  std::vector<std::string> setting_names;
  std::vector<std::vector<double>> settings;
  std::function<void(const std::vector<double>&, sim::ScenarioOptions*)> apply_setting;
  std::vector<StudyMethod> methods;
  double series_period_s = 10.0;  // the online pose sampled this often [s]
  // What the paper reports for a method at a setting (it gives curves more often than
  // tables), in words; and what it reports for the timings.
  std::function<std::string(const std::string& method, const std::vector<double>& setting)> paper_finding;
  std::string paper_timings;
  // Runs on a real data set (given with --dataset), one per method, measured against its
  // GPS (aligned RMS); the paper's figures for them, per method, in words.
  std::string dataset_title;
  std::vector<StudyMethod> dataset_methods;
  std::function<std::string(const std::string& method)> paper_dataset_finding;
};

std::unique_ptr<Study> MakeMonteCarloStudy(MonteCarloSpec spec);

}  // namespace subslam::study

#endif  // SUBSLAM_STUDY_SRC_MONTE_CARLO_STUDY_H_
