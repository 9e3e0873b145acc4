#include "frontend_flags.h"

#include <string>

#include "absl/flags/flag.h"
#include "backend_flags.h"
#include "subslam/association/data_association.h"
#include "subslam/frontend/ekf_slam.h"
#include "subslam/frontend/fastslam.h"
#include "subslam/frontend/seif_slam.h"
#include "subslam/frontend/submap_policy.h"
#include "subslam/io/input_screening.h"

namespace {
const subslam::frontend::EkfSlamOptions& EkfDefaults() {
  static const subslam::frontend::EkfSlamOptions defaults;
  return defaults;
}
const subslam::frontend::FastSlamOptions& FastSlamDefaults() {
  static const subslam::frontend::FastSlamOptions defaults;
  return defaults;
}
const subslam::frontend::SeifOptions& SeifDefaults() {
  static const subslam::frontend::SeifOptions defaults;
  return defaults;
}
const subslam::frontend::SubmapPolicyOptions& PolicyDefaults() {
  static const subslam::frontend::SubmapPolicyOptions defaults;
  return defaults;
}
}  // namespace

ABSL_FLAG(std::string, association, subslam::association::ToString(EkfDefaults().association),
          "ekfslam / seif / iseif data association: nn | jcbb");
ABSL_FLAG(double, gate, EkfDefaults().landmarks.gate_probability,
          "individual compatibility gate probability (chi2, 2 dof)");
ABSL_FLAG(double, new_landmark_gate, EkfDefaults().landmarks.new_landmark_probability,
          "a detection outside this gate for every landmark starts a new one");
ABSL_FLAG(double, existence_alpha, EkfDefaults().landmarks.existence.detection_probability,
          "existence model: detection probability");
ABSL_FLAG(double, existence_beta, EkfDefaults().landmarks.existence.false_alarm_probability,
          "existence model: false-alarm probability");
ABSL_FLAG(int, particles, FastSlamDefaults().num_particles, "fastslam / rbpf: number of particles");
ABSL_FLAG(uint64_t, filter_seed, FastSlamDefaults().seed,
          "fastslam / rbpf: seed of the particle filter's random draws");
ABSL_FLAG(int, threads, 0,
          "fastslam / rbpf: threads for the per-particle scan update (0: every core); the "
          "results are the same for any number");
ABSL_FLAG(bool, sample_association, FastSlamDefaults().sample_association,
          "fastslam / rbpf: sample the data association instead of maximum likelihood");
ABSL_FLAG(int, landmark_iterations, FastSlamDefaults().landmark_update_iterations,
          "fastslam / rbpf: landmark update iterations (1: EKF, more: iterated EKF)");
ABSL_FLAG(double, resample_ess, FastSlamDefaults().resample_ess_ratio,
          "fastslam / rbpf: resample when N_eff / N falls below this");
ABSL_FLAG(bool, correct_shared_ancestry, FastSlamDefaults().correct_shared_ancestry,
          "fastslam / rbpf: scale the particles' spread in the moment matching by (1 + R) / (1 - R), "
          "R the weighted share of pose noise that pairs of particles hold through common "
          "ancestors (the spread's bias and the mean's Monte Carlo error); false: the mixture's "
          "own moments");
ABSL_FLAG(int, seif_max_active, SeifDefaults().max_active_landmarks,
          "seif / iseif: sparsification bound on the active landmarks (0: never sparsify)");
ABSL_FLAG(std::string, seif_recovery, subslam::frontend::ToString(SeifDefaults().recovery),
          "seif / iseif: mean recovery, relaxation (amortised Gauss-Seidel) | exact (CHOLMOD)");
ABSL_FLAG(int, seif_sweeps, SeifDefaults().relaxation_sweeps, "seif / iseif: relaxation sweeps per scan");
ABSL_FLAG(int, seif_extra_landmarks, SeifDefaults().relaxation_extra_landmarks,
          "seif / iseif: round-robin landmarks relaxed per scan besides the local ones");
ABSL_FLAG(std::string, seif_covariance, subslam::frontend::ToString(SeifDefaults().covariance),
          "seif / iseif: marginal covariances for gating and the pose, markov-blanket | exact");
ABSL_FLAG(std::string, seif_pose_covariance, subslam::frontend::ToString(SeifDefaults().pose_covariance),
          "seif / iseif: the reported pose covariance, markov-blanket (cheap, over-confident) | exact "
          "(the filter's own marginal; one factorisation per scan)");
ABSL_FLAG(int, seif_blanket, SeifDefaults().blanket_max_landmarks,
          "seif / iseif: most landmarks in a scan's Markov blanket (gating covariances)");
ABSL_FLAG(double, seif_candidate_radius, SeifDefaults().candidate_radius_m,
          "seif / iseif: landmarks farther than this from a detection's point are not gated with it [m]");
ABSL_FLAG(int, iseif_period, SeifDefaults().iterated.period_scans,
          "iseif: iterate the measurement update on every N-th scan (the paper: 100 or 500)");
ABSL_FLAG(int, iseif_max_iterations, SeifDefaults().iterated.max_iterations,
          "iseif: linearisations per iterated update");
ABSL_FLAG(double, iseif_stop, SeifDefaults().iterated.stop_change,
          "iseif: adaptive stop, largest change of the pose or an observed landmark [m, rad]");
ABSL_FLAG(int, iseif_exact_recoveries, SeifDefaults().iterated.exact_recoveries,
          "iseif: the first N linearisations of an iterated update are followed by an exact recovery of "
          "the whole mean, later ones by local relaxation");
ABSL_FLAG(double, submap_min_duration, PolicyDefaults().min_duration_s,
          "rbpf: a local map is never closed younger than this [s]");
ABSL_FLAG(double, submap_max_duration, PolicyDefaults().max_duration_s,
          "rbpf: close a local map after this long [s] (0: off)");
ABSL_FLAG(int, submap_max_features, PolicyDefaults().max_features,
          "rbpf: close a local map holding this many confirmed features (0: off)");
ABSL_FLAG(double, submap_min_ess, PolicyDefaults().min_ess_ratio,
          "rbpf: close when N_eff / N falls below this (0: off)");
ABSL_FLAG(double, submap_min_diversity, PolicyDefaults().min_lineage_diversity,
          "rbpf: close when the share of distinct ancestors at the map's first scan falls "
          "below this (0: off)");
ABSL_FLAG(double, submap_max_pose_sigma, PolicyDefaults().max_pose_sigma_ratio,
          "rbpf: close when the local pose sigma exceeds this many sensor sigmas (0: off)");
ABSL_FLAG(double, submap_max_feature_sigma, PolicyDefaults().max_feature_sigma_ratio,
          "rbpf, ekf: do not export a feature more uncertain relative to the map's end pose "
          "(widest axis) than this many times one detection at the sensor's maximum range "
          "(0: export all)");
ABSL_FLAG(double, submap_moving_feature_probability, PolicyDefaults().moving_features.probability,
          "rbpf, ekf: do not export a feature whose detections a static point explains worse than "
          "one moving at a constant velocity, by the likelihood-ratio test at this probability "
          "that a static feature passes (frontend/moving_feature_test.h; 0: off)");
ABSL_FLAG(int, submap_density_features, PolicyDefaults().density_min_features,
          "rbpf: landmark-density rule: close once the map holds this many features and "
          "--submap_density_visible of them are in range (0: off)");
ABSL_FLAG(int, submap_density_visible, PolicyDefaults().density_min_visible, "rbpf: see --submap_density_features");
ABSL_FLAG(bool, submap_delay_ambiguous, PolicyDefaults().delay_while_ambiguous,
          "rbpf: postpone closing while the particles disagree about identities");

ABSL_FLAG(double, sensor_yaw_sigma, FastSlamDefaults().sensor_yaw_sigma,
          "fastslam / rbpf: sigma [rad] of the sensor yaw each particle draws at the start of a local map "
          "and adds to every bearing, so that the maps of an uncalibrated sensor carry its yaw's uncertainty "
          "(0: off; docs/limits.md)");

ABSL_FLAG(double, odometry_scale_sigma, EkfDefaults().odometry.scale_prior_sigma,
          "ekfslam, ekf, fastslam, rbpf: learn the odometry's scale on each control channel, and with "
          "--odometry_offset_sigma an offset on channel 1, as part of the filter's state: sigma of the prior "
          "on each scale around 1 (0: off; frontend/odometry_calibration.h)");
ABSL_FLAG(
    double, odometry_offset_sigma, EkfDefaults().odometry.offset_prior_sigma,
    "ekfslam, ekf, fastslam, rbpf: sigma of the prior on the offset of control channel 1 [rad/s or rad] (0: none)");
ABSL_FLAG(int, innovation_test_window, EkfDefaults().innovation_test.window_scans,
          "ekfslam / ekf: scans per window of the normalised innovation test for divergence (0: off)");
ABSL_FLAG(double, depletion_ess, FastSlamDefaults().depletion_ess_ratio,
          "fastslam / rbpf: an update leaving fewer than this fraction of effective particles counts as depleted");
ABSL_FLAG(bool, drop_unconfirmed_landmarks, subslam::pipeline::MapConfirmationOptions{}.drop_unconfirmed,
          "leave out of the map the landmarks the run's own scans do not detect more often than chance "
          "pairings explain (backend/landmark_persistence.h; the test is reported either way)");
ABSL_FLAG(double, control_spike_sigmas, subslam::io::InputScreeningOptions{}.control_spike_sigmas,
          "a control departing from its neighbours' median by more than this many sigmas (the noise's or the "
          "neighbours' spread, the larger) is a spike, replaced");
ABSL_FLAG(double, time_gap_factor, subslam::io::InputScreeningOptions{}.time_gap_factor,
          "an interval between steps longer than this many median intervals is counted as a time gap");

namespace subslam::cli {

absl::Status SetFrontendOptionsFromFlags(pipeline::RunOptions* options) {
  absl::StatusOr<association::AssociationMethod> method =
      association::AssociationMethodFromString(absl::GetFlag(FLAGS_association));
  if (!method.ok()) return method.status();
  options->ekf.association = *method;
  options->seif.association = *method;
  // The gates, known association and existence model every front-end shares.
  frontend::LandmarkOptions landmarks;
  landmarks.gate_probability = absl::GetFlag(FLAGS_gate);
  landmarks.new_landmark_probability = absl::GetFlag(FLAGS_new_landmark_gate);
  landmarks.existence.detection_probability = absl::GetFlag(FLAGS_existence_alpha);
  landmarks.existence.false_alarm_probability = absl::GetFlag(FLAGS_existence_beta);
  landmarks.known_association = absl::GetFlag(FLAGS_known_association);
  options->ekf.landmarks = landmarks;
  options->fastslam.landmarks = landmarks;
  options->seif.landmarks = landmarks;
  options->policy.min_duration_s = absl::GetFlag(FLAGS_submap_min_duration);
  options->policy.max_duration_s = absl::GetFlag(FLAGS_submap_max_duration);
  options->policy.max_features = absl::GetFlag(FLAGS_submap_max_features);
  options->policy.min_ess_ratio = absl::GetFlag(FLAGS_submap_min_ess);
  options->policy.min_lineage_diversity = absl::GetFlag(FLAGS_submap_min_diversity);
  options->policy.max_pose_sigma_ratio = absl::GetFlag(FLAGS_submap_max_pose_sigma);
  options->policy.max_feature_sigma_ratio = absl::GetFlag(FLAGS_submap_max_feature_sigma);
  options->policy.moving_features.probability = absl::GetFlag(FLAGS_submap_moving_feature_probability);
  options->policy.density_min_features = absl::GetFlag(FLAGS_submap_density_features);
  options->policy.density_min_visible = absl::GetFlag(FLAGS_submap_density_visible);
  options->policy.delay_while_ambiguous = absl::GetFlag(FLAGS_submap_delay_ambiguous);
  options->fastslam.num_particles = absl::GetFlag(FLAGS_particles);
  options->fastslam.seed = absl::GetFlag(FLAGS_filter_seed);
  options->fastslam.num_threads = absl::GetFlag(FLAGS_threads);
  options->fastslam.sample_association = absl::GetFlag(FLAGS_sample_association);
  options->fastslam.resample_ess_ratio = absl::GetFlag(FLAGS_resample_ess);
  options->fastslam.depletion_ess_ratio = absl::GetFlag(FLAGS_depletion_ess);
  options->ekf.innovation_test.window_scans = absl::GetFlag(FLAGS_innovation_test_window);
  options->ekf.odometry.scale_prior_sigma = absl::GetFlag(FLAGS_odometry_scale_sigma);
  options->ekf.odometry.offset_prior_sigma = absl::GetFlag(FLAGS_odometry_offset_sigma);
  options->fastslam.odometry = options->ekf.odometry;
  options->inputs.control_spike_sigmas = absl::GetFlag(FLAGS_control_spike_sigmas);
  options->map_confirmation.drop_unconfirmed = absl::GetFlag(FLAGS_drop_unconfirmed_landmarks);
  options->inputs.time_gap_factor = absl::GetFlag(FLAGS_time_gap_factor);
  options->fastslam.landmark_update_iterations = absl::GetFlag(FLAGS_landmark_iterations);
  options->fastslam.sigma_signature = absl::GetFlag(FLAGS_sigma_signature);
  options->fastslam.correct_shared_ancestry = absl::GetFlag(FLAGS_correct_shared_ancestry);
  options->fastslam.sensor_yaw_sigma = absl::GetFlag(FLAGS_sensor_yaw_sigma);
  options->seif.max_active_landmarks = absl::GetFlag(FLAGS_seif_max_active);
  auto recovery = frontend::MeanRecoveryFromString(absl::GetFlag(FLAGS_seif_recovery));
  if (!recovery.ok()) return recovery.status();
  options->seif.recovery = *recovery;
  auto covariance = frontend::CovarianceRecoveryFromString(absl::GetFlag(FLAGS_seif_covariance));
  if (!covariance.ok()) return covariance.status();
  options->seif.covariance = *covariance;
  auto pose_covariance = frontend::CovarianceRecoveryFromString(absl::GetFlag(FLAGS_seif_pose_covariance));
  if (!pose_covariance.ok()) return pose_covariance.status();
  options->seif.pose_covariance = *pose_covariance;
  options->seif.relaxation_sweeps = absl::GetFlag(FLAGS_seif_sweeps);
  options->seif.relaxation_extra_landmarks = absl::GetFlag(FLAGS_seif_extra_landmarks);
  options->seif.candidate_radius_m = absl::GetFlag(FLAGS_seif_candidate_radius);
  options->seif.blanket_max_landmarks = absl::GetFlag(FLAGS_seif_blanket);
  options->seif.iterated.period_scans = absl::GetFlag(FLAGS_iseif_period);
  options->seif.iterated.max_iterations = absl::GetFlag(FLAGS_iseif_max_iterations);
  options->seif.iterated.stop_change = absl::GetFlag(FLAGS_iseif_stop);
  options->seif.iterated.exact_recoveries = absl::GetFlag(FLAGS_iseif_exact_recoveries);
  return absl::OkStatus();
}

}  // namespace subslam::cli
