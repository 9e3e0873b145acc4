// subslam — the command-line tool: one command per job (docs/cli.md, `subslam help`).
//
//   subslam simulate | run | join | solve | study | study merge | plot | scenarios [flags]
//   subslam help [COMMAND]      subslam COMMAND --help | -h      subslam --version
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "cli_reference.h"
#include "command_flags.h"
#include "invocation.h"
#include "keep_freed_memory_flag.h"
#include "subslam/pipeline/build_info.h"
#include "subslam/sim/simulator.h"
#include "tool_commands.h"
#include "tool_flags.h"

namespace {

bool IsHelp(std::string_view arg) {
  return arg == "-h" || arg == "--help" || arg == "-help" || arg == "--helpfull" || arg == "--helpshort";
}

// The command named by the arguments before any flag: "study merge" is one command.
std::string CommandOf(int argc, char** argv, int first) {
  if (first >= argc) return "";
  std::string command = argv[first];
  if (command == "study" && first + 1 < argc && std::string_view(argv[first + 1]) == "merge") command = "study merge";
  return command;
}

// `subslam help [COMMAND]`, `subslam COMMAND --help`: prints the help and returns 0, or
// names an unknown command and returns 2.
int Help(const std::string& command) {
  if (command.empty()) {
    std::printf("%s", subslam::pipeline::GeneralHelp().c_str());
    return 0;
  }
  const std::string help = subslam::pipeline::CommandHelp(command);
  if (help.empty()) {
    std::fprintf(stderr, "subslam: unknown command \"%s\"\n%s", command.c_str(),
                 subslam::pipeline::GeneralHelp().c_str());
    return 2;
  }
  std::printf("%s", help.c_str());
  return 0;
}

// Help and version are answered before Abseil parses the flags (its own --help exits
// with status 1 and lists the flags by source file). Returns -1 when neither was asked.
int HelpOrVersion(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "%s", subslam::pipeline::GeneralHelp().c_str());
    return 2;
  }
  const std::string_view first = argv[1];
  if (first == "--version" || first == "version") {
    std::printf("subslam %s (commit %s, %s build)\n", subslam::pipeline::Version(), subslam::pipeline::Commit(),
                subslam::pipeline::BuildType());
    return 0;
  }
  if (first == "help" || IsHelp(first)) return Help(CommandOf(argc, argv, 2));
  for (int i = 2; i < argc; ++i) {
    if (IsHelp(argv[i])) return Help(CommandOf(argc, argv, 1));
  }
  return -1;
}

// The positional arguments a command takes: none but its name, except study and plot.
int CheckNoArguments(const std::vector<char*>& args) {
  if (args.size() <= 2) return 0;
  std::vector<std::string> extra(args.begin() + 2, args.end());
  return subslam::tool::Fail(absl::StrCat("unexpected argument", extra.size() > 1 ? "s" : "", " \"",
                                          absl::StrJoin(extra, "\", \""), "\" after `", args[1],
                                          "` (it takes flags only; `subslam help ", args[1], "`)"));
}

// The invocation a report records; with --config, the recorded flags first.
absl::StatusOr<nlohmann::json> Invocation(int argc, char** argv, const std::string& command) {
  if (const std::string config = absl::GetFlag(FLAGS_config); !config.empty()) {
    if (absl::Status s = subslam::cli::ApplyRecordedFlags(config, command); !s.ok()) return s;
  }
  return subslam::cli::InvocationJson(argc, argv, command);
}

}  // namespace

int main(int argc, char** argv) {
  if (const int status = HelpOrVersion(argc, argv); status >= 0) return status;
  absl::SetProgramUsageMessage(subslam::pipeline::CliUsage());
  subslam::cli::NoteFlagsGiven(argc, argv);
  std::vector<char*> args = absl::ParseCommandLine(argc, argv);
  subslam::pipeline::ApplyKeepFreedMemoryFlag();
  const std::string command = args.size() >= 2 ? args[1] : "";
  if (command == "study") return subslam::tool::Study(std::vector<std::string>(args.begin() + 2, args.end()));
  if (command == "plot") {
    return subslam::tool::Plot(std::vector<std::string>(args.begin() + 2, args.end()), !absl::GetFlag(FLAGS_quiet));
  }
  if (command == "simulate" || command == "run" || command == "join" || command == "solve" || command == "calibrate") {
    if (const int status = CheckNoArguments(args); status != 0) return status;
    if (command == "simulate") return subslam::tool::Simulate();
    absl::StatusOr<nlohmann::json> invocation = Invocation(argc, argv, command);
    if (!invocation.ok()) return subslam::tool::Fail(std::string(invocation.status().message()));
    if (command == "run") return subslam::tool::Run(*invocation);
    if (command == "join") return subslam::tool::Join(*invocation);
    if (command == "calibrate") return subslam::tool::Calibrate(*invocation);
    return subslam::tool::Solve(*invocation);
  }
  if (command == "cli-reference" || command == "scenarios") {
    if (const int status = CheckNoArguments(args); status != 0) return status;
    if (command == "cli-reference") {
      std::printf("%s", subslam::pipeline::CliReferenceMarkdown().c_str());
    } else {
      std::printf("%s\n", absl::StrJoin(subslam::sim::ScenarioNames(), "\n").c_str());
    }
    return 0;
  }
  std::fprintf(stderr, "subslam: unknown command \"%s\"\n%s", command.c_str(),
               subslam::pipeline::GeneralHelp().c_str());
  return 2;
}
