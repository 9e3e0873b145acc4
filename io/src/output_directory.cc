#include "subslam/io/output_directory.h"

#include <algorithm>
#include <array>
#include <fstream>
#include <nlohmann/json.hpp>
#include <system_error>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace subslam::io {
namespace {

constexpr std::array<std::string_view, 10> kExtensions = {".csv", ".dat", ".json", ".jsonl", ".md",
                                                          ".tum", ".g2o", ".isam", ".toro",  ".graph"};

std::string Str(std::string_view text) { return std::string(text); }

// An output directory that a version of the tool before the marker wrote: its report.json
// (a run's or join's "format": "subslam-…", a solve's "job") or a study's config.json.
bool HoldsEarlierReport(const std::filesystem::path& dir) {
  const auto parse = [](const std::filesystem::path& path) {
    std::ifstream in(path);
    return in ? nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false) : nlohmann::json();
  };
  const nlohmann::json report = parse(dir / "report.json");
  if (report.is_object() && (report.value("format", "").starts_with("subslam-") || report.contains("job"))) {
    return true;
  }
  const nlohmann::json config = parse(dir / "config.json");
  return config.is_object() && config.contains("study") && config.contains("runs");
}

bool IsOutput(const std::filesystem::directory_entry& entry) {
  if (entry.is_directory()) return entry.path().filename() == "plots";
  const std::string extension = entry.path().extension().string();
  return std::find(kExtensions.begin(), kExtensions.end(), extension) != kExtensions.end();
}

}  // namespace

std::span<const std::string_view> OutputExtensions() { return kExtensions; }

absl::StatusOr<std::filesystem::path> PrepareOutputDirectory(const std::string& dir, std::string_view command) {
  const std::filesystem::path path(dir);
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_directory(path, ec)) {
    return absl::InvalidArgumentError(absl::StrCat(dir, ": the output path exists and is not a directory"));
  }
  std::filesystem::create_directories(path, ec);
  if (ec) return absl::PermissionDeniedError(absl::StrCat(dir, ": cannot create the output directory: ", ec.message()));
  const std::filesystem::path marker = path / kOutputMarker;
  std::vector<std::filesystem::directory_entry> entries;
  for (const auto& entry : std::filesystem::directory_iterator(path, ec)) entries.push_back(entry);
  if (ec) return absl::PermissionDeniedError(absl::StrCat(dir, ": cannot list the output directory: ", ec.message()));
  const bool ours = std::filesystem::exists(marker, ec) || HoldsEarlierReport(path);
  if (!entries.empty() && !ours) {
    return absl::FailedPreconditionError(
        absl::StrCat(dir, ": the output directory is not empty and is not an output directory of subslam (it has no ",
                     Str(kOutputMarker), " file); choose another --out or empty it"));
  }
  for (const auto& entry : entries) {
    if (!IsOutput(entry)) continue;
    std::filesystem::remove_all(entry.path(), ec);
    if (ec) {
      return absl::PermissionDeniedError(
          absl::StrCat(entry.path().string(), ": cannot remove an earlier output: ", ec.message()));
    }
  }
  std::ofstream out(marker, std::ios::trunc);
  out << "subslam " << command << "\n";
  if (!out) return absl::PermissionDeniedError(absl::StrCat(marker.string(), ": cannot write"));
  return path;
}

}  // namespace subslam::io
