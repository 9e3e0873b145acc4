// The front-end flags of subslam's executables (--association, --gate, --existence_*,
// the particle filter's, --seif_* / --iseif_*, --submap_*) and their one binding to the
// options of pipeline::RunOptions, shared by the tool and the benchmarks. Defaults come
// from the option structs.
#ifndef SUBSLAM_CLI_FRONTEND_FLAGS_H_
#define SUBSLAM_CLI_FRONTEND_FLAGS_H_

#include "absl/status/status.h"
#include "subslam/pipeline/run_pipeline.h"

namespace subslam::cli {

// Sets options->ekf, fastslam, seif, policy and inputs from the flags (not the front-end kind,
// the back-end or the noise overrides); errors for names no enum table knows.
absl::Status SetFrontendOptionsFromFlags(pipeline::RunOptions* options);

}  // namespace subslam::cli

#endif  // SUBSLAM_CLI_FRONTEND_FLAGS_H_
