#include "subslam/eval/labelled_map_errors.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>
#include <unordered_set>

#include "subslam/core/check.h"
#include "subslam/eval/nees.h"
#include "subslam/models/gating.h"

namespace subslam::eval {

std::vector<int> GlobalLandmarkTruthLabels(const SubmapGraph& graph, const std::vector<LocalSubmap>& labelled,
                                           const std::vector<LandmarkEstimate>& landmarks) {
  std::map<std::pair<int, int>, int> truth_of_feature;  // (map id, local id) → true id
  for (const LocalSubmap& s : labelled) {
    for (const LocalSubmapLandmark& l : s.landmarks) {
      if (l.truth_id && *l.truth_id >= 0) truth_of_feature[{s.id, l.local_id}] = *l.truth_id;
    }
  }
  std::map<int, std::map<int, int>> votes;  // global landmark → true id → features
  for (const SubmapFactor& f : graph.factors()) {
    for (int i = 0; i < f.submap.num_landmarks(); ++i) {
      const auto it = truth_of_feature.find({f.submap.id, f.submap.landmarks[i].local_id});
      if (it != truth_of_feature.end()) ++votes[f.landmark_of_feature[i]][it->second];
    }
  }
  std::vector<int> out(landmarks.size(), -1);
  for (size_t k = 0; k < landmarks.size(); ++k) {
    const auto it = votes.find(landmarks[k].id);
    if (it == votes.end()) continue;
    out[k] = std::max_element(it->second.begin(), it->second.end(), [](const auto& a, const auto& b) {
               return a.second < b.second;
             })->first;
  }
  return out;
}

LabelledMapErrors ComputeLabelledMapErrors(const std::vector<LandmarkEstimate>& estimate,
                                           const std::vector<int>& truth_label,
                                           const std::vector<io::TruthLandmark>& truth) {
  SUBSLAM_CHECK(truth_label.size() == estimate.size()) << "one label per estimate";
  std::unordered_map<int, Eigen::Vector2d> position_of;
  for (const io::TruthLandmark& t : truth) position_of[t.id] = t.p;
  LabelledMapErrors m;
  std::unordered_set<int> seen;
  double sq_x = 0, sq_y = 0, nees = 0;
  int nees_count = 0, inside = 0;
  const double bound = models::ChiSquareQuantile(0.95, 2);
  for (size_t i = 0; i < estimate.size(); ++i) {
    const auto it = position_of.find(truth_label[i]);
    if (it == position_of.end()) continue;
    ++m.labelled;
    seen.insert(truth_label[i]);
    const Eigen::Vector2d error = estimate[i].position - it->second;
    sq_x += error.x() * error.x();
    sq_y += error.y() * error.y();
    if (auto v = PointNees(it->second, estimate[i].position, estimate[i].covariance)) {
      nees += *v;
      ++nees_count;
      inside += *v <= bound ? 1 : 0;
    }
  }
  m.true_landmarks = static_cast<int>(seen.size());
  m.duplicates = m.labelled - m.true_landmarks;
  if (m.labelled > 0) {
    m.rms_x_m = std::sqrt(sq_x / m.labelled);
    m.rms_y_m = std::sqrt(sq_y / m.labelled);
    m.rms_m = std::sqrt((sq_x + sq_y) / m.labelled);
  }
  if (nees_count > 0) {
    m.mean_nees = nees / nees_count;
    m.fraction_nees_in_95 = static_cast<double>(inside) / nees_count;
  }
  return m;
}

}  // namespace subslam::eval
