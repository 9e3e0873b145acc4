#include "command_flags.h"

#include <algorithm>
#include <array>
#include <initializer_list>
#include <set>

#include "absl/flags/commandlineflag.h"
#include "absl/flags/reflection.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace subslam::cli {
namespace {

using pipeline::Backend;
using pipeline::Frontend;

enum Command : unsigned {
  kSimulate = 1u << 0,
  kRun = 1u << 1,
  kJoin = 1u << 2,
  kSolve = 1u << 3,
  kStudy = 1u << 4,
  kStudyMerge = 1u << 5,
  kPlot = 1u << 6,
  kScenarios = 1u << 7,
  kCalibrate = 1u << 8,
};
constexpr unsigned kEveryCommand = 0x1FFu;

constexpr std::array<std::pair<std::string_view, Command>, 9> kCommandNames = {{
    {"simulate", kSimulate},
    {"run", kRun},
    {"join", kJoin},
    {"solve", kSolve},
    {"study", kStudy},
    {"study merge", kStudyMerge},
    {"plot", kPlot},
    {"scenarios", kScenarios},
    {"calibrate", kCalibrate},
}};

unsigned CommandBit(std::string_view command) {
  for (const auto& [name, bit] : kCommandNames) {
    if (name == command) return bit;
  }
  return 0;
}

unsigned Bit(Frontend f) { return 1u << static_cast<unsigned>(f); }
unsigned Bit(Backend b) { return 1u << static_cast<unsigned>(b); }
unsigned Frontends(std::initializer_list<Frontend> list) {
  unsigned bits = 0;
  for (Frontend f : list) bits |= Bit(f);
  return bits;
}
unsigned Backends(std::initializer_list<Backend> list) {
  unsigned bits = 0;
  for (Backend b : list) bits |= Bit(b);
  return bits;
}

constexpr std::array<Frontend, 7> kAllFrontends = {Frontend::kOdometry, Frontend::kEkfSlam, Frontend::kFastSlam,
                                                   Frontend::kSeif,     Frontend::kIseif,   Frontend::kRbpf,
                                                   Frontend::kEkfLocal};
constexpr std::array<Backend, 7> kAllBackends = {Backend::kNone,     Backend::kEif,     Backend::kCeres,
                                                 Backend::kEkf,      Backend::kTreeEkf, Backend::kTreeEif,
                                                 Backend::kTreeCeres};

// One way a flag is read: by `commands`; for run, only with one of `frontends` (0: any);
// for run and join, only with one of `backends` (0: any, none included; run reaches a
// back-end only through rbpf or ekf); only on a simulated scenario when `scenario`.
struct FlagScope {
  std::vector<std::string_view> patterns;  // exact names, or a prefix ending in '*'
  unsigned commands = 0;
  unsigned frontends = 0;
  unsigned backends = 0;
  bool scenario = false;
  std::vector<std::string_view> except = {};  // names the patterns do not cover here
};

const std::vector<FlagScope>& Scopes() {
  const unsigned not_odometry = Frontends({Frontend::kEkfSlam, Frontend::kFastSlam, Frontend::kSeif, Frontend::kIseif,
                                           Frontend::kRbpf, Frontend::kEkfLocal});
  const unsigned particle_filters = Frontends({Frontend::kFastSlam, Frontend::kRbpf});
  const unsigned local_mappers = Frontends({Frontend::kRbpf, Frontend::kEkfLocal});
  const unsigned joining = Backends(
      {Backend::kEif, Backend::kCeres, Backend::kEkf, Backend::kTreeEkf, Backend::kTreeEif, Backend::kTreeCeres});
  const unsigned eif = Backends({Backend::kEif, Backend::kCeres, Backend::kTreeEif, Backend::kTreeCeres});
  const unsigned ceres = Backends({Backend::kCeres, Backend::kTreeCeres});
  static const auto* scopes = new std::vector<FlagScope>{
      // Input and output.
      {{"dataset"}, kRun | kJoin | kStudy | kCalibrate},
      {{"scenario"}, kSimulate | kRun | kJoin | kCalibrate},
      {{"seed", "world_seed", "alpha", "beta", "duration", "moving_objects", "fmj_case", "world_size", "landmarks",
        "path_length", "lattice_spacing", "noise_scale", "signature"},
       kSimulate | kRun | kJoin | kCalibrate,
       0,
       0,
       /*scenario=*/true},
      {{"calibration"}, kRun | kCalibrate},
      {{"submaps"}, kJoin},
      {{"out"}, kSimulate | kRun | kJoin | kSolve | kStudy | kStudyMerge | kCalibrate},
      {{"config"}, kRun | kJoin | kSolve},
      {{"quiet"}, kSimulate | kRun | kJoin | kSolve | kStudy | kStudyMerge | kPlot | kCalibrate},
      {{"progress"}, kRun | kStudy},
      {{"keep_freed_memory"}, kEveryCommand},
      {{"known_association"}, kRun, not_odometry},
      {{"known_association"}, kJoin | kCalibrate},
      {{"sigma_v", "sigma_u1", "control_spike_sigmas", "time_gap_factor", "frontend"}, kRun},
      {{"sigma_range", "sigma_bearing", "max_range", "sensor_yaw"}, kRun, not_odometry},
      // Front-ends.
      {{"association"}, kRun, Frontends({Frontend::kEkfSlam, Frontend::kEkfLocal, Frontend::kSeif, Frontend::kIseif})},
      {{"gate", "new_landmark_gate", "existence_*", "drop_unconfirmed_landmarks"}, kRun, not_odometry},
      {{"innovation_test_window"}, kRun, Frontends({Frontend::kEkfSlam, Frontend::kEkfLocal})},
      {{"odometry_scale_sigma", "odometry_offset_sigma"},
       kRun,
       Frontends({Frontend::kEkfSlam, Frontend::kEkfLocal, Frontend::kFastSlam, Frontend::kRbpf})},
      {{"particles", "filter_seed", "threads", "sample_association", "landmark_iterations", "resample_ess",
        "depletion_ess", "correct_shared_ancestry", "sensor_yaw_sigma", "sigma_signature"},
       kRun,
       particle_filters},
      {{"seif_*"}, kRun, Frontends({Frontend::kSeif, Frontend::kIseif})},
      {{"iseif_*"}, kRun, Frontends({Frontend::kIseif})},
      {{"submap_*"}, kRun, local_mappers},
      // Back-ends: run reaches them through a local-map front-end.
      {{"backend"}, kRun, local_mappers},
      {{"backend"}, kJoin},
      {{"join_*", "sensor_yaw_calibration", "sensor_yaw_prior_sigma", "sigma_signature"}, kRun, local_mappers, joining},
      // A recorded join has no online pose to keep up: it joins in the foreground.
      {{"join_*", "sensor_yaw_calibration", "sensor_yaw_prior_sigma", "sigma_signature"},
       kJoin,
       0,
       joining,
       false,
       {"join_in_background"}},
      {{"relinearize_*", "max_relinearizations", "single_linearization", "eif_*", "validate_joins"},
       kRun,
       local_mappers,
       eif},
      {{"relinearize_*", "max_relinearizations", "single_linearization", "eif_*", "validate_joins"}, kJoin, 0, eif},
      {{"relinearize_*", "max_relinearizations", "single_linearization", "eif_*"}, kSolve},
      {{"ceres_*"}, kRun, local_mappers, ceres},
      {{"ceres_*"}, kJoin, 0, ceres},
      {{"ceres_method", "ceres_loss", "ceres_loss_scale"}, kSolve},
      {{"ekf_*"}, kRun, local_mappers, Backends({Backend::kEkf, Backend::kTreeEkf})},
      {{"ekf_*"}, kJoin, 0, Backends({Backend::kEkf, Backend::kTreeEkf})},
      {{"tree_batch", "tree_online_fold"},
       kRun,
       local_mappers,
       Backends({Backend::kTreeEkf, Backend::kTreeEif, Backend::kTreeCeres})},
      {{"tree_batch"}, kJoin, 0, Backends({Backend::kTreeEkf, Backend::kTreeEif, Backend::kTreeCeres})},
      // Graphs and studies.
      {{"graph", "format", "noise", "initial", "poses_per_map", "tree_joining", "write_local_maps", "max_iterations"},
       kSolve},
      {{"methods"}, kSolve | kStudy},
      {{"plots"}, kSolve | kStudy | kStudyMerge},
      {{"trials", "workers", "shard"}, kStudy},
  };
  return *scopes;
}

bool Matches(std::string_view name, std::string_view pattern) {
  if (!pattern.empty() && pattern.back() == '*') return name.starts_with(pattern.substr(0, pattern.size() - 1));
  return name == pattern;
}

bool ScopeNames(const FlagScope& scope, std::string_view name) {
  if (std::find(scope.except.begin(), scope.except.end(), name) != scope.except.end()) return false;
  return std::any_of(scope.patterns.begin(), scope.patterns.end(),
                     [&](std::string_view p) { return Matches(name, p); });
}

bool ScopeApplies(const FlagScope& scope, const CommandContext& c) {
  const unsigned command = CommandBit(c.command);
  if ((scope.commands & command) == 0) return false;
  if (scope.scenario && !c.scenario) return false;
  if (scope.frontends != 0 && (!c.frontend.has_value() || (scope.frontends & Bit(*c.frontend)) == 0)) return false;
  if (scope.backends != 0 && (!c.backend.has_value() || (scope.backends & Bit(*c.backend)) == 0)) return false;
  return true;
}

std::string Join(const std::vector<std::string>& parts, std::string_view last) {
  if (parts.size() <= 1) return parts.empty() ? "" : parts.front();
  std::vector<std::string> head(parts.begin(), parts.end() - 1);
  return absl::StrCat(absl::StrJoin(head, ", "), " ", absl::string_view(last.data(), last.size()), " ", parts.back());
}

std::string Describe(const FlagScope& scope) {
  std::vector<std::string> commands;
  for (const auto& [name, bit] : kCommandNames) {
    if (scope.commands & bit) commands.emplace_back(name);
  }
  std::string text = Join(commands, "and");
  if (scope.commands == kEveryCommand) text = "every command";
  if (scope.frontends != 0) {
    std::vector<std::string> names;
    for (Frontend f : kAllFrontends) {
      if (scope.frontends & Bit(f)) names.emplace_back(pipeline::ToString(f));
    }
    absl::StrAppend(&text, " with --frontend ", Join(names, "or"));
  }
  if (scope.backends != 0) {
    std::vector<std::string> names;
    for (Backend b : kAllBackends) {
      if (scope.backends & Bit(b)) names.emplace_back(pipeline::ToString(b));
    }
    absl::StrAppend(&text, scope.frontends != 0 ? " and" : " with", " --backend ", Join(names, "or"));
  }
  if (scope.scenario) absl::StrAppend(&text, " on a simulated --scenario");
  return text;
}

}  // namespace

bool FlagIsRead(std::string_view name, const CommandContext& context) {
  return std::any_of(Scopes().begin(), Scopes().end(),
                     [&](const FlagScope& s) { return ScopeNames(s, name) && ScopeApplies(s, context); });
}

bool CommandMayReadFlag(std::string_view name, std::string_view command) {
  const unsigned bit = CommandBit(command);
  return std::any_of(Scopes().begin(), Scopes().end(),
                     [&](const FlagScope& s) { return ScopeNames(s, name) && (s.commands & bit) != 0; });
}

std::string FlagReaders(std::string_view name) {
  std::vector<std::string> readers;
  for (const FlagScope& s : Scopes()) {
    if (!ScopeNames(s, name)) continue;
    std::string reader = Describe(s);
    if (std::find(readers.begin(), readers.end(), reader) == readers.end()) readers.push_back(std::move(reader));
  }
  return readers.empty() ? "no command" : absl::StrJoin(readers, "; ");
}

std::set<std::string>& GivenFlags() {
  static auto* given = new std::set<std::string>;
  return *given;
}

void NoteFlagsGiven(int argc, char** argv) {
  GivenFlags().clear();
  for (int i = 1; i < argc; ++i) {
    std::string_view arg = argv[i];
    if (arg == "--") break;
    if (!arg.starts_with("-")) continue;
    arg.remove_prefix(arg.starts_with("--") ? 2 : 1);
    std::string name(arg.substr(0, arg.find('=')));
    if (absl::FindCommandLineFlag(name) == nullptr && name.starts_with("no")) name = name.substr(2);
    if (absl::FindCommandLineFlag(name) != nullptr) GivenFlags().insert(name);
  }
}

bool FlagGiven(std::string_view name) { return GivenFlags().contains(std::string(name)); }

std::vector<std::string> ProgramFlagNames() {
  std::vector<std::string> names;
  for (const auto& [name, flag] : absl::GetAllFlags()) {
    if (flag->IsRetired() || flag->Filename().find("absl/") != std::string::npos) continue;
    names.emplace_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

absl::Status CheckFlagsRead(const CommandContext& context) {
  std::vector<std::string> problems;
  for (const std::string& name : ProgramFlagNames()) {
    const absl::CommandLineFlag* flag = absl::FindCommandLineFlag(name);
    if (flag->CurrentValue() == flag->DefaultValue() && !FlagGiven(name)) continue;
    if (FlagIsRead(name, context)) continue;
    problems.push_back(absl::StrCat("--", name, " (read by ", FlagReaders(name), ")"));
  }
  if (problems.empty()) return absl::OkStatus();
  std::string what = context.command;
  if (context.frontend.has_value()) absl::StrAppend(&what, " --frontend ", pipeline::ToString(*context.frontend));
  if (context.backend.has_value()) absl::StrAppend(&what, " --backend ", pipeline::ToString(*context.backend));
  return absl::InvalidArgumentError(absl::StrCat(what, " does not read ", absl::StrJoin(problems, ", "),
                                                 "; a flag that would change nothing is refused (`subslam help ",
                                                 context.command, "` lists what it reads)"));
}

}  // namespace subslam::cli
