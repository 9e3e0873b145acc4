// A method of a study: a named configuration of `subslam run`, kept in two forms that a
// test holds equal — the options it sets and the equivalent command-line flags that
// config.json records for a reader to rerun.
#ifndef SUBSLAM_STUDY_SRC_STUDY_METHOD_H_
#define SUBSLAM_STUDY_SRC_STUDY_METHOD_H_

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "subslam/io/dataset.h"
#include "subslam/pipeline/run_pipeline.h"

namespace subslam::study {

struct StudyMethod {
  std::string name;
  std::string description;
  std::string flags;  // `subslam run` flags beyond the trial's scenario flags
  std::function<void(pipeline::RunOptions*)> configure;
};

// Every study run uses one thread and joins in the foreground (the online pose holds each
// join as soon as its map closes); the flags that say so for `method` (the tool refuses a
// flag its front-end and back-end do not read): --threads 1 for the particle filters,
// --join_in_background=false for local maps joined by a back-end.
std::string OneThreadFlags(const StudyMethod& method);

// Runs `method` on `dataset` with one thread and foreground joins.
absl::StatusOr<pipeline::RunResult> RunMethod(const StudyMethod& method, io::Dataset dataset);
// The same on a simulated data set: an error if the run has no trajectory and map metrics.
absl::StatusOr<pipeline::RunResult> RunMethodWithTruth(const StudyMethod& method, io::Dataset dataset);

// The errors of the online estimate: what a filter reports at each step (for the
// single-map filters the final trajectory is the online one).
const eval::TrajectoryErrors& OnlineErrors(const pipeline::RunResult& r);

const StudyMethod* FindMethod(const std::vector<StudyMethod>& methods, const std::string& name);
std::vector<std::string> MethodNames(const std::vector<StudyMethod>& methods);

// config.json's "methods": name, description and `command` = `trial_command` + flags +
// OneThreadFlags.
nlohmann::json MethodsJson(const std::vector<StudyMethod>& methods, const std::string& trial_command);

}  // namespace subslam::study

#endif  // SUBSLAM_STUDY_SRC_STUDY_METHOD_H_
