#include "cli_reference.h"

#include <algorithm>
#include <array>
#include <initializer_list>
#include <map>
#include <vector>

#include "absl/flags/commandlineflag.h"
#include "absl/flags/reflection.h"
#include "command_flags.h"

namespace subslam::pipeline {
namespace {

constexpr std::array<CliCommand, 11> kCommands = {{
    {"simulate", "subslam simulate --scenario NAME [--seed S] --out DIR",
     "Simulates a named scenario (docs/scenarios.md) and writes it as a data-set directory "
     "(docs/formats.md, \"Data-set directory\"), with the true poses, the true landmarks and "
     "each detection's true id for evaluation."},
    {"run",
     "subslam run (--dataset DIR | --scenario NAME [--seed S]) --frontend "
     "odometry|ekfslam|fastslam|seif|iseif|rbpf|ekf [--backend eif|none|ceres|ekf|tree-ekf|tree-eif|tree-ceres] "
     "[--config DIR/report.json] --out DIR",
     "Runs one estimator over a data set or a simulated scenario, prints a summary table and "
     "writes the run outputs (docs/formats.md, \"Run outputs\"): the online and final "
     "trajectories, the map, `report.json` with the metrics the ground truth allows, and for the "
     "local-map front-ends (`rbpf`, `ekf`) the local maps as `submaps.jsonl`. `--out` is the "
     "run's own directory: an earlier output directory of the tool is reused after its earlier "
     "outputs are removed, any other non-empty directory is refused. `--config DIR/report.json` "
     "repeats a recorded run (report.json's `invocation` holds the command line and every "
     "flag's value)."},
    {"join",
     "subslam join --submaps FILE --backend eif|ceres|ekf|tree-ekf|tree-eif|tree-ceres [--known_association] "
     "[--dataset DIR | --scenario NAME --seed S] [--config DIR/report.json] --out DIR",
     "Runs a back-end alone on recorded local maps, so that every back-end can be compared on "
     "the same input. With `--dataset` or `--scenario`/`--seed` it takes the initial pose and "
     "the ground truth from there and scores the association against the features' true ids. "
     "Writes the anchors, the map, the submap graph (`graph.g2o`) and `report.json`."},
    {"solve",
     "subslam solve --graph FILE [--format g2o|toro|isam|gtsam] [--noise covariance|information|sqrt-information] "
     "[--methods lm,dogleg,gn,eif,submaps,submaps-lm] [--initial dead-reckoning|file] --out DIR",
     "Reads a pose-landmark graph in a standard format (docs/formats.md, \"Graph files\"), runs the chosen "
     "solvers on it from the same start — Ceres batch Levenberg-Marquardt, Dogleg and Gauss-Newton, the "
     "incremental EIF, and the submap route with and without a final Levenberg-Marquardt — and prints each "
     "one's error (½Σ rᵀΩr and χ²), iterations, time and peak memory. Writes each solution as `METHOD.g2o`, "
     "`report.json` and the figures."},
    {"calibrate",
     "subslam calibrate (--dataset DIR | --scenario NAME [--seed S]) [--known_association] [--calibration FILE] --out "
     "DIR",
     "Estimates a robot's odometry and sensor from its own data, the way a new robot is brought in: "
     "from an RBPF + EIF run over the data, a batch fit of the scan poses, the landmarks and the "
     "odometry's scale and turn-rate offset, with the noise levels by variance-component estimation "
     "(calibration/robot_calibration.h); then the field of view, the range limits and the detection "
     "probability by range. Prints each value before and after with its standard error and writes "
     "`calibration.json`, whose `manifest_fragment` is what dataset.json's `motion` and `sensor` "
     "would hold; `subslam run --calibration DIR/calibration.json` uses it in place of the "
     "manifest's values. Without `--known_association` the detections are paired by a gate."},
    {"study",
     "subslam study hybridslam|combined-slam|fmj|iseif --out DIR [--trials N] [--methods A,B] [--workers W] [--shard "
     "K/N] [--dataset DIR]",
     "Runs a paper's experiment (docs/reproducing.md): every method, setting and trial, on every "
     "core, and writes the per-run table (`runs.csv`), the paper's table beside ours "
     "(`summary.md`, the same figures in `summary.json`), the run times (`timings.csv`) and the "
     "exact configuration (`config.json`). `--shard K/N` runs one slice of the runs. `iseif` with "
     "`--dataset` (Victoria Park) adds the paper's real-data table."},
    {"study merge", "subslam study merge DIR... --out DIR",
     "Combines the slices of a study run with `--shard K/N` (every K once) into the same outputs "
     "a single run writes, byte for byte."},
    {"plot", "subslam plot DIR...",
     "Draws the figures of `subslam run`, `join` and `study` output directories into `DIR/plots/` "
     "(PNG and SVG) with matplotlib: the map with 95 % ellipses over the true landmarks or the GPS "
     "track, the trajectories, the pose NEES with its χ² band, the time per join, each study's "
     "figures (scripts/plot.py lists them). A complete study draws its own unless `--plots=false`."},
    {"scenarios", "subslam scenarios", "Lists the simulated scenarios, one name per line."},
    {"cli-reference", "subslam cli-reference", "Prints this reference in Markdown; docs/cli.md is its output."},
    {"help", "subslam help [COMMAND]",
     "Prints the commands, or one command's usage and the flags it reads with their defaults "
     "(also `subslam COMMAND --help` and `-h`). `subslam --version` prints the version, the "
     "commit and the build type."},
}};

// Flag groups of the reference, in order. A flag belongs to the first group one of whose
// patterns it matches: a pattern ending in '*' is a name prefix, any other an exact name.
struct FlagGroup {
  std::string_view title;
  std::string_view note;
  std::vector<std::string_view> patterns;
};

const std::vector<FlagGroup>& FlagGroups() {
  static const auto* groups = new std::vector<FlagGroup>{
      {"Input and output",
       "Where the data comes from and where the outputs go. The noise and sensor overrides "
       "replace the data set's own values.",
       {"dataset", "scenario", "seed", "submaps", "out", "config", "calibration", "known_association", "sensor_yaw",
        "sigma_v", "sigma_u1", "sigma_range", "sigma_bearing", "max_range", "control_spike_sigmas", "time_gap_factor",
        "progress", "quiet", "keep_freed_memory"}},
      {"Studies", "`subslam study` (docs/reproducing.md).", {"trials", "methods", "workers", "shard", "plots"}},
      {"Graphs",
       "`subslam solve` (docs/formats.md, \"Graph files\").",
       {"graph", "format", "noise", "initial", "poses_per_map", "tree_joining", "write_local_maps", "max_iterations"}},
      {"Simulation",
       "Shape the simulated worlds (docs/scenarios.md).",
       {"world_seed", "alpha", "beta", "duration", "moving_objects", "fmj_case", "world_size", "landmarks",
        "path_length", "lattice_spacing", "noise_scale", "signature"}},
      {"Front-end: association and existence",
       "Shared by EKF-SLAM, SEIF/ISEIF and the particle filters.",
       {"frontend", "association", "gate", "new_landmark_gate", "existence_*", "innovation_test_window", "odometry_*",
        "drop_unconfirmed_landmarks"}},
      {"Particle filter (`fastslam`, `rbpf`)",
       "",
       {"particles", "filter_seed", "threads", "sample_association", "landmark_iterations", "resample_ess",
        "correct_shared_ancestry", "sigma_signature", "sensor_yaw_sigma", "depletion_ess"}},
      {"SEIF and ISEIF (`seif`, `iseif`)", "", {"seif_*", "iseif_*"}},
      {"Local maps (`rbpf`, `ekf`)",
       "When a local map is closed and what it exports (frontend/submap_policy.h).",
       {"submap_*"}},
      {"Back-end: joining and association",
       "How local maps are joined into the global map and how their features are associated "
       "with its landmarks (association/submap_association.h, association/landmark_revision.h).",
       {"backend", "join_*", "validate_joins", "sensor_yaw_calibration", "sensor_yaw_prior_sigma"}},
      {"Back-end: EIF relinearisation and factorisation",
       "",
       {"relinearize_*", "max_relinearizations", "single_linearization", "eif_*"}},
      {"Back-end: Ceres", "", {"ceres_*"}},
      {"Back-end: dense EKF and binary tree", "", {"ekf_*", "tree_*"}},
  };
  return *groups;
}

// Appends the pieces to `out` (Abseil's string functions here take absl::string_view,
// which Debian's build does not alias to std::string_view).
void Append(std::string& out, std::initializer_list<std::string_view> pieces) {
  for (std::string_view piece : pieces) out.append(piece);
}

bool Matches(std::string_view name, std::string_view pattern) {
  if (!pattern.empty() && pattern.back() == '*') {
    return name.starts_with(pattern.substr(0, pattern.size() - 1));
  }
  return name == pattern;
}

// Markdown table cell: no pipes or line breaks that would end the cell.
std::string Cell(std::string_view text) {
  std::string cell;
  for (char c : text) {
    if (c == '|')
      cell += "\\|";
    else
      cell += c == '\n' ? ' ' : c;
  }
  return cell;
}

// The program's own flags (Abseil's --help, --flagfile, ... are left out) that `command`
// may read (every flag when it is empty), by group of FlagGroups() and then "Other", each
// group by name.
std::vector<std::vector<const absl::CommandLineFlag*>> GroupedFlags(std::string_view command) {
  std::vector<std::vector<const absl::CommandLineFlag*>> grouped(FlagGroups().size() + 1);
  for (const std::string& name : cli::ProgramFlagNames()) {
    if (!command.empty() && !cli::CommandMayReadFlag(name, command)) continue;
    size_t g = 0;
    while (g < FlagGroups().size() && std::none_of(FlagGroups()[g].patterns.begin(), FlagGroups()[g].patterns.end(),
                                                   [&](std::string_view p) { return Matches(name, p); })) {
      ++g;
    }
    grouped[g].push_back(absl::FindCommandLineFlag(name));
  }
  return grouped;
}

// `text` wrapped at `width` columns, every line indented by `indent` spaces.
std::string Wrapped(std::string_view text, size_t indent, size_t width) {
  std::string out;
  std::string line(indent, ' ');
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find(' ', start);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view word = text.substr(start, end - start);
    if (line.size() > indent && line.size() + 1 + word.size() > width) {
      Append(out, {line, "\n"});
      line.assign(indent, ' ');
    }
    if (line.size() > indent) line += ' ';
    line.append(word);
    start = end + 1;
  }
  if (line.size() > indent) Append(out, {line, "\n"});
  return out;
}

}  // namespace

std::string CommandHelp(std::string_view name) {
  const auto command =
      std::find_if(kCommands.begin(), kCommands.end(), [&](const CliCommand& c) { return c.name == name; });
  if (command == kCommands.end()) return "";
  std::string help;
  Append(help, {"Usage: ", command->synopsis, "\n\n", Wrapped(command->description, 0, 92)});
  const std::vector<std::vector<const absl::CommandLineFlag*>> grouped = GroupedFlags(name);
  for (size_t g = 0; g < grouped.size(); ++g) {
    if (grouped[g].empty()) continue;
    Append(help, {"\n", g == FlagGroups().size() ? "Other" : FlagGroups()[g].title, ":\n"});
    for (const absl::CommandLineFlag* flag : grouped[g]) {
      const std::string default_value = flag->DefaultValue();
      Append(help, {"  --", std::string(flag->Name()), default_value.empty() ? "" : "=", default_value, "\n",
                    Wrapped(flag->Help(), 6, 92)});
    }
  }
  help +=
      "\nFlags are --name=value or --name value (booleans also --name / --noname); a flag the\n"
      "command would not read with the other flags given is refused. Every flag: docs/cli.md.\n";
  return help;
}

std::string GeneralHelp() {
  std::string help = "subslam: submap-based landmark SLAM\n\nCommands:\n";
  for (const CliCommand& command : kCommands) Append(help, {"  ", command.synopsis, "\n"});
  help +=
      "\n`subslam help COMMAND` (or `subslam COMMAND --help`) prints a command's flags with their defaults;\n"
      "`subslam --version` the version. Every command and flag: docs/cli.md.\n";
  return help;
}

std::span<const CliCommand> CliCommands() { return kCommands; }

std::string CliUsage() {
  std::string usage = "submap-based landmark SLAM";
  for (const CliCommand& command : kCommands) Append(usage, {"\n  ", command.synopsis});
  usage += "\nA command's flags: subslam help COMMAND (or COMMAND --help); every flag: docs/cli.md.";
  return usage;
}

std::string CliReferenceMarkdown() {
  const std::vector<std::vector<const absl::CommandLineFlag*>> grouped = GroupedFlags("");
  std::string md =
      "# Command-line reference\n\n"
      "<!-- Generated by `subslam cli-reference > docs/cli.md` (scripts/update_cli_doc.sh); "
      "a test checks that it is current. Do not edit by hand. -->\n\n"
      "`subslam` is the command-line tool of the library: one command per job. Flags are "
      "given as `--name=value` or `--name value` (booleans also as `--name` / "
      "`--noname`). A command reads the flags its \"read by\" column names, with the "
      "front-end, back-end or input named there; it refuses a flag it would not read, so "
      "that nothing is silently ignored. `subslam help COMMAND` prints the same per command. "
      "Units are SI, angles in radians (docs/conventions.md).\n\n"
      "## Commands\n";
  for (const CliCommand& command : kCommands) {
    Append(md, {"\n### `", command.name, "`\n\n```\n", command.synopsis, "\n```\n\n", command.description, "\n"});
  }
  md += "\n## Flags\n";
  for (size_t g = 0; g < grouped.size(); ++g) {
    if (grouped[g].empty()) continue;
    const bool other = g == FlagGroups().size();
    Append(md, {"\n### ", other ? "Other" : FlagGroups()[g].title, "\n\n"});
    if (!other && !FlagGroups()[g].note.empty()) Append(md, {FlagGroups()[g].note, "\n\n"});
    md += "| flag | default | meaning | read by |\n| --- | --- | --- | --- |\n";
    for (const absl::CommandLineFlag* flag : grouped[g]) {
      const std::string default_value = flag->DefaultValue();
      std::string shown = "(none)";
      if (!default_value.empty()) {
        shown = "`";
        Append(shown, {Cell(default_value), "`"});
      }
      const std::string name(flag->Name());
      Append(md,
             {"| `--", name, "` | ", shown, " | ", Cell(flag->Help()), " | ", Cell(cli::FlagReaders(name)), " |\n"});
    }
  }
  return md;
}

}  // namespace subslam::pipeline
