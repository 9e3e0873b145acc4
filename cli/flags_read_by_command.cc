#include "flags_read_by_command.h"

#include <algorithm>

#include "absl/flags/commandlineflag.h"
#include "absl/flags/reflection.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace subslam::cli {

std::vector<std::string> FlagsGivenButNotRead(const std::vector<std::string_view>& read) {
  std::vector<std::string> unread;
  for (const auto& [name, flag] : absl::GetAllFlags()) {
    if (flag->IsRetired() || flag->Filename().find("absl/") != std::string::npos) continue;
    if (flag->CurrentValue() == flag->DefaultValue()) continue;
    if (std::find(read.begin(), read.end(), std::string_view(name.data(), name.size())) != read.end()) continue;
    unread.push_back(absl::StrCat("--", name));
  }
  std::sort(unread.begin(), unread.end());
  return unread;
}

absl::Status CheckOnlyFlagsReadBy(std::string_view command, const std::vector<std::string_view>& read,
                                  std::string_view why) {
  const std::vector<std::string> unread = FlagsGivenButNotRead(read);
  if (unread.empty()) return absl::OkStatus();
  std::vector<std::string> names;
  for (std::string_view name : read) names.push_back(absl::StrCat("--", absl::string_view(name.data(), name.size())));
  return absl::InvalidArgumentError(absl::StrCat(absl::string_view(command.data(), command.size()), " does not read ",
                                                 absl::StrJoin(unread, ", "), " (",
                                                 absl::string_view(why.data(), why.size()), "); it reads ",
                                                 absl::StrJoin(names, ", ")));
}

}  // namespace subslam::cli
