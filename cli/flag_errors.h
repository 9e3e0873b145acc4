// Option errors that name the flag and the value at fault. The library's option structs
// validate themselves (FastSlamOptions::Validate, …) and name their own fields; the tool
// reads many flags into them, so a failed check is traced back to the flags that cause it.
#ifndef SUBSLAM_CLI_FLAG_ERRORS_H_
#define SUBSLAM_CLI_FLAG_ERRORS_H_

#include <functional>

#include "absl/status/status.h"

namespace subslam::cli {

// Runs `check` (it reads the flags and validates what they configure). When it fails,
// each program flag not at its default is tried alone (every other flag at its default):
// the error names the flags that fail alone, "--particles=-5: num_particles must be >= 1";
// when none does, the combination is named: "--a=1, --b=2 together: <message>". The flags
// keep their values.
absl::Status CheckNamingFlags(const std::function<absl::Status()>& check);

}  // namespace subslam::cli

#endif  // SUBSLAM_CLI_FLAG_ERRORS_H_
