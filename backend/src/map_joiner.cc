#include "subslam/backend/map_joiner.h"

#include <numeric>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "subslam/core/check.h"

namespace subslam::backend {

std::span<const JoinerCounters::Field> JoinerCounters::Fields() {
  using C = JoinerCounters;
  static constexpr Field kFields[] = {
      {"maps", &C::joins},
      {"associated_features", &C::associated},
      {"new_landmarks", &C::new_landmarks},
      {"relinearizations", &C::relinearizations},
      {"relinearizations_diverged", &C::relinearizations_diverged},
      {"relinearizations_predicted_converged", &C::relinearizations_predicted_converged},
      {"relinearized_on_heading", &C::relinearized_on_heading},
      {"relinearized_on_linearization_error", &C::relinearized_on_linearization_error},
      {"jcbb_truncated", &C::jcbb_truncated},
      {"loop_closures_thin", &C::loop_closures_thin},
      {"loop_closures_ambiguous", &C::loop_closures_ambiguous},
      {"loop_closures_confirmed", &C::loop_closures_confirmed},
      {"loop_closures_unconfirmed", &C::loop_closures_unconfirmed},
      {"associations_replayed", &C::associations_replayed},
      {"maps_widened", &C::maps_widened},
      {"maps_spread", &C::maps_spread},
      {"rejected", &C::rejected_joins},
      {"revision_passes", &C::revision_passes},
      {"landmarks_merged", &C::landmarks_merged},
      {"features_split", &C::features_split},
      {"incremental_updates", &C::incremental_updates},
      {"full_factorizations", &C::full_factorizations},
      {"nested_dissection_factorizations", &C::nested_dissection_factorizations},
      {"reused_analyses", &C::reused_analyses},
      {"failed_updates", &C::failed_updates},
      {"candidates", &C::candidates},
      {"candidates_bounded_out", &C::candidates_bounded_out},
      {"covariance_columns", &C::covariance_columns},
      {"covariance_reach", &C::covariance_reach},
  };
  return kFields;
}

JoinerCounters& JoinerCounters::operator+=(const JoinerCounters& o) {
  for (const Field& f : Fields()) this->*f.member += o.*f.member;
  return *this;
}

JoinerCounters JoinerCounters::operator-(const JoinerCounters& o) const {
  JoinerCounters d = *this;
  for (const Field& f : Fields()) d.*f.member -= o.*f.member;
  return d;
}

absl::Status MapJoiner::Join(const LocalSubmap& submap) {
  const JoinerCounters before = counters();
  const absl::Time start = absl::Now();
  association_d2_ = 0.0;
  association_dof_ = 0;
  absl::Status status = JoinLocalMap(submap);
  last_join_ = {submap.id,       absl::ToDoubleSeconds(absl::Now() - start),
                status,          counters() - before,
                association_d2_, association_dof_};
  return status;
}

std::vector<Eigen::Matrix3d> MapJoiner::AnchorCovariances() const {
  std::vector<Eigen::Matrix3d> out;
  out.reserve(num_anchors());
  for (int k = 0; k < num_anchors(); ++k) out.push_back(AnchorCovariance(k));
  return out;
}

std::vector<Eigen::Matrix2d> MapJoiner::LandmarkCovariances() const {
  std::vector<Eigen::Matrix2d> out;
  out.reserve(num_landmarks());
  for (int j = 0; j < num_landmarks(); ++j) out.push_back(LandmarkCovariance(j));
  return out;
}

LocalSubmap SummarizeAsLocalSubmap(const MapJoiner& j, bool with_covariance) {
  const SubmapGraph& g = j.graph();
  SUBSLAM_CHECK(!g.factors().empty()) << "an empty map has no summary";
  const Pose2& origin = g.anchors()[0];
  SUBSLAM_CHECK(origin.x == 0 && origin.y == 0 && origin.theta == 0) << "anchor 0 must be the identity";
  const int last = g.num_anchors() - 1, n = g.num_landmarks();
  LocalSubmap s;
  s.id = g.factors().front().submap.id;
  s.t_start = g.factors().front().submap.t_start;
  s.t_end = g.factors().back().submap.t_end;
  s.mean.resize(3 + 2 * n);
  s.mean.head<3>() = g.anchors()[last].vector();
  std::vector<int> landmarks(n);
  std::iota(landmarks.begin(), landmarks.end(), 0);
  for (int l = 0; l < n; ++l) s.mean.segment<2>(3 + 2 * l) = g.landmarks()[l];
  if (with_covariance) s.covariance = j.JointCovariance({last}, landmarks);
  const std::vector<int> truth = j.associator().TruthIds(n);
  for (int l = 0; l < n; ++l) {
    LocalSubmapLandmark lm;
    lm.local_id = l;
    lm.signature = j.associator().MeanSignature(l);
    lm.existence = 1.0;
    if (truth[l] >= 0) lm.truth_id = truth[l];
    s.landmarks.push_back(lm);
  }
  return s;
}

absl::StatusOr<LocalSubmap> SummarizeForJoin(const MapJoiner& right, double left_t_end, bool with_covariance) {
  LocalSubmap summary = SummarizeAsLocalSubmap(right, with_covariance);
  if (summary.t_start < left_t_end - 1e-9) {
    return absl::InvalidArgumentError(
        absl::StrCat("map from ", summary.t_start, " s starts before this one ends (", left_t_end, " s)"));
  }
  return summary;
}

absl::Status ReviseUntilSettled(MapJoiner& joiner, int max_passes) {
  for (int pass = 0; pass < max_passes; ++pass) {
    const long before = joiner.counters().landmarks_merged + joiner.counters().features_split;
    if (absl::Status st = joiner.ReviseAssociation(); !st.ok()) return st;
    if (joiner.counters().landmarks_merged + joiner.counters().features_split == before) break;
  }
  return absl::OkStatus();
}

}  // namespace subslam::backend
