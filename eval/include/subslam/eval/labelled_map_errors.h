// The joined map against the truth by label rather than by distance (evaluation only):
// each global landmark is labelled with the majority true id of the local-map features
// joined into it, and compared with that true landmark however far it has drifted.
#ifndef SUBSLAM_EVAL_LABELLED_MAP_ERRORS_H_
#define SUBSLAM_EVAL_LABELLED_MAP_ERRORS_H_

#include <vector>

#include "subslam/core/estimates.h"
#include "subslam/core/local_submap.h"
#include "subslam/core/submap_graph.h"
#include "subslam/io/dataset.h"

namespace subslam::eval {

struct LabelledMapErrors {
  int labelled = 0;        // estimates with a label found in the truth
  int true_landmarks = 0;  // distinct labels among them
  int duplicates = 0;      // labelled − true_landmarks: surplus estimates of a true landmark
  double rms_m = 0.0;      // over labelled estimates
  double rms_x_m = 0.0;
  double rms_y_m = 0.0;
  double mean_nees = 0.0;            // 2-dof NEES, over labelled estimates with a valid covariance
  double fraction_nees_in_95 = 0.0;  // of those, NEES ≤ χ²₂(0.95)
};

// The label of each global landmark of a joined graph: the majority true id of the
// local-map features joined into it (features matched to `labelled` — the same local
// maps with truth_id set — by map id and local id); −1 where no feature has one.
// Aligned with `landmarks`, whose ids are graph landmark indices. Evaluation only.
std::vector<int> GlobalLandmarkTruthLabels(const SubmapGraph& graph, const std::vector<LocalSubmap>& labelled,
                                           const std::vector<LandmarkEstimate>& landmarks);

// The map against the truth through labels rather than distances: `truth_label[i]` is
// the true landmark estimate i stands for (e.g. from GlobalLandmarkTruthLabels; −1 or
// any id not in `truth`: unlabelled). Unlike ComputeMapErrors, a landmark far from its
// true position still counts (as a large error), so the figures hold however far the
// map has drifted. All zero when nothing is labelled.
LabelledMapErrors ComputeLabelledMapErrors(const std::vector<LandmarkEstimate>& estimate,
                                           const std::vector<int>& truth_label,
                                           const std::vector<io::TruthLandmark>& truth);

}  // namespace subslam::eval

#endif  // SUBSLAM_EVAL_LABELLED_MAP_ERRORS_H_
