// The back-end flags of subslam's executables (--backend, --join_*, --relinearize_*,
// --eif_*, --ceres_*, --ekf_*, --tree_*, --known_association) and their one binding to
// pipeline::BackendOptions, shared by the tool and the benchmarks so that a back-end is
// configured the same way everywhere. Defaults come from the option structs.
#ifndef SUBSLAM_CLI_BACKEND_FLAGS_H_
#define SUBSLAM_CLI_BACKEND_FLAGS_H_

#include "absl/flags/declare.h"
#include "absl/status/statusor.h"
#include "subslam/pipeline/submap_slam.h"

// Also read by the front-ends' binding: the study option of every stage, and the signature
// cue's σ that the RBPF and the back-end's association share.
ABSL_DECLARE_FLAG(bool, known_association);
ABSL_DECLARE_FLAG(double, sigma_signature);
// The back-end's name, which decides which other back-end flags a command reads.
ABSL_DECLARE_FLAG(std::string, backend);

namespace subslam::cli {

// The back-end the flags describe, validated. `sensor_yaw_given`: the run was given the
// sensor's yaw (--sensor_yaw), so the online yaw calibration is off unless asked for.
absl::StatusOr<pipeline::BackendOptions> BackendOptionsFromFlags(bool sensor_yaw_given = false);

}  // namespace subslam::cli

#endif  // SUBSLAM_CLI_BACKEND_FLAGS_H_
