// The commands of the `subslam` tool, each reading its flags (apps/tool_flags.h,
// cli/frontend_flags.h, cli/backend_flags.h) after Abseil parsed them. Each returns the
// process's exit status: 0 done, 1 failed (the message is on stderr).
#ifndef SUBSLAM_APPS_TOOL_COMMANDS_H_
#define SUBSLAM_APPS_TOOL_COMMANDS_H_

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "absl/status/status.h"

namespace subslam::tool {

int Simulate();
int Run(const nlohmann::json& invocation);
int Join(const nlohmann::json& invocation);
// subslam calibrate: a robot's odometry and sensor from its own data (calibration.json).
int Calibrate(const nlohmann::json& invocation);
int Solve(const nlohmann::json& invocation);
// `args`: the positional arguments after "study" (the study's name, or "merge" DIR...).
int Study(const std::vector<std::string>& args);
// `list_files`: let the script list the figures it wrote.
int Plot(const std::vector<std::string>& dirs, bool list_files = false);

// Prints "subslam: error: MESSAGE" and returns 1.
int Fail(const std::string& message);
int Fail(const absl::Status& status);

}  // namespace subslam::tool

#endif  // SUBSLAM_APPS_TOOL_COMMANDS_H_
