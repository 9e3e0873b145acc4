#include "study_method.h"

#include "absl/strings/str_cat.h"

namespace subslam::study {

absl::StatusOr<pipeline::RunResult> RunMethod(const StudyMethod& method, io::Dataset dataset) {
  pipeline::RunOptions options;
  options.fastslam.num_threads = 1;
  options.backend.background = false;
  method.configure(&options);
  absl::StatusOr<pipeline::RunResult> r = pipeline::RunPipeline(std::move(dataset), options);
  if (r.ok() && r->stop) {  // a study's figures need the whole run
    return absl::InternalError(absl::StrCat("the run stopped at step ", r->stop->step, ": ", r->stop->reason));
  }
  return r;
}

absl::StatusOr<pipeline::RunResult> RunMethodWithTruth(const StudyMethod& method, io::Dataset dataset) {
  absl::StatusOr<pipeline::RunResult> r = RunMethod(method, std::move(dataset));
  if (r.ok() && (!r->errors || !r->map_errors)) return absl::InternalError("the run has no ground-truth metrics");
  return r;
}

const eval::TrajectoryErrors& OnlineErrors(const pipeline::RunResult& r) {
  return r.errors_online ? *r.errors_online : *r.errors;
}

std::string OneThreadFlags(const StudyMethod& method) {
  pipeline::RunOptions options;
  method.configure(&options);
  using pipeline::Frontend;
  std::string flags;
  if (options.frontend == Frontend::kFastSlam || options.frontend == Frontend::kRbpf) flags += " --threads 1";
  if ((options.frontend == Frontend::kRbpf || options.frontend == Frontend::kEkfLocal) &&
      options.backend.kind != pipeline::Backend::kNone) {
    flags += " --join_in_background=false";
  }
  return flags;
}

const StudyMethod* FindMethod(const std::vector<StudyMethod>& methods, const std::string& name) {
  for (const StudyMethod& m : methods) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

std::vector<std::string> MethodNames(const std::vector<StudyMethod>& methods) {
  std::vector<std::string> names;
  for (const StudyMethod& m : methods) names.push_back(m.name);
  return names;
}

nlohmann::json MethodsJson(const std::vector<StudyMethod>& methods, const std::string& trial_command) {
  nlohmann::json list = nlohmann::json::array();
  for (const StudyMethod& m : methods) {
    list.push_back({{"method", m.name},
                    {"description", m.description},
                    {"command", absl::StrCat(trial_command, " ", m.flags, OneThreadFlags(m))}});
  }
  return list;
}

}  // namespace subslam::study
