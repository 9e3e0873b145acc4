// Association against the local maps' true ids: the counts of a joined graph's pairings.
#include <gtest/gtest.h>

#include <optional>
#include <vector>

#include "subslam/pipeline/join_pipeline.h"

namespace subslam::pipeline {
namespace {

// Association against truth on a hand-built association table: a merge of two features
// that mix the same two trees with different majorities is wrong by the majority labels
// and not by the features' true landmarks; a third tree merged into them is wrong by
// both; a feature without truth_ids counts by its majority id, a false alarm not at all.
TEST(CountAssociationsAgainstTruth, CountsWrongMergesByMajorityAndBySharedTrueLandmarks) {
  SubmapGraph g(Pose2(0, 0, 0));
  for (int k = 1; k <= 4; ++k) g.AddAnchor(Pose2(k, 0, 0));
  g.AddLandmark(Eigen::Vector2d(1, 1));
  g.AddLandmark(Eigen::Vector2d(2, 1));
  const auto feature = [](std::optional<int> truth, std::optional<int> mixed, std::vector<int> ids) {
    LocalSubmapLandmark l;
    l.truth_id = truth;
    l.truth_landmarks = mixed;
    l.truth_ids = std::move(ids);
    return l;
  };
  const auto add = [&g](int k, std::vector<LocalSubmapLandmark> features, std::vector<int> globals) {
    SubmapFactor f;
    f.submap.id = k;
    f.submap.landmarks = std::move(features);
    f.start_anchor = k;
    f.end_anchor = k + 1;
    f.landmark_of_feature = std::move(globals);
    g.AddFactor(std::move(f));
  };
  add(0, {feature(10, 2, {10, 365})}, {0});
  add(1, {feature(365, 2, {10, 365})}, {0});
  add(2, {feature(7, 1, {7}), feature(8, std::nullopt, {})}, {0, 1});
  add(3, {feature(8, 1, {8}), feature(-1, std::nullopt, {})}, {1, 1});
  const AssociationVsTruth c = CountAssociationsAgainstTruth(g);
  EXPECT_EQ(c.wrong, 2);  // global 0 holds majorities 10, 365 and 7
  EXPECT_EQ(c.wrong_with_mixed_feature, 2);
  EXPECT_EQ(c.wrong_sharing_no_true_landmark, 1);  // only tree 7 shares nothing
  EXPECT_EQ(c.correct, 4);                         // true landmarks 10, 365, 7, 8
  EXPECT_EQ(c.missed, 0);
  EXPECT_EQ(c.recent_merged, 1);  // tree 8, seen again by the next map
  EXPECT_EQ(c.recent_missed + c.loop_merged + c.loop_missed, 0);

  // The same table with the true ids held apart from the graph, in local maps of the same
  // ids (as a run labels its maps after joining them), listed in another order and with
  // their features in another order: the same counts; a feature the labelled maps do not
  // hold is left out.
  SubmapGraph bare(Pose2(0, 0, 0));
  for (int k = 1; k <= 4; ++k) bare.AddAnchor(Pose2(k, 0, 0));
  bare.AddLandmark(Eigen::Vector2d(1, 1));
  bare.AddLandmark(Eigen::Vector2d(2, 1));
  std::vector<LocalSubmap> labelled;
  for (const SubmapFactor& f : g.factors()) {
    labelled.push_back(f.submap);
    SubmapFactor stripped = f;
    for (int i = 0; i < stripped.submap.num_landmarks(); ++i) {
      stripped.submap.landmarks[i] = LocalSubmapLandmark{};
      stripped.submap.landmarks[i].local_id = 10 + i;
      labelled.back().landmarks[i].local_id = 10 + i;
    }
    std::reverse(labelled.back().landmarks.begin(), labelled.back().landmarks.end());
    bare.AddFactor(std::move(stripped));
  }
  std::reverse(labelled.begin(), labelled.end());
  EXPECT_EQ(CountAssociationsAgainstTruth(bare).correct, 0);  // no true ids in the graph
  const AssociationVsTruth d = CountAssociationsAgainstTruth(bare, labelled);
  EXPECT_EQ(d.wrong, c.wrong);
  EXPECT_EQ(d.wrong_with_mixed_feature, c.wrong_with_mixed_feature);
  EXPECT_EQ(d.wrong_sharing_no_true_landmark, c.wrong_sharing_no_true_landmark);
  EXPECT_EQ(d.correct, c.correct);
  EXPECT_EQ(d.recent_merged, c.recent_merged);
  // Map 2 (now second, its features reversed) without tree 8: map 3's is then its first sight.
  labelled[1].landmarks.erase(labelled[1].landmarks.begin());
  EXPECT_EQ(CountAssociationsAgainstTruth(bare, labelled).recent_merged, 0);
}

}  // namespace
}  // namespace subslam::pipeline
