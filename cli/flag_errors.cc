#include "flag_errors.h"

#include <string>
#include <utility>
#include <vector>

#include "absl/flags/commandlineflag.h"
#include "absl/flags/reflection.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "command_flags.h"

namespace subslam::cli {
namespace {

// Sets `flag` to `value`, which it held before, so it parses.
void Set(absl::CommandLineFlag* flag, const std::string& value) {
  std::string error;
  flag->ParseFrom(value, &error);
}

}  // namespace

absl::Status CheckNamingFlags(const std::function<absl::Status()>& check) {
  const absl::Status all = check();
  if (all.ok()) return all;
  // The flags away from their defaults, and their values.
  std::vector<std::pair<absl::CommandLineFlag*, std::string>> changed;
  for (const std::string& name : ProgramFlagNames()) {
    absl::CommandLineFlag* flag = absl::FindCommandLineFlag(name);
    if (flag->CurrentValue() != flag->DefaultValue()) changed.emplace_back(flag, flag->CurrentValue());
  }
  for (auto& [flag, value] : changed) Set(flag, flag->DefaultValue());
  std::vector<std::string> culprits;
  for (auto& [flag, value] : changed) {
    Set(flag, value);
    if (absl::Status alone = check(); !alone.ok()) {
      culprits.push_back(absl::StrCat("--", flag->Name(), "=", value, ": ", alone.message()));
    }
    Set(flag, flag->DefaultValue());
  }
  for (auto& [flag, value] : changed) Set(flag, value);
  if (!culprits.empty()) return absl::InvalidArgumentError(absl::StrJoin(culprits, "; "));
  std::vector<std::string> given;
  for (auto& [flag, value] : changed) given.push_back(absl::StrCat("--", flag->Name(), "=", value));
  if (given.empty()) return all;
  return absl::InvalidArgumentError(absl::StrCat(absl::StrJoin(given, ", "), " together: ", all.message()));
}

}  // namespace subslam::cli
