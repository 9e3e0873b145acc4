// `subslam study`, `study merge` and `plot`.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "command_flags.h"
#include "subslam/io/output_directory.h"
#include "subslam/study/study.h"
#include "subslam/study/study_runner.h"
#include "tool_commands.h"
#include "tool_flags.h"
#include "tool_jobs.h"

namespace subslam::tool {
namespace {

// scripts/plot.py: SUBSLAM_PLOT_SCRIPT if set; else beside an installed tool
// (<prefix>/share/subslam/plot.py); else the source tree's.
std::string PlotScript() {
  if (const char* path = std::getenv("SUBSLAM_PLOT_SCRIPT"); path != nullptr && *path != '\0') return path;
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::filesystem::path installed = exe.parent_path().parent_path() / "share" / "subslam" / "plot.py";
    if (std::filesystem::exists(installed)) return installed.string();
  }
  return SUBSLAM_SOURCE_PLOT_SCRIPT;
}

std::string ShellQuoted(const std::string& text) {
  std::string quoted = "'";
  for (char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

// Prints a study's summary.md.
void PrintSummary(const std::string& out) {
  std::FILE* f = std::fopen((out + "/summary.md").c_str(), "r");
  for (int c; f != nullptr && (c = std::fgetc(f)) != EOF;) std::putchar(c);
  if (f != nullptr) std::fclose(f);
}

int Merge(const std::vector<std::string>& dirs, const std::string& out) {
  if (absl::Status s = cli::CheckFlagsRead({.command = "study merge"}); !s.ok()) return Fail(s);
  if (dirs.empty()) return Fail("study merge needs the slices' directories");
  if (auto dir = io::PrepareOutputDirectory(out, "study merge"); !dir.ok()) return Fail(dir.status());
  if (absl::Status s = study::MergeStudy(dirs, out); !s.ok()) return Fail(s);
  if (!absl::GetFlag(FLAGS_quiet)) std::printf("merged %zu slices -> %s/summary.md\n", dirs.size(), out.c_str());
  return absl::GetFlag(FLAGS_plots) ? Plot({out}) : 0;
}

}  // namespace

int Study(const std::vector<std::string>& args) {
  if (args.empty()) {
    return Fail(absl::StrCat("study needs a name (", absl::StrJoin(study::StudyNames(), ", "), ") or merge DIR..."));
  }
  const std::string out = absl::GetFlag(FLAGS_out);
  if (args[0] == "merge") return Merge(std::vector<std::string>(args.begin() + 1, args.end()), out);
  if (args.size() != 1) {
    return Fail(absl::StrCat("study takes one study name; unexpected argument \"", args[1], "\""));
  }
  absl::StatusOr<StudyRequest> request = StudyRequestFromFlags(args[0]);
  if (!request.ok()) return Fail(request.status());
  const study::StudyOptions& options = request->options;
  if (auto dir = io::PrepareOutputDirectory(out, "study"); !dir.ok()) return Fail(dir.status());
  if (absl::Status s = study::RunStudy(*request->study, options); !s.ok()) return Fail(s);
  const bool whole = options.shard.count == 1;
  if (!absl::GetFlag(FLAGS_quiet)) {
    if (whole) {
      PrintSummary(out);
      std::printf("\noutputs: %s/{summary.md,summary.json,runs.csv,timings.csv,config.json}%s\n", out.c_str(),
                  absl::GetFlag(FLAGS_plots) ? ", plots/" : "");
    } else {
      std::printf("slice %d/%d -> %s/runs.csv; combine the slices with `subslam study merge DIR... --out DIR`\n",
                  options.shard.index, options.shard.count, out.c_str());
    }
  }
  return whole && absl::GetFlag(FLAGS_plots) ? Plot({out}) : 0;
}

// `subslam plot DIR...`: the figures of run, join, solve and study directories
// (scripts/plot.py, run once for all of them by Debian's Python with python3-matplotlib).
int Plot(const std::vector<std::string>& dirs, bool list_files) {
  if (dirs.empty()) return Fail("plot needs the output directories to draw");
  const std::string script = PlotScript();
  if (!std::filesystem::exists(script)) {
    return Fail(absl::StrCat("the plot script ", script, " is missing (set SUBSLAM_PLOT_SCRIPT)"));
  }
  std::string command = absl::StrCat("/usr/bin/python3 ", ShellQuoted(script));
  for (const std::string& dir : dirs) absl::StrAppend(&command, " ", ShellQuoted(dir));
  if (!list_files) absl::StrAppend(&command, " > /dev/null");
  std::fflush(stdout);
  if (std::system(command.c_str()) != 0) {
    return Fail(absl::StrCat("plotting with ", script,
                             " failed (its message is above; it runs /usr/bin/python3 with python3-matplotlib)"));
  }
  return 0;
}

}  // namespace subslam::tool
