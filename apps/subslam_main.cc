// subslam — command-line tool.
//
//   subslam simulate --scenario NAME [--seed S] --out DIR [scenario flags]
//   subslam run (--dataset DIR | --scenario NAME [--seed S]) --frontend odometry|ekfslam|fastslam|seif|iseif|rbpf|ekf
//               --out DIR [estimator and noise flags]
//   subslam scenarios
//
// Every flag is listed by `subslam --help`.
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/flags/parse.h"
#include "absl/flags/usage.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "cli_reference.h"
#include "backend_flags.h"
#include "keep_freed_memory_flag.h"
#include "subslam/pipeline/join_pipeline.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/io/submaps_jsonl.h"
#include "subslam/io/dataset_reader.h"
#include "subslam/io/dataset_writer.h"
#include "subslam/sim/simulator.h"

// Flag defaults come from the option structs, so the tool and the library agree.
namespace {
const subslam::sim::ScenarioOptions kScenarioDefaults;
const subslam::frontend::EkfSlamOptions kEkfDefaults;
const subslam::frontend::FastSlamOptions kFastSlamDefaults;
const subslam::frontend::SeifOptions kSeifDefaults;
const subslam::frontend::SubmapPolicyOptions kPolicyDefaults;
}  // namespace

ABSL_FLAG(std::string, dataset, "", "data-set directory holding dataset.json");
ABSL_FLAG(std::string, scenario, "", "simulated scenario name (see `subslam scenarios`)");
ABSL_FLAG(uint64_t, seed, kScenarioDefaults.seed, "scenario seed (noise, detections, clutter)");
ABSL_FLAG(std::optional<uint64_t>, world_seed, std::nullopt,
          "scenario world seed (landmarks, path jitter); default: --seed");
ABSL_FLAG(std::optional<double>, alpha, std::nullopt,
          "simulated detection probability alpha (default 1.0)");
ABSL_FLAG(std::optional<double>, beta, std::nullopt,
          "simulated false-alarm probability beta per visible feature (default 0.0)");
ABSL_FLAG(std::optional<double>, duration, std::nullopt, "truncate the simulation [s]");
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
ABSL_FLAG(std::string, frontend, subslam::pipeline::ToString(subslam::pipeline::RunOptions{}.frontend),
          "odometry | ekfslam | fastslam | seif | iseif | rbpf | ekf");
ABSL_FLAG(std::string, association, subslam::association::ToString(kEkfDefaults.association),
          "ekfslam / seif / iseif data association: nn | jcbb");
ABSL_FLAG(double, gate, kEkfDefaults.landmarks.gate_probability, "individual compatibility gate probability (chi2, 2 dof)");
ABSL_FLAG(double, new_landmark_gate, kEkfDefaults.landmarks.new_landmark_probability,
          "a detection outside this gate for every landmark starts a new one");
ABSL_FLAG(double, existence_alpha, kEkfDefaults.landmarks.existence.detection_probability, "existence model: detection probability");
ABSL_FLAG(int, particles, kFastSlamDefaults.num_particles, "fastslam / rbpf: number of particles");
ABSL_FLAG(uint64_t, filter_seed, kFastSlamDefaults.seed, "fastslam / rbpf: seed of the particle filter's random draws");
ABSL_FLAG(int, threads, 0,
          "fastslam / rbpf: threads for the per-particle scan update (0: every core); the "
          "results are the same for any number");
ABSL_FLAG(bool, sample_association, kFastSlamDefaults.sample_association,
          "fastslam / rbpf: sample the data association instead of maximum likelihood");
ABSL_FLAG(int, landmark_iterations, kFastSlamDefaults.landmark_update_iterations,
          "fastslam / rbpf: landmark update iterations (1: EKF, more: iterated EKF)");
ABSL_FLAG(double, resample_ess, kFastSlamDefaults.resample_ess_ratio,
          "fastslam / rbpf: resample when N_eff / N falls below this");
ABSL_FLAG(bool, correct_shared_ancestry, kFastSlamDefaults.correct_shared_ancestry,
          "fastslam / rbpf: scale the particles' spread in the moment matching by (1 + R) / (1 - R), "
          "R the weighted share of pose noise that pairs of particles hold through common "
          "ancestors (the spread's bias and the mean's Monte Carlo error); false: the mixture's "
          "own moments");
ABSL_FLAG(std::string, submaps, "", "join: the local maps (submaps.jsonl)");
ABSL_FLAG(int, seif_max_active, kSeifDefaults.max_active_landmarks,
          "seif / iseif: sparsification bound on the active landmarks (0: never sparsify)");
ABSL_FLAG(std::string, seif_recovery, subslam::frontend::ToString(kSeifDefaults.recovery),
          "seif / iseif: mean recovery, relaxation (amortised Gauss-Seidel) | exact (CHOLMOD)");
ABSL_FLAG(int, seif_sweeps, kSeifDefaults.relaxation_sweeps, "seif / iseif: relaxation sweeps per scan");
ABSL_FLAG(int, seif_extra_landmarks, kSeifDefaults.relaxation_extra_landmarks,
          "seif / iseif: round-robin landmarks relaxed per scan besides the local ones");
ABSL_FLAG(std::string, seif_covariance, subslam::frontend::ToString(kSeifDefaults.covariance),
          "seif / iseif: marginal covariances for gating and the pose, markov-blanket | exact");
ABSL_FLAG(std::string, seif_pose_covariance, subslam::frontend::ToString(kSeifDefaults.pose_covariance),
          "seif / iseif: the reported pose covariance, markov-blanket (cheap, over-confident) | exact "
          "(the filter's own marginal; one factorisation per scan)");
ABSL_FLAG(int, seif_blanket, kSeifDefaults.blanket_max_landmarks,
          "seif / iseif: most landmarks in a scan's Markov blanket (gating covariances)");
ABSL_FLAG(double, seif_candidate_radius, kSeifDefaults.candidate_radius_m,
          "seif / iseif: landmarks farther than this from a detection's point are not gated with it [m]");
ABSL_FLAG(int, iseif_period, kSeifDefaults.iterated.period_scans,
          "iseif: iterate the measurement update on every N-th scan (the paper: 100 or 500)");
ABSL_FLAG(int, iseif_max_iterations, kSeifDefaults.iterated.max_iterations, "iseif: linearisations per iterated update");
ABSL_FLAG(double, iseif_stop, kSeifDefaults.iterated.stop_change,
          "iseif: adaptive stop, largest change of the pose or an observed landmark [m, rad]");
ABSL_FLAG(int, iseif_exact_recoveries, kSeifDefaults.iterated.exact_recoveries,
          "iseif: the first N linearisations of an iterated update are followed by an exact recovery of "
          "the whole mean, later ones by local relaxation");
ABSL_FLAG(double, submap_min_duration, kPolicyDefaults.min_duration_s,
          "rbpf: a local map is never closed younger than this [s]");
ABSL_FLAG(double, submap_max_duration, kPolicyDefaults.max_duration_s,
          "rbpf: close a local map after this long [s] (0: off)");
ABSL_FLAG(int, submap_max_features, kPolicyDefaults.max_features,
          "rbpf: close a local map holding this many confirmed features (0: off)");
ABSL_FLAG(double, submap_min_ess, kPolicyDefaults.min_ess_ratio,
          "rbpf: close when N_eff / N falls below this (0: off)");
ABSL_FLAG(double, submap_min_diversity, kPolicyDefaults.min_lineage_diversity,
          "rbpf: close when the share of distinct ancestors at the map's first scan falls "
          "below this (0: off)");
ABSL_FLAG(double, submap_max_pose_sigma, kPolicyDefaults.max_pose_sigma_ratio,
          "rbpf: close when the local pose sigma exceeds this many sensor sigmas (0: off)");
ABSL_FLAG(double, submap_max_feature_sigma, kPolicyDefaults.max_feature_sigma_ratio,
          "rbpf, ekf: do not export a feature more uncertain relative to the map's end pose "
          "(widest axis) than this many times one detection at the sensor's maximum range "
          "(0: export all)");
ABSL_FLAG(int, submap_density_features, kPolicyDefaults.density_min_features,
          "rbpf: landmark-density rule: close once the map holds this many features and "
          "--submap_density_visible of them are in range (0: off)");
ABSL_FLAG(int, submap_density_visible, kPolicyDefaults.density_min_visible,
          "rbpf: see --submap_density_features");
ABSL_FLAG(bool, submap_delay_ambiguous, kPolicyDefaults.delay_while_ambiguous,
          "rbpf: postpone closing while the particles disagree about identities");
ABSL_FLAG(double, existence_beta, kEkfDefaults.landmarks.existence.false_alarm_probability, "existence model: false-alarm probability");
ABSL_FLAG(std::optional<double>, sigma_v, std::nullopt, "override speed noise sigma [m/s]");
ABSL_FLAG(std::optional<double>, sigma_u1, std::nullopt,
          "override turn-rate [rad/s] or steering [rad] noise sigma");
ABSL_FLAG(std::optional<double>, sigma_range, std::nullopt, "override range sigma [m]");
ABSL_FLAG(std::optional<double>, sigma_bearing, std::nullopt, "override bearing sigma [rad]");
ABSL_FLAG(std::optional<double>, max_range, std::nullopt, "ignore detections beyond [m]");
ABSL_FLAG(std::optional<double>, sensor_yaw, std::nullopt,
          "add this to every bearing [rad]: the sensor's yaw on the vehicle, a calibration "
          "(Victoria Park: -0.019, bench/sensor_yaw_calibration)");
ABSL_FLAG(bool, progress, true, "show a progress line on a terminal");
ABSL_FLAG(bool, quiet, false, "do not print the summary table");

namespace {

using subslam::sim::ScenarioOptions;

ScenarioOptions ScenarioOptionsFromFlags() {
  ScenarioOptions o;
  o.seed = absl::GetFlag(FLAGS_seed);
  o.world_seed = absl::GetFlag(FLAGS_world_seed);
  o.detection_probability = absl::GetFlag(FLAGS_alpha);
  o.false_alarm_probability = absl::GetFlag(FLAGS_beta);
  o.duration_s = absl::GetFlag(FLAGS_duration);
  o.fmj_case = absl::GetFlag(FLAGS_fmj_case);
  o.random_world_size_m = absl::GetFlag(FLAGS_world_size);
  o.random_landmarks = absl::GetFlag(FLAGS_landmarks);
  o.random_path_length_m = absl::GetFlag(FLAGS_path_length);
  o.random_noise_scale = absl::GetFlag(FLAGS_noise_scale);
  o.random_lattice_spacing_m = absl::GetFlag(FLAGS_lattice_spacing);
  o.with_signature = absl::GetFlag(FLAGS_signature);
  return o;
}

int Fail(const absl::Status& status) {
  std::fprintf(stderr, "subslam: error: %s\n", std::string(status.message()).c_str());
  return 1;
}

int Simulate() {
  const std::string name = absl::GetFlag(FLAGS_scenario);
  const std::string out = absl::GetFlag(FLAGS_out);
  if (name.empty() || out.empty()) {
    return Fail(absl::InvalidArgumentError("simulate needs --scenario and --out"));
  }
  const ScenarioOptions options = ScenarioOptionsFromFlags();
  auto config = subslam::sim::MakeScenario(name, options);
  if (!config.ok()) return Fail(config.status());
  auto dataset = subslam::sim::Simulate(*config, options.seed);
  if (!dataset.ok()) return Fail(dataset.status());
  subslam::io::SimulationInfo info{name, options.seed, config->detection_probability,
                                   config->false_alarm_probability};
  if (auto s = subslam::io::WriteDataset(*dataset, out, &info); !s.ok()) return Fail(s);
  std::printf("wrote %s: %zu controls, %zu scans, %zu detections, %zu landmarks -> %s\n",
              name.c_str(), dataset->controls.size(), dataset->scans.size(),
              dataset->NumDetections(), dataset->truth_landmarks.size(), out.c_str());
  return 0;
}

int Join() {
  const std::string path = absl::GetFlag(FLAGS_submaps);
  if (path.empty()) return Fail(absl::InvalidArgumentError("join needs --submaps FILE"));
  auto backend = subslam::cli::BackendOptionsFromFlags();
  if (!backend.ok()) return Fail(backend.status());
  if (backend->kind == subslam::pipeline::Backend::kNone) {
    return Fail(absl::InvalidArgumentError("join needs --backend eif, ceres, ekf, tree-ekf or tree-eif"));
  }
  auto submaps = subslam::io::ReadSubmapsJsonl(path);
  if (!submaps.ok()) return Fail(submaps.status());
  subslam::pipeline::JoinOptions options;
  options.backend = *backend;
  options.out_dir = absl::GetFlag(FLAGS_out);
  // The initial pose and the ground truth come from the data set or the scenario the
  // local maps were built on, when given.
  const std::string dataset_dir = absl::GetFlag(FLAGS_dataset);
  const std::string scenario = absl::GetFlag(FLAGS_scenario);
  absl::StatusOr<subslam::io::Dataset> dataset = absl::NotFoundError("");
  if (!dataset_dir.empty()) {
    dataset = subslam::io::ReadDataset(dataset_dir);
  } else if (!scenario.empty()) {
    dataset = subslam::sim::SimulateScenario(scenario, ScenarioOptionsFromFlags());
  }
  if (!dataset_dir.empty() || !scenario.empty()) {
    if (!dataset.ok()) return Fail(dataset.status());
    options.initial_pose = dataset->initial_pose;
    options.truth_poses = dataset->truth_poses;
    options.truth_landmarks = dataset->truth_landmarks;
  }
  auto r = subslam::pipeline::RunJoin(*submaps, options);
  if (!r.ok()) return Fail(r.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam join summary\n%s", r->report.dump(2).c_str());
    std::printf("\n");
    if (!options.out_dir.empty()) {
      std::printf("outputs: %s/{anchors,landmarks}.csv, graph.g2o, report.json\n", options.out_dir.c_str());
    }
  }
  return 0;
}

int Run() {
  const std::string dataset_dir = absl::GetFlag(FLAGS_dataset);
  const std::string scenario = absl::GetFlag(FLAGS_scenario);
  if (dataset_dir.empty() == scenario.empty()) {
    return Fail(absl::InvalidArgumentError("run needs exactly one of --dataset or --scenario"));
  }
  subslam::pipeline::RunOptions options;
  auto frontend = subslam::pipeline::FrontendFromString(absl::GetFlag(FLAGS_frontend));
  if (!frontend.ok()) return Fail(frontend.status());
  options.frontend = *frontend;
  auto association = subslam::association::AssociationMethodFromString(absl::GetFlag(FLAGS_association));
  if (!association.ok()) return Fail(association.status());
  options.ekf.association = *association;
  options.seif.association = *association;
  // The gates, known association and existence model every front-end shares.
  subslam::frontend::LandmarkOptions landmarks;
  landmarks.gate_probability = absl::GetFlag(FLAGS_gate);
  landmarks.new_landmark_probability = absl::GetFlag(FLAGS_new_landmark_gate);
  landmarks.existence.detection_probability = absl::GetFlag(FLAGS_existence_alpha);
  landmarks.existence.false_alarm_probability = absl::GetFlag(FLAGS_existence_beta);
  landmarks.known_association = absl::GetFlag(FLAGS_known_association);
  options.ekf.landmarks = landmarks;
  options.fastslam.landmarks = landmarks;
  options.seif.landmarks = landmarks;
  auto backend = subslam::cli::BackendOptionsFromFlags();
  if (!backend.ok()) return Fail(backend.status());
  options.backend = *backend;
  options.policy.min_duration_s = absl::GetFlag(FLAGS_submap_min_duration);
  options.policy.max_duration_s = absl::GetFlag(FLAGS_submap_max_duration);
  options.policy.max_features = absl::GetFlag(FLAGS_submap_max_features);
  options.policy.min_ess_ratio = absl::GetFlag(FLAGS_submap_min_ess);
  options.policy.min_lineage_diversity = absl::GetFlag(FLAGS_submap_min_diversity);
  options.policy.max_pose_sigma_ratio = absl::GetFlag(FLAGS_submap_max_pose_sigma);
  options.policy.max_feature_sigma_ratio = absl::GetFlag(FLAGS_submap_max_feature_sigma);
  options.policy.density_min_features = absl::GetFlag(FLAGS_submap_density_features);
  options.policy.density_min_visible = absl::GetFlag(FLAGS_submap_density_visible);
  options.policy.delay_while_ambiguous = absl::GetFlag(FLAGS_submap_delay_ambiguous);
  options.fastslam.num_particles = absl::GetFlag(FLAGS_particles);
  options.fastslam.seed = absl::GetFlag(FLAGS_filter_seed);
  options.fastslam.num_threads = absl::GetFlag(FLAGS_threads);
  options.fastslam.sample_association = absl::GetFlag(FLAGS_sample_association);
  options.fastslam.resample_ess_ratio = absl::GetFlag(FLAGS_resample_ess);
  options.fastslam.landmark_update_iterations = absl::GetFlag(FLAGS_landmark_iterations);
  options.fastslam.sigma_signature = absl::GetFlag(FLAGS_sigma_signature);
  options.fastslam.correct_shared_ancestry = absl::GetFlag(FLAGS_correct_shared_ancestry);
  options.seif.max_active_landmarks = absl::GetFlag(FLAGS_seif_max_active);
  auto recovery = subslam::frontend::MeanRecoveryFromString(absl::GetFlag(FLAGS_seif_recovery));
  if (!recovery.ok()) return Fail(recovery.status());
  options.seif.recovery = *recovery;
  auto covariance = subslam::frontend::CovarianceRecoveryFromString(absl::GetFlag(FLAGS_seif_covariance));
  if (!covariance.ok()) return Fail(covariance.status());
  options.seif.covariance = *covariance;
  auto pose_covariance = subslam::frontend::CovarianceRecoveryFromString(absl::GetFlag(FLAGS_seif_pose_covariance));
  if (!pose_covariance.ok()) return Fail(pose_covariance.status());
  options.seif.pose_covariance = *pose_covariance;
  options.seif.relaxation_sweeps = absl::GetFlag(FLAGS_seif_sweeps);
  options.seif.relaxation_extra_landmarks = absl::GetFlag(FLAGS_seif_extra_landmarks);
  options.seif.candidate_radius_m = absl::GetFlag(FLAGS_seif_candidate_radius);
  options.seif.blanket_max_landmarks = absl::GetFlag(FLAGS_seif_blanket);
  options.seif.iterated.period_scans = absl::GetFlag(FLAGS_iseif_period);
  options.seif.iterated.max_iterations = absl::GetFlag(FLAGS_iseif_max_iterations);
  options.seif.iterated.stop_change = absl::GetFlag(FLAGS_iseif_stop);
  options.seif.iterated.exact_recoveries = absl::GetFlag(FLAGS_iseif_exact_recoveries);
  options.noise.sigma_v = absl::GetFlag(FLAGS_sigma_v);
  options.noise.sigma_u1 = absl::GetFlag(FLAGS_sigma_u1);
  options.noise.sigma_range = absl::GetFlag(FLAGS_sigma_range);
  options.noise.sigma_bearing = absl::GetFlag(FLAGS_sigma_bearing);
  options.noise.max_range = absl::GetFlag(FLAGS_max_range);
  options.noise.sensor_yaw = absl::GetFlag(FLAGS_sensor_yaw);
  options.out_dir = absl::GetFlag(FLAGS_out);
  options.progress = absl::GetFlag(FLAGS_progress);

  absl::StatusOr<subslam::io::Dataset> dataset;
  if (!dataset_dir.empty()) {
    dataset = subslam::io::ReadDataset(dataset_dir);
    options.source = absl::StrCat("dataset ", dataset_dir);
  } else {
    const ScenarioOptions scenario_options = ScenarioOptionsFromFlags();
    dataset = subslam::sim::SimulateScenario(scenario, scenario_options);
    options.source = absl::StrCat("scenario ", scenario, " seed ", scenario_options.seed);
  }
  if (!dataset.ok()) return Fail(dataset.status());
  auto result = subslam::pipeline::RunPipeline(*std::move(dataset), options);
  if (!result.ok()) return Fail(result.status());
  if (!absl::GetFlag(FLAGS_quiet)) {
    std::printf("subslam run summary\n%s", subslam::pipeline::SummaryTable(*result).c_str());
    if (!options.out_dir.empty()) {
      const bool local_maps = !result->local_maps.empty();
      std::printf("  %-34s %s/{trajectory_online,trajectory_final,landmarks}.csv, report.json%s\n",
                  "outputs", options.out_dir.c_str(), local_maps ? ", submaps.jsonl" : "");
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  absl::SetProgramUsageMessage(subslam::pipeline::CliUsage());
  std::vector<char*> args = absl::ParseCommandLine(argc, argv);
  subslam::pipeline::ApplyKeepFreedMemoryFlag();
  if (args.size() != 2) {
    std::fprintf(stderr, "%s\n", absl::ProgramUsageMessage().data());
    return 2;
  }
  const std::string command = args[1];
  if (command == "simulate") return Simulate();
  if (command == "run") return Run();
  if (command == "join") return Join();
  if (command == "cli-reference") {
    std::printf("%s", subslam::pipeline::CliReferenceMarkdown().c_str());
    return 0;
  }
  if (command == "scenarios") {
    std::printf("%s\n", absl::StrJoin(subslam::sim::ScenarioNames(), "\n").c_str());
    return 0;
  }
  std::fprintf(stderr, "subslam: unknown command \"%s\"\n%s\n", command.c_str(),
               absl::ProgramUsageMessage().data());
  return 2;
}
