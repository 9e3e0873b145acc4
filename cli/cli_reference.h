// The command-line tool's commands and its reference page. docs/cli.md is the output of
// `subslam cli-reference`, generated from the program's own command table and flag
// registry (names, defaults, help texts), and a test checks that the two agree.
#ifndef SUBSLAM_CLI_CLI_REFERENCE_H_
#define SUBSLAM_CLI_CLI_REFERENCE_H_

#include <span>
#include <string>
#include <string_view>

namespace subslam::pipeline {

struct CliCommand {
  std::string_view name;
  std::string_view synopsis;     // one line, flags in the tool's notation
  std::string_view description;  // what it does and what it writes, one paragraph
};

// The commands of `subslam`, in the order the usage message lists them.
std::span<const CliCommand> CliCommands();

// The usage message: one synopsis line per command.
std::string CliUsage();

// `subslam help COMMAND`: the command's usage, what it does, and the flags it may read,
// grouped, each with its default and help text ("" for an unknown command).
std::string CommandHelp(std::string_view command);

// `subslam help`: every command's synopsis.
std::string GeneralHelp();

// The reference page in Markdown: every command, then every flag of the program (those
// defined outside Abseil), grouped by topic, each with its default and help text.
std::string CliReferenceMarkdown();

}  // namespace subslam::pipeline

#endif  // SUBSLAM_CLI_CLI_REFERENCE_H_
