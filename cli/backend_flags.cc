#include "backend_flags.h"

#include <optional>
#include <string>

#include "absl/flags/flag.h"
#include "enum_flags.h"
#include "subslam/association/landmark_revision.h"
#include "subslam/backend/ceres_solver.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/ekf_joiner.h"
#include "subslam/frontend/fastslam.h"

namespace {
const subslam::backend::EifJoinerOptions& EifDefaults() {
  static const subslam::backend::EifJoinerOptions defaults;
  return defaults;
}
}  // namespace

ABSL_FLAG(std::string, backend, "eif",
          "rbpf / ekf: how local maps are joined: eif (the incremental EIF) | none (chained end to start, "
          "not joined) | ceres "
          "(EIF association, then a Ceres solve of the whole graph at the end) | ekf (dense "
          "EKF map joining, the baseline) | tree-ekf | tree-eif (binary-tree joining) | tree-ceres "
          "(binary-tree EIF joins, then the Ceres solve)");
ABSL_FLAG(std::string, ekf_fusion, "zero-noise",
          "ekf back-end: how matched features are fused: zero-noise (HybridSLAM: augment, "
          "constrain copy = landmark, drop the copy) | conditional (the EIF's update in "
          "covariance form)");
ABSL_FLAG(bool, tree_batch, false,
          "tree-ekf / tree-eif / tree-ceres: keep the leaves and build the tree level by level at the end "
          "(default: running, a binary counter that joins pairs as they complete)");
ABSL_FLAG(bool, tree_online_fold, false,
          "tree-ekf / tree-eif / tree-ceres: the online pose from the whole map folded after every local map "
          "(as the sequential joiner's) instead of the tree's nodes chained; costs a fold per local map");
ABSL_FLAG(bool, ekf_keep_anchors, true,
          "ekf back-end: keep every anchor in the state (false: marginalise each start "
          "anchor once joined, as the papers' baseline)");
ABSL_FLAG(std::string, ceres_method, "lm", "ceres: lm (Levenberg-Marquardt) | dogleg | gn (Gauss-Newton)");
ABSL_FLAG(std::string, ceres_loss, "none", "ceres: robust loss per local map: none | huber | cauchy");
ABSL_FLAG(double, ceres_loss_scale, 3.0, "ceres: robust loss scale, in whitened units");
ABSL_FLAG(int, ceres_every, 0, "ceres: also solve the graph every K joins during the run (0: at the end only)");
ABSL_FLAG(std::optional<bool>, sensor_yaw_calibration, std::nullopt,
          "back-ends that join (run and join): =true calibrates the sensor's yaw online from the "
          "features consecutive local maps share and joins each map turned by the estimate "
          "(counters sensor_yaw_correction, _sigma, _pairs; docs/limits.md); unset: on, except for "
          "a run given --sensor_yaw, whose yaw is taken as calibrated");
ABSL_FLAG(double, sensor_yaw_prior_sigma, subslam::backend::SensorYawCalibrationOptions{}.prior_sigma_rad,
          "the online yaw calibration's prior sigma [rad] (zero mean)");
// On in the tool, which runs where a second core is there to take the joins; a library
// caller asks for it (BackendOptions::background is off by default).
ABSL_FLAG(bool, join_in_background, true,
          "run: join each closed local map on a thread of its own while the front-end builds the "
          "next (the online pose one join behind; while a join runs, rbpf leaves it a core; the "
          "final trajectory and map are unchanged); false: join inside the scan that closed the "
          "map, the online pose using its joined anchor at once");
ABSL_FLAG(double, join_anchor_radius, EifDefaults().association.anchor_search_radius_m,
          "eif: earlier local maps with an anchor within this of the start anchor give "
          "association candidates [m] (2·TH1)");
ABSL_FLAG(double, join_landmark_radius, EifDefaults().association.landmark_search_radius_m,
          "eif: candidate landmarks within this of a feature [m] (TH2)");
ABSL_FLAG(double, join_gate, EifDefaults().association.gate_probability, "eif: association gate probability (chi2)");
ABSL_FLAG(bool, join_jcbb, EifDefaults().association.joint_compatibility,
          "eif: joint compatibility (JCBB) for the local map's features; false: nearest neighbour");
ABSL_FLAG(int, join_min_loop_pairings, EifDefaults().association.min_loop_pairings,
          "accept a loop closure (pairings with landmarks the last local maps did not see) only "
          "with at least this many pairings (<= 1: always)");
ABSL_FLAG(bool, join_loop_ambiguity, EifDefaults().association.loop_ambiguity_test,
          "eif: drop a loop closure when another jointly compatible hypothesis, without its loop "
          "pairings, pairs as many features with old landmarks (JCBB)");
ABSL_FLAG(bool, join_keep_certain_loop_pairings, EifDefaults().association.keep_certain_loop_pairings,
          "when the loop tests drop a closure, keep the pairings whose landmark is known relative to "
          "the start anchor to 3 sigma below --join_loop_test_sigma (no chance fit)");
ABSL_FLAG(double, join_loop_test_sigma, EifDefaults().association.loop_test_min_sigma_radius_m,
          "apply --join_min_loop_pairings only when 3 sigma of the start anchor's position is at "
          "least this [m]");
ABSL_FLAG(bool, join_loop_test_spacing, EifDefaults().association.loop_test_scaled_by_spacing,
          "the loop tests' radius is the smaller of --join_loop_test_sigma and the median "
          "nearest-neighbour distance among the map's candidate landmarks (a lattice, a dense room)");
ABSL_FLAG(bool, join_merge, EifDefaults().revision.merge,
          "every back-end: merge two global landmarks once the estimate shows they are one "
          "point (chi2 test on their difference with their joint marginal; never two that one "
          "local map holds apart; mutual best partners, unambiguous, their relative position "
          "known to 3 sigma below --join_loop_test_sigma)");
ABSL_FLAG(bool, join_merge_loops, EifDefaults().revision.merge_loops,
          "also merge pairs known relative to each other only to metres when at least "
          "--join_min_loop_pairings of them are jointly compatible and unambiguous (a loop "
          "closure too thin for any one local map)");
ABSL_FLAG(bool, join_merge_unresolved, EifDefaults().revision.merge_unresolved,
          "also merge a pair that a single local map could not tell apart (the test with each "
          "landmark's typical feature covariance)");
ABSL_FLAG(bool, join_merge_density, EifDefaults().revision.merge_by_density,
          "also merge a pair the merge test holds apart, inside --join_merge_density_gate, "
          "when one point explains their difference better than two points at the map's "
          "local density (landmarks within 10 m)");
ABSL_FLAG(double, join_merge_density_gate, EifDefaults().revision.density_gate_probability,
          "density test: chi2 (2 dof) probability of the outer gate, beyond which a pair is "
          "never merged");
ABSL_FLAG(double, join_merge_gate, EifDefaults().revision.merge_probability,
          "merge test: chi2 (2 dof) acceptance probability of 'the same point'");
ABSL_FLAG(bool, join_split, EifDefaults().revision.split,
          "every back-end: split a feature whose residual fails its outlier test off to a "
          "landmark of its own (ekf / tree-ekf: by joining every map again)");
ABSL_FLAG(double, join_split_level, EifDefaults().revision.split_probability,
          "split test: family-wise confidence over the features tested in a pass (Bonferroni)");
ABSL_FLAG(int, join_revise_every, EifDefaults().revision.every_joins,
          "also run the merge and split tests every K joins (besides after relinearisations, "
          "whole-map joins and at the end; 0: not on a schedule)");
ABSL_FLAG(int, join_loop_confirmation_maps, EifDefaults().association.loop_confirmation_maps,
          "eif, and the tree joiners' whole-map joins: undo a loop closure made under an "
          "uncertain anchor unless one of this many next local maps pairs a feature with "
          "another old landmark (0: off)");
ABSL_FLAG(bool, join_confirm_thin_loops, EifDefaults().association.confirm_thin_loops,
          "eif and ceres: hold a loop closure with fewer than --join_min_loop_pairings pairings (under an "
          "uncertain, not lost, anchor) until the next --join_loop_confirmation_maps local maps pair "
          "that many other old landmarks, and undo it otherwise (false: drop it at once)");
ABSL_FLAG(double, join_map_rotation_sigma, EifDefaults().association.map_rotation_sigma_rad,
          "every joiner: test each local map for a rotation about its start, searched within 3 "
          "sigma [rad] of none, against the landmarks the previous local maps saw (the tree "
          "joiners: the previous local map's), and join a map that fails the test rotated back "
          "and widened by the rotation's spread (0: off)");
ABSL_FLAG(double, join_map_rotation_level, EifDefaults().association.map_rotation_probability,
          "rotation test (--join_map_rotation_sigma): chi2 (1 dof) probability that a map that is "
          "not rotated passes");
ABSL_FLAG(double, join_map_rotation_spread_level, EifDefaults().association.map_rotation_spread_probability,
          "every joiner: while the count of rotation-test fits beyond its bound rejects, at this "
          "level (spent over the fits), the binomial of maps as certain of their rotation as their "
          "covariances say, join each next map with its features widened by the fits' "
          "maximum-likelihood spread (counter join_maps_spread; 0: off)");
ABSL_FLAG(bool, validate_joins, EifDefaults().validate_joins,
          "eif: test each join's normalised residual against chi2 and undo a failing one "
          "(the map is joined again without associations)");
ABSL_FLAG(int, relinearize_every, EifDefaults().relinearize_every,
          "eif: relinearise to convergence every K joins (0: never during the run)");
ABSL_FLAG(bool, eif_incremental, EifDefaults().incremental_factorization,
          "eif: update the factor of the information matrix by each join's rank update "
          "(false: refactorise it at every join)");
ABSL_FLAG(double, eif_recovery_threshold, EifDefaults().recovery_change_threshold,
          "eif: after a join's incremental update, carry the estimate's change down the elimination tree "
          "only while it exceeds this (m, rad); 0: solve afresh at every join");
ABSL_FLAG(subslam::backend::FillReducingOrdering, eif_ordering, EifDefaults().ordering,
          "eif: fill-reducing ordering of a full factorisation: amd | nested_dissection (METIS) | "
          "auto (nested dissection where AMD's factor would cost >= 50 flops per entry)");
ABSL_FLAG(bool, eif_bound_marginals, EifDefaults().bound_candidate_marginals,
          "eif: skip the covariance recovery of association candidates that fail the gate "
          "even under an upper bound on their marginal (same decisions, less work)");
ABSL_FLAG(double, relinearize_tolerance, EifDefaults().relinearize_tolerance,
          "eif: a relinearisation iterates until no state entry moves by more than this (m, rad)");
ABSL_FLAG(double, relinearize_step_chi2, EifDefaults().relinearize_step_chi2,
          "eif: ... or until the step's squared Mahalanobis length (dx' Lambda dx, chi-square "
          "units) falls below this (0: off)");
ABSL_FLAG(bool, relinearize_predict, EifDefaults().predict_convergence,
          "eif: stop a relinearisation when the next Gauss-Newton step, solved with the last "
          "factor, is below half --relinearize_tolerance or a quarter of "
          "--relinearize_step_chi2 (saves the confirming factorisation)");
ABSL_FLAG(int, max_relinearizations, EifDefaults().max_relinearizations,
          "eif: at most this many iterations per relinearisation");
ABSL_FLAG(int, relinearize_max_rises, EifDefaults().divergence_rises,
          "eif: cost rises in a row that end a relinearisation at its best iterate "
          "(1: monotone Gauss-Newton, 0: never)");
ABSL_FLAG(double, relinearize_heading_change, EifDefaults().relinearize_heading_change,
          "eif: also relinearise after a join when an anchor's heading has moved this far [rad] "
          "from where one of its factors was linearised (0: off, the default)");
ABSL_FLAG(double, relinearize_linearization_chi2, EifDefaults().relinearize_linearization_chi2,
          "eif: relinearise after a join when some factor's linear model is off at the current "
          "estimate by more than this, whitened by its local map's covariance (chi2 units; 0: off)");
ABSL_FLAG(bool, single_linearization, false,
          "eif: the single-linearisation EIF of Combined SLAM: no relinearisation at "
          "all, whatever the relinearize_* flags say");
ABSL_FLAG(bool, relinearize_at_end, EifDefaults().relinearize_at_end,
          "eif: relinearise to convergence after the last join (ceres: off, Ceres solves there)");
ABSL_FLAG(bool, known_association, false,
          "associate by the true ids (simulations; a study option, as Combined SLAM §7): "
          "run: every front-end pairs detections by their truth_id and the back-end joins "
          "local-map features by theirs; join: features by their truth_id");
ABSL_FLAG(double, sigma_signature, subslam::frontend::FastSlamOptions{}.sigma_signature,
          "fastslam / rbpf: sigma of the signature cue (0: cue off)");

namespace subslam::cli {
namespace {

association::LandmarkRevisionOptions RevisionOptionsFromFlags() {
  association::LandmarkRevisionOptions o;
  o.merge = absl::GetFlag(FLAGS_join_merge);
  o.merge_unresolved = absl::GetFlag(FLAGS_join_merge_unresolved);
  o.merge_by_density = absl::GetFlag(FLAGS_join_merge_density);
  o.density_gate_probability = absl::GetFlag(FLAGS_join_merge_density_gate);
  o.merge_loops = absl::GetFlag(FLAGS_join_merge_loops);
  o.merge_probability = absl::GetFlag(FLAGS_join_merge_gate);
  o.split = absl::GetFlag(FLAGS_join_split);
  o.split_probability = absl::GetFlag(FLAGS_join_split_level);
  o.every_joins = absl::GetFlag(FLAGS_join_revise_every);
  return o;
}

backend::EifJoinerOptions EifOptionsFromFlags() {
  backend::EifJoinerOptions o;
  o.association.anchor_search_radius_m = absl::GetFlag(FLAGS_join_anchor_radius);
  o.association.landmark_search_radius_m = absl::GetFlag(FLAGS_join_landmark_radius);
  o.association.gate_probability = absl::GetFlag(FLAGS_join_gate);
  o.association.joint_compatibility = absl::GetFlag(FLAGS_join_jcbb);
  o.association.min_loop_pairings = absl::GetFlag(FLAGS_join_min_loop_pairings);
  o.association.loop_ambiguity_test = absl::GetFlag(FLAGS_join_loop_ambiguity);
  o.association.keep_certain_loop_pairings = absl::GetFlag(FLAGS_join_keep_certain_loop_pairings);
  o.association.loop_test_min_sigma_radius_m = absl::GetFlag(FLAGS_join_loop_test_sigma);
  o.association.loop_test_scaled_by_spacing = absl::GetFlag(FLAGS_join_loop_test_spacing);
  o.association.loop_confirmation_maps = absl::GetFlag(FLAGS_join_loop_confirmation_maps);
  o.association.confirm_thin_loops = absl::GetFlag(FLAGS_join_confirm_thin_loops);
  o.association.map_rotation_sigma_rad = absl::GetFlag(FLAGS_join_map_rotation_sigma);
  o.association.map_rotation_probability = absl::GetFlag(FLAGS_join_map_rotation_level);
  o.association.map_rotation_spread_probability = absl::GetFlag(FLAGS_join_map_rotation_spread_level);
  o.revision = RevisionOptionsFromFlags();
  o.validate_joins = absl::GetFlag(FLAGS_validate_joins);
  o.relinearize_every = absl::GetFlag(FLAGS_relinearize_every);
  o.relinearize_at_end = absl::GetFlag(FLAGS_relinearize_at_end);
  o.relinearize_tolerance = absl::GetFlag(FLAGS_relinearize_tolerance);
  o.relinearize_step_chi2 = absl::GetFlag(FLAGS_relinearize_step_chi2);
  o.max_relinearizations = absl::GetFlag(FLAGS_max_relinearizations);
  o.predict_convergence = absl::GetFlag(FLAGS_relinearize_predict);
  o.divergence_rises = absl::GetFlag(FLAGS_relinearize_max_rises);
  o.relinearize_heading_change = absl::GetFlag(FLAGS_relinearize_heading_change);
  o.relinearize_linearization_chi2 = absl::GetFlag(FLAGS_relinearize_linearization_chi2);
  o.incremental_factorization = absl::GetFlag(FLAGS_eif_incremental);
  o.recovery_change_threshold = absl::GetFlag(FLAGS_eif_recovery_threshold);
  o.bound_candidate_marginals = absl::GetFlag(FLAGS_eif_bound_marginals);
  o.ordering = absl::GetFlag(FLAGS_eif_ordering);
  o.association.sigma_signature = absl::GetFlag(FLAGS_sigma_signature);
  o.association.known_association = absl::GetFlag(FLAGS_known_association);
  if (absl::GetFlag(FLAGS_single_linearization)) o = o.SingleLinearization();
  return o;
}

// Association options are the EIF's, so both joiners associate alike.
absl::StatusOr<backend::EkfJoinerOptions> EkfJoinOptionsFromFlags() {
  backend::EkfJoinerOptions o;
  o.association = EifOptionsFromFlags().association;
  o.revision = RevisionOptionsFromFlags();  // (the EIF's single linearisation turns its own off)
  absl::StatusOr<backend::EkfFusion> fusion = backend::EkfFusionFromString(absl::GetFlag(FLAGS_ekf_fusion));
  if (!fusion.ok()) return fusion.status();
  o.fusion = *fusion;
  o.keep_anchors = absl::GetFlag(FLAGS_ekf_keep_anchors);
  if (absl::Status s = o.Validate(); !s.ok()) return s;
  return o;
}

absl::StatusOr<backend::CeresSolveOptions> CeresOptionsFromFlags() {
  backend::CeresSolveOptions o;
  absl::StatusOr<backend::CeresMethod> method = backend::CeresMethodFromString(absl::GetFlag(FLAGS_ceres_method));
  if (!method.ok()) return method.status();
  o.method = *method;
  absl::StatusOr<backend::RobustLoss> loss = backend::RobustLossFromString(absl::GetFlag(FLAGS_ceres_loss));
  if (!loss.ok()) return loss.status();
  o.loss = *loss;
  o.loss_scale = absl::GetFlag(FLAGS_ceres_loss_scale);
  if (absl::Status s = o.Validate(); !s.ok()) return s;
  return o;
}

}  // namespace

absl::StatusOr<pipeline::BackendOptions> BackendOptionsFromFlags(bool sensor_yaw_given) {
  pipeline::BackendOptions o;
  auto kind = pipeline::BackendFromString(absl::GetFlag(FLAGS_backend));
  if (!kind.ok()) return kind.status();
  o.kind = *kind;
  o.eif = EifOptionsFromFlags();
  auto ekf = EkfJoinOptionsFromFlags();
  if (!ekf.ok()) return ekf.status();
  o.ekf = *ekf;
  o.tree.running = !absl::GetFlag(FLAGS_tree_batch);
  o.tree.online_anchor_from_whole_map = absl::GetFlag(FLAGS_tree_online_fold);
  auto ceres = CeresOptionsFromFlags();
  if (!ceres.ok()) return ceres.status();
  o.ceres = *ceres;
  o.ceres_every = absl::GetFlag(FLAGS_ceres_every);
  o.background = absl::GetFlag(FLAGS_join_in_background);
  o.sensor_yaw.enabled = absl::GetFlag(FLAGS_sensor_yaw_calibration).value_or(!sensor_yaw_given);
  o.sensor_yaw.prior_sigma_rad = absl::GetFlag(FLAGS_sensor_yaw_prior_sigma);
  if (absl::Status st = o.Validate(); !st.ok()) return st;
  return o;
}

}  // namespace subslam::cli
