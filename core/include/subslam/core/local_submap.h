// A local map reduced to one Gaussian: the unit the front-end hands to the back-end
// (docs/conventions.md, "The submap factor"; docs/formats.md, "Local maps exchange
// (submaps.jsonl)").
//
// Local map k starts at anchor P_s (the end pose of local map k − 1, or the initial pose)
// with zero uncertainty and no landmarks. Its Gaussian is over
//   mean = [end pose (x, y, θ), landmark 1 (x, y), …, landmark n (x, y)]
// all expressed in the frame of P_s (metres, radians, θ wrapped to (−π, π]), with a
// symmetric positive-definite (3 + 2n)² covariance. `landmarks[i]` describes the
// landmark at mean.segment<2>(3 + 2i).
#ifndef SUBSLAM_CORE_LOCAL_SUBMAP_H_
#define SUBSLAM_CORE_LOCAL_SUBMAP_H_

#include <Eigen/Core>
#include <limits>
#include <optional>
#include <vector>

#include "absl/status/status.h"
#include "subslam/core/pose2.h"

namespace subslam {

struct LocalSubmapLandmark {
  int local_id = 0;  // the front-end's feature id (unique within the local map)
  double signature = std::numeric_limits<double>::quiet_NaN();  // NaN when absent
  double existence = 1.0;                                       // P(exists) at export, in [0, 1]
  std::optional<int> truth_id;                                  // evaluation / known-association studies only
  // Evaluation only: how many distinct true landmarks the feature's detections came from
  // (≥ 2: the front-end mixed them; truth_id is the majority).
  std::optional<int> truth_landmarks;
  // Evaluation only: those true landmarks' ids, ascending (empty: not known).
  std::vector<int> truth_ids;
};

struct LocalSubmap {
  int id = 0;
  double t_start = 0.0;        // s
  double t_end = 0.0;          // s
  Eigen::VectorXd mean;        // 3 + 2n, in the start-pose frame
  Eigen::MatrixXd covariance;  // (3 + 2n) × (3 + 2n)
  std::vector<LocalSubmapLandmark> landmarks;
  // How many times the conversion had to repair the covariance to make it positive
  // definite and well conditioned (0 normally; reported, never silent).
  int covariance_repairs = 0;
  // Set by the back-end only: σ [rad] of the rotation about the start that the covariance
  // was widened by when association found the map rotated beyond it (its mean then rotated
  // by the fitted rotation; 0: neither; subslam/association/local_map_rotation.h).
  double rotation_widening_rad = 0.0;
  // Set by the back-end only: σ [rad] of the rotation about the start that the features'
  // covariance (not the end pose's) was widened by, the spread of the maps' own rotation
  // measured over the run (0: not widened; subslam/association/map_rotation_spread.h).
  double rotation_spread_rad = 0.0;
  // Set by the back-end only: the association's rotation fit of this map when it was first
  // joined — the fitted rotation of its features about its start [rad] and that estimate's
  // variance [rad²] with the map as it was associated (NaN: no fit). Kept with the joined
  // map so that a map joined again (after an undone loop closure, or when a joiner replays
  // its maps) counts its fit once (subslam/association/map_rotation_spread.h).
  double rotation_fit_rad = std::numeric_limits<double>::quiet_NaN();
  double rotation_fit_variance_rad2 = std::numeric_limits<double>::quiet_NaN();

  int num_landmarks() const { return static_cast<int>(landmarks.size()); }
  Pose2 end_pose() const { return Pose2::FromVector(mean.head<3>()); }
  Eigen::Vector2d landmark(int i) const { return mean.segment<2>(3 + 2 * i); }
  Eigen::Matrix2d landmark_covariance(int i) const { return covariance.block<2, 2>(3 + 2 * i, 3 + 2 * i); }

  // Sizes agree, values finite, t_start ≤ t_end, heading wrapped, local ids unique,
  // existence in [0, 1], covariance symmetric (to 1e-9 relative), positive definite and
  // not numerically singular (smallest eigenvalue ≥ kMinRelativeEigenvalue × largest)
  // nor nearly rigid (smallest eigenvalue ≥ kMinVariance).
  absl::Status Validate() const;
  static constexpr double kMinRelativeEigenvalue = 1e-13;
  // (1 µm)² and (1 µrad)², far below any sensor's resolution. A stiffer map is numerically
  // a rigid constraint, which the information form cannot take: its information (above
  // 10¹²) swamps the rest of Λ in the sum, and the factorisation loses positive
  // definiteness to rounding — a run's last local map of one 0.1 s step in which the
  // vehicle barely moved (variance 1.1·10⁻¹⁵ m² along its path) did that to the EIF.
  static constexpr double kMinVariance = 1e-12;

  // The rule for a local map whose covariance is symmetric, finite and positive
  // semidefinite (to rounding) but singular, numerically so or nearly rigid (a robot that
  // stood still exports a zero covariance): its diagonal gets kRegularizationVariance (1 mm², 1 mrad²: the rule
  // of the I-SLSJF authors' tools), ten times more each round until Validate() passes, at
  // most kMaxRegularizationRounds rounds; each round adds one to covariance_repairs.
  // Returns the rounds taken (0: the map was valid, or invalid for another reason — an
  // indefinite covariance among them —, which Validate() then reports).
  int RegularizeDegenerateCovariance();
  static constexpr double kRegularizationVariance = 1e-6;
  static constexpr int kMaxRegularizationRounds = 6;
};

}  // namespace subslam

#endif  // SUBSLAM_CORE_LOCAL_SUBMAP_H_
