// How the tool was invoked, recorded in each report.json ("invocation") so that a result can
// be repeated: the command, the command line, and the value of every program flag (not only
// those given, so that a later change of a default does not change the repeat).
// `subslam run --config DIR/report.json` (also join, solve) sets every flag from the record
// that the command line does not set itself, and so repeats the run to the same outputs.
#ifndef SUBSLAM_CLI_INVOCATION_H_
#define SUBSLAM_CLI_INVOCATION_H_

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "absl/status/status.h"

namespace subslam::cli {

// {"command": COMMAND, "command_line": [argv...], "flags": {name: value, ...}} with every
// program flag (Abseil's own left out) at its current value, as Abseil prints it.
nlohmann::json InvocationJson(int argc, char** argv, std::string_view command);

// Sets each flag recorded in the report's "invocation" that was not given on the command
// line, except those that only say where and how to write (--out, --progress, --quiet,
// --config). Errors (naming the file and the field): the file cannot be read or is not
// JSON, it records another command, a recorded flag is unknown to this build or its value
// does not parse.
absl::Status ApplyRecordedFlags(const std::string& report_path, std::string_view command);

}  // namespace subslam::cli

#endif  // SUBSLAM_CLI_INVOCATION_H_
