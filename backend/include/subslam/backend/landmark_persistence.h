// Which landmarks of a map the robot's own scans confirm: a map-level existence test, and
// the sensor's detection probability by range learned from the same scans.
//
// Along the final trajectory each scan is compared with the map. A landmark is *expected*
// when it lies inside the sensor's range and field of view (by the margins below), and
// *detected* when one of the scan's detections pairs with it (χ²₂ gate on the innovation
// with the sensor's noise; one to one, nearest first). A feature that is not a landmark —
// an object that has moved on, a false alarm — is still detected now and then by chance:
// some other detection falls inside its gate, which for detections scattered at density
// λ over measurement space (range × bearing, the clutter model of probabilistic data
// association) happens with probability q = 1 − exp(−λ V) for a gate of area V. Over a
// landmark's n sightings the chance pairings number about Poisson(μ), μ = q n; the
// landmark is *confirmed* when its k detections are more than chance explains:
// P(K ≥ k | μ) < 1 − confirm_probability. λ is the density of the detections that no
// confirmed landmark explains, over the scans' measurement area; confirmation and λ are
// iterated to a fixed point (from every landmark confirmed). A landmark never expected is
// confirmed (nothing speaks against it).
//
// The gate leaves out the pose's and the landmark's covariances on purpose: they are
// marginals in the world frame, which grow with the drift of a long run, while the map and
// the trajectory of one estimate drift together (their cross-covariances, not kept,
// cancel most of it); with them the gates of a long run widen until chance explains every
// landmark (docs/limits.md). A run whose map and trajectory disagree locally — one gone
// wrong — has fewer landmarks confirmed, which is what the report shows.
//
// The test asks for presence, not for a detection rate: a landmark seen one time in five
// (occluded, or read only from some sides) is confirmed as long as that is well above
// chance. Two copies of one landmark are both confirmed (the pairing splits their
// detections); merging them is association's work.
//
// P_D by range: over the confirmed landmarks' sightings, detected / expected per range
// bin. A data set that records only scans with detections makes it an over-estimate
// (a scan with every landmark missed is not there to count).
//
// The idea of deciding a feature's persistence from whether it is re-detected when it
// should be follows D. M. Rosen, J. Mason and J. J. Leonard, "Towards lifelong
// feature-based mapping in semi-static environments", ICRA 2016; here over a whole run.
#ifndef SUBSLAM_BACKEND_LANDMARK_PERSISTENCE_H_
#define SUBSLAM_BACKEND_LANDMARK_PERSISTENCE_H_

#include <vector>

#include "absl/status/status.h"
#include "subslam/core/estimates.h"
#include "subslam/models/range_bearing_model.h"
#include "subslam/models/scan.h"

namespace subslam::backend {

struct LandmarkPersistenceOptions {
  // χ²₂ gate pairing a detection with a landmark.
  double gate_probability = 0.99;
  // A landmark is expected only this far inside the sensor's range [m] and field of view
  // [rad] (as LandmarkOptions: its position is uncertain).
  double expect_range_margin_m = 1.0;
  double expect_bearing_margin_rad = 0.05;
  // The test's level: the probability that chance pairings alone do not confirm a
  // feature that is not there.
  double confirm_probability = 0.999;
  // P_D by range is reported over this many equal bins from 0 to the sensor's maximum range.
  int range_bins = 8;
  int max_iterations = 50;  // rounds of the λ / confirmation fixed point

  absl::Status Validate() const;
};

struct DetectionRate {
  double range_min_m = 0.0, range_max_m = 0.0;
  long expected = 0;  // sightings of confirmed landmarks in the bin
  long detected = 0;
  double probability = 0.0;  // detected / expected (NaN: none expected)
};

struct LandmarkPersistence {
  // Per landmark of the map, in its order.
  std::vector<int> expected;            // scans in which it was in view
  std::vector<int> detected;            // of those, scans with a detection paired with it
  std::vector<double> chance_expected;  // μ: detections chance pairings explain
  std::vector<double> p_value;          // P(K ≥ detected | μ)
  std::vector<bool> confirmed;
  int num_confirmed = 0;
  std::vector<DetectionRate> detection_probability;  // by range
  double chance_pairing_density = 0.0;               // λ [per m·rad of measurement space and scan]
  double chance_pairing_probability = 0.0;           // q: per sighting
  int iterations = 0;
  long scans_used = 0;  // scans whose time the trajectory holds
};

// `trajectory` sorted by time; a scan is used when the trajectory has a pose at its time
// (to within 1e-9 s). Landmark and pose covariances in the world frame.
LandmarkPersistence AssessLandmarkPersistence(const std::vector<LandmarkEstimate>& map, const Trajectory& trajectory,
                                              const std::vector<Scan>& scans, const models::RangeBearingConfig& sensor,
                                              const LandmarkPersistenceOptions& options);

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_LANDMARK_PERSISTENCE_H_
