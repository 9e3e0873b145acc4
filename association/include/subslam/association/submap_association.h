// Data association of a new local map's features to the global landmarks (Combined SLAM,
// Algorithm 1), shared by every joiner so they can be compared on identical input:
//  1. candidate landmarks: those of earlier local maps whose start or end anchor lies
//     within `anchor_search_radius_m` (2·TH1) of the new map's start anchor, and within
//     `landmark_search_radius_m` (TH2) of a feature's world position. Both radii grow by
//     three standard deviations of the start anchor's marginal uncertainty (position, and
//     heading × the feature's distance; ours), so a loop is still found after a long drift;
//  2. the joint marginal covariance Σ of the start anchor and the candidates only is asked
//     of the joiner (sparse solves in the EIF, a sub-block in the EKF). A joiner that can
//     bound the [start anchor, candidate] marginal from above cheaply (the EIF: the exact
//     cross-covariance and the candidate's marginal when last recovered, which bounds
//     today's because Λ only grows between relinearisations) lets the associator drop,
//     before recovering their marginals, the candidates that fail step 3's gate even
//     under the bound: Σ ⪯ Σ⁺ gives S ⪯ S⁺ and νᵀS⁻¹ν ≥ νᵀ(S⁺)⁻¹ν, so no pairing the
//     exact test would keep is lost and the decisions are unchanged;
//  3. each pair's innovation ν = P_s⁻¹ · L_j − l_i (start frame, metres) with
//     S = J Σ Jᵀ + Q_ii is gated at χ²₂(gate_probability) (plus the signature cue when
//     both have one: (Δs/σ)² added to d² and 3 dof);
//  4. the hypothesis is chosen by joint compatibility (JCBB, default: the pairings' joint
//     innovation, with the local map's own feature correlations Q_ik, must pass χ²_{2k})
//     or by nearest neighbour; one-to-one either way;
//  5. (ours) a loop closure with too few pairings, made while the start anchor is very
//     uncertain, is dropped (its features become new landmarks): see min_loop_pairings.
// Or known association: features with the same truth_id are the same landmark
// (evaluation studies; unknown or negative truth ids make new landmarks).
//
// The associator keeps what association needs beyond the graph: the mean signature of
// the features joined to each landmark, and the landmark of each truth id. It is a value
// type, so a joiner that may undo a join copies it.
#ifndef SUBSLAM_ASSOCIATION_SUBMAP_ASSOCIATION_H_
#define SUBSLAM_ASSOCIATION_SUBMAP_ASSOCIATION_H_

#include <Eigen/Core>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "subslam/association/map_rotation_spread.h"
#include "subslam/core/local_submap.h"
#include "subslam/core/submap_graph.h"

namespace subslam::association {

using Matrix5d = Eigen::Matrix<double, 5, 5>;

struct SubmapAssociationOptions {
  // 2·TH1 with TH1 ≈ the sensor range, and TH2 (metres).
  double anchor_search_radius_m = 60.0;
  double landmark_search_radius_m = 10.0;
  double gate_probability = 0.99;  // χ²₂ individual gate (and JCBB's joint gate)
  // true: joint compatibility (JCBB over the map's features); false: nearest neighbour.
  bool joint_compatibility = true;
  long jcbb_max_nodes = 20000;
  // Signature cue: σ of the difference of two signatures (0: off).
  double sigma_signature = 0.0;
  bool known_association = false;  // associate by truth_id instead
  // Loop closures: pairings with landmarks that none of the last `recent_maps` local maps
  // saw are kept only if there are at least `min_loop_pairings` of them (≤ 1: no test;
  // but see keep_certain_loop_pairings),
  // when 3σ of the start anchor's position is at least `loop_test_min_sigma_radius_m`
  // (the drift is large against the landmark spacing, and a hypothesis with one or two
  // old landmarks fits by chance). The defaults' evidence: docs/design/association.md,
  // "Why the defaults".
  int min_loop_pairings = 4;
  // With JCBB, in the same regime: a loop closure is also dropped when, with its loop
  // pairings struck out, another jointly compatible hypothesis still has at least
  // min_loop_pairings of them (two explanations of the same features; "local
  // uniqueness"): where two hypotheses explain the same features, neither is evidence.
  bool loop_ambiguity_test = true;
  // When either test drops a loop closure's pairings, keep those whose landmark's
  // position relative to the start anchor is known to 3σ < loop_test_min_sigma_radius_m
  // (through the [anchor, landmark] marginal): a landmark seen a few maps ago is still
  // tightly correlated with the anchor, and no chance fit. They still count towards
  // min_loop_pairings. Without them a loop's well-known landmarks would be duplicated
  // whenever its few uncertain ones are dropped.
  bool keep_certain_loop_pairings = true;
  int recent_maps = 2;
  double loop_test_min_sigma_radius_m = 5.0;
  // The loop tests' radius scaled by the landmarks' spacing: the regime (and the
  // certain-pairing radius) uses the smaller of loop_test_min_sigma_radius_m and the median
  // nearest-neighbour distance among the map's candidate landmarks. Where landmarks stand
  // closer than the radius (a lattice, a dense room), a start anchor known to 3σ of a few
  // spacings can already put a map one spacing off with every feature on a landmark.
  bool loop_test_scaled_by_spacing = true;
  // Loop-closure confirmation (beyond the papers).
  //  - When: a loop closure made while the start anchor is lost, 3σ of its position at
  //    least `loop_confirmation_min_sigma_radius_m` (default 2·TH1: the map could lie
  //    anywhere in an area wider than the sensor's reach, so matching it is
  //    relocalisation, where chance fits of a few features abound).
  //  - Rule: it stands only if one of the next `loop_confirmation_maps` local maps pairs
  //    a feature with an old landmark the closure did not use — one that existed before
  //    the closing map, that the recent maps before it did not see, and that no map since
  //    has seen. A true closure leads on into mapped ground; a chance fit finds nothing
  //    more.
  //  - Otherwise: the closing map is associated again without its loop pairings (its
  //    features become new landmarks), and the maps after it again after it. The
  //    sequential EIF applies it across joins (eif_joiner.h: it undoes the joins since;
  //    a closure still waiting at Finish() stands); a whole-map join applies it across
  //    the groups of its association, and undoes a closure still waiting after the last
  //    group (the maps that would confirm it come in a later join). After a group's
  //    closure the later groups are gated about the start anchor the decided pairings
  //    imply (an iterated Kalman update of the anchor alone), not about the prior's: a
  //    whole map hundreds of metres long, under a heading off by tenths of a radian,
  //    otherwise puts its far features metres off through the linearisation, and no
  //    correct closure is confirmed.
  //  - Scope: it rides on the loop regime (min_loop_pairings > 1). 0 maps: off.
  //  - Evidence: docs/design/association.md, "Why the defaults".
  int loop_confirmation_maps = 3;
  double loop_confirmation_min_sigma_radius_m = 60.0;
  // Thin closures wait for confirmation (beyond the papers; the sequential EIF).
  //  - When: a local map pairs fewer than min_loop_pairings features with old landmarks
  //    under an uncertain start anchor (the thin-closure test above), but not a lost one
  //    (3σ below loop_confirmation_min_sigma_radius_m: relocalisation needs its pairings
  //    in one map), and no other hypothesis pairs as many once its loop pairings are
  //    struck out. Maps of few features (a sensor that detects seldom, or a sparse
  //    world) can never bring min_loop_pairings in one map, and a loop missed there stays
  //    missed.
  //  - Rule: the closure is held, and stands once the next `loop_confirmation_maps` local
  //    maps (each associated given it) have paired at least min_loop_pairings old
  //    landmarks it did not use, as one map would have had to; otherwise it is undone as
  //    an unconfirmed closure is (above), also when the run ends first. The held
  //    pairings do not count: the later maps are gated given them.
  //  - Joiners that cannot undo a join (EKF, whole-map joins) drop thin closures (Ceres
  //    joins through the sequential EIF, and holds them as it does).
  bool confirm_thin_loops = true;
  // Rotated local maps (beyond the papers; local_map_rotation.h).
  //  - Test: the map's rotation δ about its start is fitted to its features' pairings with
  //    the landmarks the last recent_maps local maps saw (found by a vote over rotations
  //    within ±3σ, σ = map_rotation_sigma_rad, then JCBB with the map rotated by δ and
  //    widened by σ, then Gauss-Newton on δ; at least two pairings), and the likelihood
  //    ratio d²(0) − d²(δ̂) of those pairings is tested at χ²₁(map_rotation_probability):
  //    the probability that a map that is not rotated passes.
  //  - Rule: a map that fails it is associated again, and joined, rotated by δ̂ and widened
  //    by a rotation of σ̂ about its start, σ̂² = δ̂² − var δ̂ (the rotation's spread as the
  //    data show it): the graph then weighs its rotation against the landmarks it shares
  //    with its neighbours (SubmapAssociation::map_rotated). Not for whole-map groups
  //    (the tree joiners test each local map against the one before it instead,
  //    tree_joiner.h) or nearest neighbour. 0: off.
  //  - Why: a particle filter's local map over a sharp turn can be wrong in its heading
  //    after the turn beyond its covariance (sample impoverishment); its features then miss
  //    the previous map's landmarks (duplicates), and its stiff factor bends the trajectory
  //    so that a later loop is not found. σ = 0.3 rad lets the vote reach 0.9 rad, several
  //    times the rotations such maps were measured to carry (docs/design/association.md).
  double map_rotation_sigma_rad = 0.3;
  double map_rotation_probability = 0.99;
  // The spread of the maps' own rotation (map_rotation_spread.h): the count of the rotation
  // test's fits beyond its bound among the maps joined so far, tested against the binomial
  // of consistent maps at this probability (spent over the fits); while it is rejected,
  // each next map is joined with its features widened by the fits' maximum-likelihood
  // spread. Needs the rotation test. 0: off.
  double map_rotation_spread_probability = 0.999;

  absl::Status Validate() const;
};

// What the joiner reports about one association.
struct SubmapAssociation {
  std::vector<int> landmark_of_feature;  // −1: a new landmark
  bool jcbb_truncated = false;           // JCBB hit its node budget
  // A loop closure with too few pairings: how many it had (those kept as certain, see
  // keep_certain_loop_pairings, included).
  int loop_pairings_dropped = 0;
  bool loop_ambiguous = false;  // a loop closure dropped by loop_ambiguity_test
  // A thin closure (fewer than min_loop_pairings loop pairings) that no other hypothesis
  // explains as well (with confirm_thin_loops, joint compatibility and loop_ambiguity_test;
  // not for whole-map groups): its dropped uncertain pairings, (feature, landmark), for a
  // joiner that can hold the closure until the next local maps confirm it (eif_joiner.h).
  // Empty otherwise.
  bool thin_loop_unambiguous = false;
  std::vector<std::pair<int, int>> thin_loop_pairings;
  // Whole-map joins: loop closures by a group that a later group did or did not confirm
  // (loop_confirmation_maps; an unconfirmed one was undone).
  int loop_closures_confirmed = 0;
  int loop_closures_unconfirmed = 0;
  // A loop closure kept under an uncertain start anchor (the regime of the loop tests):
  // the features paired with landmarks no recent map saw (empty: none kept, or the anchor
  // was certain).
  std::vector<int> uncertain_loop_features;
  // The rotation test (map_rotation_sigma_rad): its statistic (NaN: not reached), and
  // whether the map failed it, with the rotation fitted and the spread it is widened by.
  // Then the association is that of the map the joiner joins (RotatedBack).
  double map_rotation_statistic = NAN;
  bool map_rotated = false;
  double map_rotation_rad = 0.0;
  double map_widening_rad = 0.0;
  // The test's fit of the map as associated, with its variance (NaN: not reached): what
  // StampRotationFit puts into the map joined.
  double map_rotation_fit_rad = NAN;
  double map_rotation_fit_variance_rad2 = NAN;
  // The joint innovation d² of the pairings the joint-compatibility search chose (before
  // the loop tests strike any), and its degrees of freedom (2 per pairing; 0: none, or
  // nearest neighbour, or a whole map's grouped search): how well the local map agrees
  // with the map where it is paired — χ² with that dof for consistent maps, truncated
  // from above by the joint gate.
  double pairings_d2 = 0.0;
  int pairings_dof = 0;
  double covariance_seconds = 0.0;  // spent in the joiner's covariance recovery
  int candidates = 0;               // candidate landmarks (step 1)
  int candidates_bounded_out = 0;   // of those, dropped under the joiner's bound (step 2)
  // The start anchor's marginal covariance before the join (zero for the fixed P0;
  // unset under known association).
  Eigen::Matrix3d start_anchor_covariance = Eigen::Matrix3d::Constant(NAN);
  // √ of the largest eigenvalue of its position block [m] (unset under known association).
  double start_position_sigma_m = NAN;
};

// The features of each local map of `graph` (its landmarks, as SummarizeAsLocalSubmap
// numbers them), in the order the maps were joined: Associate's groups for a whole-map join.
std::vector<std::vector<int>> WholeMapGroups(const SubmapGraph& graph);

// The local map `s` as a joiner joins it after association `a`, when the rotation test
// found it rotated: WidenedByRotation(RotatedAboutStart(s, a.map_rotation_rad),
// a.map_widening_rad) (local_map_rotation.h). nullopt when `s` is joined as it is: not
// found rotated, or rotated back already (a map taken back from the graph, whose first
// association is replayed after an undone loop closure).
std::optional<LocalSubmap> RotatedBack(const LocalSubmap& s, const SubmapAssociation& a);

// `s` carrying the rotation fit of association `a` (SubmapAssociation::map_rotation_fit_rad)
// unless it carries one from an earlier join (LocalSubmap::rotation_fit_rad).
void StampRotationFit(const SubmapAssociation& a, LocalSubmap* s);

class SubmapAssociator {
 public:
  // Joint marginal covariance of the listed anchors then landmarks (3 rows per anchor,
  // 2 per landmark; a fixed anchor has zero rows and columns).
  using JointCovarianceFn =
      std::function<Eigen::MatrixXd(const std::vector<int>& anchors, const std::vector<int>& landmarks)>;
  // For each landmark, the joint marginal covariance of [anchor, landmark] (5 × 5), without
  // the landmarks' cross-covariances: what individual compatibility needs. Optional; when
  // given, the joint covariance is asked only for the individually compatible landmarks.
  using PairCovarianceFn = std::function<std::vector<Matrix5d>(int anchor, const std::vector<int>& landmarks)>;
  // For each landmark, an upper bound (Loewner order) on the 5 × 5 marginal of
  // [anchor, landmark], or nullopt when the joiner has none. Optional, used only with a
  // PairCovarianceFn.
  using PairBoundFn =
      std::function<std::vector<std::optional<Matrix5d>>(int anchor, const std::vector<int>& landmarks)>;

  explicit SubmapAssociator(const SubmapAssociationOptions& options);

  const SubmapAssociationOptions& options() const { return options_; }

  // Associates the features of `submap`, which starts at anchor `start_anchor` of `graph`
  // (the current estimate), with the landmarks of `graph`. `anchor_prefilter` false skips
  // step 1's anchor test (every landmark near a feature is a candidate): for joining a
  // whole map, whose features lie far from its start anchor (tree joining).
  // `groups` (optional, with joint compatibility): the submap is a whole map and these are
  // the features of each of its local maps, in time order (WholeMapGroups). Steps 4-5 then
  // run group by group, each given the pairings kept before it, with the loop tests on
  // each group's own pairings: one JCBB over hundreds of features would exhaust its node
  // budget, and the loop tests, made for one local map's few features, would weigh a whole
  // map's pairings against chance fits of its many others.
  SubmapAssociation Associate(const LocalSubmap& submap, int start_anchor, const SubmapGraph& graph,
                              const JointCovarianceFn& joint_covariance, bool anchor_prefilter = true,
                              const PairCovarianceFn& pair_covariance = nullptr,
                              const PairBoundFn& pair_bound = nullptr,
                              const std::vector<std::vector<int>>* groups = nullptr) const;

  // After the join: `landmark_of_feature` is the final landmark of each feature; landmarks
  // numbered `first_new_landmark` and up were created by this join. Records signatures and,
  // if `define_truth`, the truth ids of the new landmarks.
  void Record(const LocalSubmap& submap, const std::vector<int>& landmark_of_feature, int first_new_landmark,
              bool define_truth);

  // Follow a revision of the graph's association (landmark_revision.h): landmark `drop`
  // merged into `keep` (landmarks after `drop` move down by one); or a feature with
  // `signature` (NaN: none) moved from landmark `from` to the new landmark `to`.
  void MergeLandmarks(int keep, int drop);
  void SplitFeature(int from, int to, double signature);

  // The spread of the maps' own rotation (map_rotation_spread.h): `s` with its features
  // widened by the current estimate (as it is while there is none); and the fit a joined
  // map carries (StampRotationFit) recorded, with the widening it was associated with —
  // once per map joined, also when a joiner joins a map again.
  LocalSubmap WithRotationSpread(const LocalSubmap& s) const;
  void RecordRotationFit(const LocalSubmap& joined);
  const MapRotationSpread& rotation_spread() const { return rotation_spread_; }

  // Mean signature of the features joined to `landmark` (NaN: none had one).
  double MeanSignature(int landmark) const;
  // The truth id each of the first `num_landmarks` landmarks was defined by (−1: none).
  std::vector<int> TruthIds(int num_landmarks) const;

 private:
  // Known association: each feature to the landmark of its true id, if there is one.
  SubmapAssociation AssociateByTruth(const LocalSubmap& submap) const;

  SubmapAssociationOptions options_;
  std::vector<double> signature_sum_;  // per landmark
  std::vector<int> signature_count_;
  std::map<int, int> landmark_of_truth_;
  MapRotationSpread rotation_spread_;
};

}  // namespace subslam::association

#endif  // SUBSLAM_ASSOCIATION_SUBMAP_ASSOCIATION_H_
