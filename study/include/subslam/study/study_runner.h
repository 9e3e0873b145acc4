// Runs a study's runs on every core, or one slice of them, and writes the study outputs
// (docs/formats.md, "Study outputs") to a directory:
//   config.json   the study, its trial count, the slice, and Study::Configuration();
//   runs.csv      one row per run: run, method, the setting, trial, seed, the metrics;
//   series.csv    (studies with series) run and the series columns, rows in time order;
//   timings.csv   run, wall_s and the study's timing columns (wall clock: differs from
//                 run to run, so kept out of runs.csv and the summary);
//   timings.md    median and minimum of each timing per method, and the paper's figures;
//   join_times.csv  (runs that join local maps) run, join (0-based), seconds;
//   summary.json, summary.md   the study's table — written when every run is present
//                 (one slice of 1, or after MergeStudy).
// The summary is computed from runs.csv as read back from the file, so the same runs
// give the same bytes whatever the number of workers or slices.
#ifndef SUBSLAM_STUDY_STUDY_RUNNER_H_
#define SUBSLAM_STUDY_STUDY_RUNNER_H_

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "subslam/study/study.h"

namespace subslam::study {

// `--shard K/N`: the runs whose index i has i mod N = K − 1 (1 ≤ K ≤ N).
struct Shard {
  int index = 1;  // K
  int count = 1;  // N
};
absl::StatusOr<Shard> ShardFromString(const std::string& text);  // "K/N"

struct StudyOptions {
  int trials = 0;   // per method and setting; 0: the paper's (Study::paper_trials())
  int workers = 0;  // runs at a time, each on one thread; 0: every core
  Shard shard;
  std::vector<std::string> methods;  // only these of Study::method_names(); empty: all
  std::string dataset_dir;           // the real data set of a study that uses one (iseif: Victoria Park)
  std::string out_dir;               // required
  bool progress = false;             // a progress line on stderr (when it is a terminal)
};

// Runs the study's slice. On a failed run, the rows measured so far are still written
// and the error names the run.
absl::Status RunStudy(const Study& study, const StudyOptions& options);

// Combines the slices written by RunStudy with `--shard K/N` (K = 1..N, each once; the
// same study, trials, methods and configuration) into `out_dir`, with the summary.
absl::Status MergeStudy(const std::vector<std::string>& shard_dirs, const std::string& out_dir);

}  // namespace subslam::study

#endif  // SUBSLAM_STUDY_STUDY_RUNNER_H_
