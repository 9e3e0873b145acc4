// A command's output directory is its own. Preparing it for a command:
//   - a directory that does not exist is created (with its parents), an empty one is taken;
//   - a non-empty directory is taken only when it holds the marker file `.subslam` that an
//     earlier command of the tool wrote there (or, from versions before the marker, a
//     subslam report.json or study config.json); the earlier outputs are then removed first:
//     every file whose name ends in one of OutputExtensions(), and the `plots/`
//     subdirectory. Other files (a user's notes, say) are left where they are;
//   - a non-empty directory without the marker is refused, and nothing in it is touched.
// So a second run into the same --out never leaves the first run's files beside its own
// (a stale joins.csv that `subslam plot` would draw next to the new report).
#ifndef SUBSLAM_IO_OUTPUT_DIRECTORY_H_
#define SUBSLAM_IO_OUTPUT_DIRECTORY_H_

#include <filesystem>
#include <span>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"

namespace subslam::io {

// The name of the marker file a command writes into its output directory.
inline constexpr std::string_view kOutputMarker = ".subslam";

// The extensions of the files the tool writes (".csv", ".json", …).
std::span<const std::string_view> OutputExtensions();

// Prepares `dir` for the outputs of `command` ("run", "join", …) as described above and
// writes the marker (naming the command). Errors: a non-empty directory without the
// marker, a path that is not a directory, a file that cannot be created or removed.
absl::StatusOr<std::filesystem::path> PrepareOutputDirectory(const std::string& dir, std::string_view command);

}  // namespace subslam::io

#endif  // SUBSLAM_IO_OUTPUT_DIRECTORY_H_
