// Flags a command does not read. A flag given to a command that ignores it would leave
// the user believing it took effect (a study's methods carry their papers' settings, so
// `subslam study … --join_merge=false` changes nothing): the tool refuses it instead.
#ifndef SUBSLAM_CLI_FLAGS_READ_BY_COMMAND_H_
#define SUBSLAM_CLI_FLAGS_READ_BY_COMMAND_H_

#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"

namespace subslam::cli {

// The program's own flags (Abseil's --help, --flagfile, … left out) set to a value other
// than their default (on the command line, or by --flagfile) whose names are not in
// `read`, as "--name", sorted.
std::vector<std::string> FlagsGivenButNotRead(const std::vector<std::string_view>& read);

// OK, or InvalidArgument naming each flag so set that `command` does not read, and `why`
// (what the command takes its settings from instead).
absl::Status CheckOnlyFlagsReadBy(std::string_view command, const std::vector<std::string_view>& read,
                                  std::string_view why);

}  // namespace subslam::cli

#endif  // SUBSLAM_CLI_FLAGS_READ_BY_COMMAND_H_
