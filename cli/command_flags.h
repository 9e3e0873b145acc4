// Which flags each command of the tool reads, and under which choices of front-end,
// back-end and input: the one table behind each command's help and behind refusing a flag
// that a command would ignore (`run --frontend ekfslam --particles 5000` runs EKF-SLAM, so
// the tool says so instead of running it).
#ifndef SUBSLAM_CLI_COMMAND_FLAGS_H_
#define SUBSLAM_CLI_COMMAND_FLAGS_H_

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/pipeline/submap_slam.h"

namespace subslam::cli {

// What a command was asked to do, as far as it decides which flags it reads.
struct CommandContext {
  std::string command;  // "simulate", "run", "join", "solve", "study", "study merge", "plot", "scenarios"
  std::optional<pipeline::Frontend> frontend;  // run
  // run with a local-map front-end (rbpf, ekf), and join: how local maps are joined.
  std::optional<pipeline::Backend> backend;
  bool scenario = false;  // the input is a simulated scenario (simulate; run or join with --scenario)
};

// Whether `command` reads the flag `name` in `context`.
bool FlagIsRead(std::string_view name, const CommandContext& context);

// Whether some invocation of `command` reads the flag (whatever its front-end, back-end
// or input): the flags its help lists.
bool CommandMayReadFlag(std::string_view name, std::string_view command);

// Who reads the flag, for an error message: "run with --frontend fastslam or rbpf".
std::string FlagReaders(std::string_view name);

// OK, or InvalidArgument naming every program flag given a value other than its default
// that the context does not read, and who would read it.
absl::Status CheckFlagsRead(const CommandContext& context);

// Notes which flags the command line names (--name, --name=value, --noname), so that a
// flag given at its default value still counts as given. Call before parsing; each call
// replaces what the last one noted.
void NoteFlagsGiven(int argc, char** argv);

// Whether the command line noted by NoteFlagsGiven names the flag.
bool FlagGiven(std::string_view name);

// The program's own flags (Abseil's --help, --flagfile, … left out), by name.
std::vector<std::string> ProgramFlagNames();

}  // namespace subslam::cli

#endif  // SUBSLAM_CLI_COMMAND_FLAGS_H_
