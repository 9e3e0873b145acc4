#include "invocation.h"

#include <fstream>

#include "absl/flags/commandlineflag.h"
#include "absl/flags/reflection.h"
#include "absl/strings/str_cat.h"
#include "command_flags.h"

namespace subslam::cli {
namespace {

constexpr std::string_view kNotReplayed[] = {"out", "progress", "quiet", "config"};

bool Replayed(std::string_view name) {
  for (std::string_view n : kNotReplayed) {
    if (n == name) return false;
  }
  return true;
}

}  // namespace

nlohmann::json InvocationJson(int argc, char** argv, std::string_view command) {
  nlohmann::json line = nlohmann::json::array();
  for (int i = 0; i < argc; ++i) line.push_back(argv[i]);
  nlohmann::json flags = nlohmann::json::object();
  for (const std::string& name : ProgramFlagNames()) flags[name] = absl::FindCommandLineFlag(name)->CurrentValue();
  return {{"command", std::string(command)}, {"command_line", line}, {"flags", flags}};
}

absl::Status ApplyRecordedFlags(const std::string& report_path, std::string_view command) {
  std::ifstream in(report_path);
  if (!in) return absl::NotFoundError(absl::StrCat(report_path, ": cannot open (--config)"));
  nlohmann::json report = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (report.is_discarded()) return absl::InvalidArgumentError(absl::StrCat(report_path, ": not JSON (--config)"));
  if (!report.contains("invocation") || !report["invocation"].is_object() || !report["invocation"].contains("flags") ||
      !report["invocation"]["flags"].is_object()) {
    return absl::InvalidArgumentError(
        absl::StrCat(report_path,
                     ": field invocation.flags: missing (a report.json written by subslam run, join "
                     "or solve records how it was invoked)"));
  }
  const nlohmann::json& invocation = report["invocation"];
  const std::string recorded = invocation.value("command", "");
  if (recorded != command) {
    return absl::InvalidArgumentError(absl::StrCat(report_path, ": field invocation.command: \"", recorded,
                                                   "\", so --config cannot repeat it with `subslam ",
                                                   std::string(command), "`"));
  }
  for (const auto& [name, value] : invocation["flags"].items()) {
    if (!Replayed(name)) continue;
    absl::CommandLineFlag* flag = absl::FindCommandLineFlag(name);
    if (flag == nullptr) {
      return absl::InvalidArgumentError(
          absl::StrCat(report_path, ": field invocation.flags.", name, ": this build has no flag --", name));
    }
    if (FlagGiven(name)) continue;  // the command line wins
    if (!value.is_string()) {
      return absl::InvalidArgumentError(absl::StrCat(report_path, ": field invocation.flags.", name, ": not a string"));
    }
    std::string error;
    if (!flag->ParseFrom(value.get<std::string>(), &error)) {
      return absl::InvalidArgumentError(absl::StrCat(report_path, ": field invocation.flags.", name, ": ", error));
    }
  }
  return absl::OkStatus();
}

}  // namespace subslam::cli
