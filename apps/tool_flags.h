// The flags of the `subslam` tool itself (input, output, simulation, graphs, studies);
// the front-end and back-end flags are cli/frontend_flags.h and cli/backend_flags.h.
// Defaults come from the option structs, so the tool and the library agree.
#ifndef SUBSLAM_APPS_TOOL_FLAGS_H_
#define SUBSLAM_APPS_TOOL_FLAGS_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "absl/flags/declare.h"

ABSL_DECLARE_FLAG(std::string, dataset);
ABSL_DECLARE_FLAG(std::string, scenario);
ABSL_DECLARE_FLAG(uint64_t, seed);
ABSL_DECLARE_FLAG(std::optional<uint64_t>, world_seed);
ABSL_DECLARE_FLAG(std::optional<double>, alpha);
ABSL_DECLARE_FLAG(std::optional<double>, beta);
ABSL_DECLARE_FLAG(std::optional<double>, duration);
ABSL_DECLARE_FLAG(std::optional<int>, moving_objects);
ABSL_DECLARE_FLAG(int, fmj_case);
ABSL_DECLARE_FLAG(double, world_size);
ABSL_DECLARE_FLAG(int, landmarks);
ABSL_DECLARE_FLAG(double, path_length);
ABSL_DECLARE_FLAG(double, lattice_spacing);
ABSL_DECLARE_FLAG(double, noise_scale);
ABSL_DECLARE_FLAG(bool, signature);
ABSL_DECLARE_FLAG(std::string, out);
ABSL_DECLARE_FLAG(std::string, calibration);
ABSL_DECLARE_FLAG(std::string, frontend);
ABSL_DECLARE_FLAG(std::string, submaps);
ABSL_DECLARE_FLAG(std::optional<double>, sigma_v);
ABSL_DECLARE_FLAG(std::optional<double>, sigma_u1);
ABSL_DECLARE_FLAG(std::optional<double>, sigma_range);
ABSL_DECLARE_FLAG(std::optional<double>, sigma_bearing);
ABSL_DECLARE_FLAG(std::optional<double>, max_range);
ABSL_DECLARE_FLAG(std::optional<double>, sensor_yaw);
ABSL_DECLARE_FLAG(std::optional<int>, trials);
ABSL_DECLARE_FLAG(std::optional<int>, workers);
ABSL_DECLARE_FLAG(std::vector<std::string>, methods);
ABSL_DECLARE_FLAG(std::string, shard);
ABSL_DECLARE_FLAG(bool, plots);
ABSL_DECLARE_FLAG(std::string, graph);
ABSL_DECLARE_FLAG(std::string, format);
ABSL_DECLARE_FLAG(std::string, noise);
ABSL_DECLARE_FLAG(std::string, initial);
ABSL_DECLARE_FLAG(int, poses_per_map);
ABSL_DECLARE_FLAG(bool, tree_joining);
ABSL_DECLARE_FLAG(int, max_iterations);
ABSL_DECLARE_FLAG(std::string, config);
ABSL_DECLARE_FLAG(bool, write_local_maps);
ABSL_DECLARE_FLAG(bool, progress);
ABSL_DECLARE_FLAG(bool, quiet);

#endif  // SUBSLAM_APPS_TOOL_FLAGS_H_
