#include "tool_flags.h"

#include "absl/flags/flag.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/pipeline/solve_pipeline.h"
#include "subslam/sim/scenario.h"

// Flag defaults come from the option structs, so the tool and the library agree.
namespace {
const subslam::sim::ScenarioOptions kScenarioDefaults;
}  // namespace

ABSL_FLAG(std::string, dataset, "", "data-set directory holding dataset.json");
ABSL_FLAG(std::string, scenario, "", "simulated scenario name (see `subslam scenarios`)");
ABSL_FLAG(uint64_t, seed, kScenarioDefaults.seed, "scenario seed (noise, detections, clutter)");
ABSL_FLAG(std::optional<uint64_t>, world_seed, std::nullopt,
          "scenario world seed (landmarks, path jitter); default: --seed");
ABSL_FLAG(std::optional<double>, alpha, std::nullopt, "simulated detection probability alpha (default 1.0)");
ABSL_FLAG(std::optional<double>, beta, std::nullopt,
          "simulated false-alarm probability beta per visible feature (default 0.0)");
ABSL_FLAG(std::optional<double>, duration, std::nullopt, "truncate the simulation [s]");
ABSL_FLAG(std::optional<int>, moving_objects, std::nullopt,
          "camera-robot: other robots driving with landmark markers, >= 0 (default 4)");
ABSL_FLAG(int, fmj_case, kScenarioDefaults.fmj_case, "fmj-ellipse: case 1 (even landmarks) or 2 (uneven)");
ABSL_FLAG(double, world_size, kScenarioDefaults.random_world_size_m, "random scenario: world side [m]");
ABSL_FLAG(int, landmarks, kScenarioDefaults.random_landmarks, "random scenario: number of landmarks");
ABSL_FLAG(double, path_length, kScenarioDefaults.random_path_length_m, "random scenario: distance driven [m]");
ABSL_FLAG(double, lattice_spacing, kScenarioDefaults.random_lattice_spacing_m,
          "random scenario: landmarks on a square lattice of this spacing [m] instead of "
          "--landmarks uniform ones (0: off)");
ABSL_FLAG(double, noise_scale, kScenarioDefaults.random_noise_scale, "random scenario: multiplies every sigma");
ABSL_FLAG(bool, signature, kScenarioDefaults.with_signature, "simulated detections carry a noisy signature");
ABSL_FLAG(std::string, out, "", "output directory");
ABSL_FLAG(std::string, calibration, "",
          "run, calibrate: a calibration (`subslam calibrate`'s calibration.json, or a manifest fragment) laid "
          "over the data set's motion and sensor values (io/calibration_fragment.h)");
ABSL_FLAG(std::string, frontend, subslam::pipeline::ToString(subslam::pipeline::RunOptions{}.frontend),
          "odometry | ekfslam | fastslam | seif | iseif | rbpf | ekf");
ABSL_FLAG(std::string, submaps, "", "join: the local maps (submaps.jsonl)");
ABSL_FLAG(std::optional<double>, sigma_v, std::nullopt, "override speed noise sigma [m/s]");
ABSL_FLAG(std::optional<double>, sigma_u1, std::nullopt, "override turn-rate [rad/s] or steering [rad] noise sigma");
ABSL_FLAG(std::optional<double>, sigma_range, std::nullopt, "override range sigma [m]");
ABSL_FLAG(std::optional<double>, sigma_bearing, std::nullopt, "override bearing sigma [rad]");
ABSL_FLAG(std::optional<double>, max_range, std::nullopt, "ignore detections beyond [m]");
ABSL_FLAG(std::optional<double>, sensor_yaw, std::nullopt,
          "add this to every bearing [rad]: the sensor's yaw on the vehicle, a calibration "
          "(Victoria Park: -0.0182, bench/sensor_yaw_calibration); given, it is taken as calibrated "
          "and the back-end's online yaw calibration is off unless --sensor_yaw_calibration=true");
ABSL_FLAG(std::optional<int>, trials, std::nullopt,
          "study: trials per method and setting, >= 1 (default: the paper's)");
ABSL_FLAG(std::optional<int>, workers, std::nullopt,
          "study: runs at a time, one thread each, >= 1 (default: every core)");
ABSL_FLAG(std::vector<std::string>, methods, {}, "study: only these methods, comma-separated (default: all)");
ABSL_FLAG(std::string, shard, "1/1", "study: run slice K of N (K/N); `subslam study merge` combines the slices");
ABSL_FLAG(bool, plots, true, "study: draw the study's figures when it is complete (`subslam plot`)");
ABSL_FLAG(std::string, graph, "", "solve: the graph file (g2o, TORO, iSAM or GTSAM text)");
ABSL_FLAG(std::string, format, "",
          "solve: the graph file's format, g2o | toro | isam | gtsam (default: from the extension: .g2o, "
          ".graph/.toro, .isam)");
ABSL_FLAG(std::string, noise, "",
          "solve: read the file's noise numbers as covariance | information | sqrt-information (default: the "
          "format's: g2o and toro information, isam sqrt-information, gtsam covariance)");
ABSL_FLAG(std::string, initial, "dead-reckoning",
          "solve: start from dead-reckoning | file (the file's vertex estimates)");
ABSL_FLAG(int, poses_per_map, subslam::pipeline::SolveOptions{}.poses_per_map,
          "solve: poses per local map of the submap route (methods submaps, submaps-lm)");
ABSL_FLAG(bool, tree_joining, subslam::pipeline::SolveOptions{}.tree_joining,
          "solve: the submap route (submaps, submaps-lm) joins its local maps pairwise in a binary tree; false: in "
          "order into one map");
ABSL_FLAG(int, max_iterations, subslam::pipeline::SolveOptions{}.ceres.max_iterations,
          "solve: most iterations of a Ceres solve (lm, dogleg, gn, submaps-lm's polish); a solve that stops "
          "there is reported as not converged");
ABSL_FLAG(std::string, config, "",
          "run, join, solve: repeat the run that wrote this report.json: every flag it records, except those "
          "given on the command line and --out, --progress, --quiet");
ABSL_FLAG(bool, write_local_maps, false,
          "solve: also write the submap routes' local maps (METHOD_submaps.jsonl) for `subslam join`");
ABSL_FLAG(bool, progress, true, "show a progress line on a terminal");
ABSL_FLAG(bool, quiet, false, "do not print the summary table");
