// report.json of `subslam run` (docs/formats.md, "Run outputs"): what RunPipeline ran and
// what it measured, kept apart from the running.
#ifndef SUBSLAM_PIPELINE_SRC_RUN_REPORT_H_
#define SUBSLAM_PIPELINE_SRC_RUN_REPORT_H_

#include <nlohmann/json.hpp>

#include "subslam/frontend/online_estimator.h"
#include "subslam/frontend/seif_slam.h"
#include "subslam/io/dataset.h"
#include "subslam/pipeline/run_pipeline.h"

namespace subslam::pipeline {

// The SEIF options the run uses (ISEIF: the iterated update on), after every option
// struct was validated; and whether any stage associates by the true ids.
struct CheckedOptions {
  frontend::SeifOptions seif;
  bool known_association = false;
};

// The report: configuration (as `checked` says the run used it), counts, the
// estimator's counters and stage times, memory, `health`, `metrics`, the build and the
// invocation.
nlohmann::json RunReport(const io::Dataset& dataset, const RunOptions& options, const CheckedOptions& checked,
                         const frontend::OnlineEstimator& estimator, const RunResult& r, nlohmann::json metrics);

}  // namespace subslam::pipeline

#endif  // SUBSLAM_PIPELINE_SRC_RUN_REPORT_H_
