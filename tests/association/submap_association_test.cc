#include "subslam/association/submap_association.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace subslam::association {
namespace {

// A map driven along x: old landmarks seen by the first local map only, recent ones by
// the last; the new local map starts at the last anchor and sees `old_seen` old landmarks
// and two recent ones exactly where the map has them.
struct LoopFixture {
  SubmapGraph graph{Pose2(0, 0, 0)};
  std::vector<Eigen::Vector2d> old_landmarks, recent_landmarks;

  // `old_spacing`: the old landmarks' spacing along their row [m].
  explicit LoopFixture(double old_spacing = 12.0) {
    for (int k = 1; k <= 4; ++k) graph.AddAnchor(Pose2(10.0 * k, 0, 0));
    LocalSubmap any;  // the factors' local maps do not matter to association
    std::vector<int> first, last;
    for (int i = 0; i < 5; ++i) {
      old_landmarks.emplace_back(40.0 + old_spacing * i, 8.0);
      first.push_back(graph.AddLandmark(old_landmarks.back()));
    }
    for (int i = 0; i < 2; ++i) {
      recent_landmarks.emplace_back(38.0 + 6.0 * i, -8.0);
      last.push_back(graph.AddLandmark(recent_landmarks.back()));
    }
    graph.AddFactor({any, 0, 1, first});
    graph.AddFactor({any, 1, 2, {}});
    graph.AddFactor({any, 2, 3, {}});
    graph.AddFactor({any, 3, 4, last});
  }

  LocalSubmap NewMap(int old_seen) const {
    const Pose2& start = graph.anchors()[4];
    std::vector<Eigen::Vector2d> seen(recent_landmarks);
    for (int i = 0; i < old_seen; ++i) seen.push_back(old_landmarks[i]);
    LocalSubmap s;
    s.id = 4;
    s.mean = Eigen::VectorXd::Zero(3 + 2 * seen.size());
    s.mean.head<3>() << 10.0, 0.0, 0.0;
    for (size_t i = 0; i < seen.size(); ++i) {
      s.mean.segment<2>(3 + 2 * i) = TransformTo(start, seen[i]);
      LocalSubmapLandmark l;
      l.local_id = static_cast<int>(i);
      s.landmarks.push_back(l);
    }
    s.covariance = 0.01 * Eigen::MatrixXd::Identity(s.mean.size(), s.mean.size());
    return s;
  }
};

// Marginal covariances: the start anchor's position σ as given, landmarks 0.1 m.
SubmapAssociator::JointCovarianceFn Covariance(double anchor_sigma_m) {
  return [anchor_sigma_m](const std::vector<int>& anchors, const std::vector<int>& landmarks) {
    const int n = 3 * static_cast<int>(anchors.size()) + 2 * static_cast<int>(landmarks.size());
    Eigen::MatrixXd m = 0.01 * Eigen::MatrixXd::Identity(n, n);
    for (size_t a = 0; a < anchors.size(); ++a) {
      m.block<3, 3>(3 * a, 3 * a) =
          Eigen::Vector3d(anchor_sigma_m * anchor_sigma_m, anchor_sigma_m * anchor_sigma_m, 1e-6).asDiagonal();
    }
    return m;
  };
}

int OldPairings(const SubmapAssociation& a) {
  int count = 0;
  for (size_t i = 2; i < a.landmark_of_feature.size(); ++i) count += a.landmark_of_feature[i] >= 0 ? 1 : 0;
  return count;
}

// A loop closure with fewer than min_loop_pairings old landmarks, made while the start
// anchor is uncertain, is dropped; the recent pairings stay. With enough pairings, or a
// certain anchor, or the test off, it is kept.
TEST(SubmapAssociator, DropsThinLoopClosuresUnderLargeUncertainty) {
  const LoopFixture f;
  const SubmapAssociator associator{SubmapAssociationOptions{}};  // 4 pairings, 3σ ≥ 5 m
  ASSERT_EQ(associator.options().min_loop_pairings, 4);
  const SubmapAssociation thin = associator.Associate(f.NewMap(2), 4, f.graph, Covariance(3.0));
  EXPECT_EQ(thin.loop_pairings_dropped, 2);
  EXPECT_EQ(OldPairings(thin), 0);
  EXPECT_EQ(thin.landmark_of_feature[0], 5);  // the recent ones are kept
  EXPECT_EQ(thin.landmark_of_feature[1], 6);
  // Dropped, but offered for confirmation (no other hypothesis pairs two old landmarks).
  EXPECT_TRUE(thin.thin_loop_unambiguous);
  EXPECT_EQ(thin.thin_loop_pairings, (std::vector<std::pair<int, int>>{{2, 0}, {3, 1}}));

  const SubmapAssociation thick = associator.Associate(f.NewMap(4), 4, f.graph, Covariance(3.0));
  EXPECT_EQ(thick.loop_pairings_dropped, 0);
  EXPECT_EQ(OldPairings(thick), 4);

  const SubmapAssociation certain = associator.Associate(f.NewMap(2), 4, f.graph, Covariance(1.0));
  EXPECT_EQ(certain.loop_pairings_dropped, 0);  // 3σ = 3 m < 5 m: no test
  EXPECT_EQ(OldPairings(certain), 2);

  SubmapAssociationOptions off;
  off.min_loop_pairings = 1;
  const SubmapAssociation kept = SubmapAssociator(off).Associate(f.NewMap(2), 4, f.graph, Covariance(3.0));
  EXPECT_EQ(OldPairings(kept), 2);
}

// Where the old landmarks stand 2 m apart, a start anchor known to 3σ = 3 m (below the
// 5 m radius) can already put the map a landmark off: with the radius scaled by the
// spacing (the default) the thin closure is dropped and offered for confirmation; with
// the absolute radius alone it is taken as it comes.
TEST(SubmapAssociator, ScalesTheLoopTestsByTheLandmarksSpacing) {
  const LoopFixture f(/*old_spacing=*/2.0);
  const SubmapAssociator scaled{SubmapAssociationOptions{}};
  ASSERT_TRUE(scaled.options().loop_test_scaled_by_spacing);
  const SubmapAssociation dropped = scaled.Associate(f.NewMap(2), 4, f.graph, Covariance(1.0));
  EXPECT_EQ(dropped.loop_pairings_dropped, 2);
  EXPECT_EQ(OldPairings(dropped), 0);
  EXPECT_EQ(dropped.landmark_of_feature[0], 5);  // the recent ones are kept
  EXPECT_EQ(dropped.landmark_of_feature[1], 6);

  SubmapAssociationOptions absolute;
  absolute.loop_test_scaled_by_spacing = false;
  const SubmapAssociation taken = SubmapAssociator(absolute).Associate(f.NewMap(2), 4, f.graph, Covariance(1.0));
  EXPECT_EQ(taken.loop_pairings_dropped, 0);
  EXPECT_EQ(OldPairings(taken), 2);

  // Spread 12 m apart, the same anchor is below both radii: no test.
  const LoopFixture sparse;
  const SubmapAssociation sparse_taken = scaled.Associate(sparse.NewMap(2), 4, sparse.graph, Covariance(1.0));
  EXPECT_EQ(sparse_taken.loop_pairings_dropped, 0);
  EXPECT_EQ(OldPairings(sparse_taken), 2);
}

// keep_certain_loop_pairings: old landmark 0 is known relative to the start anchor (its
// cross-covariance with the anchor's position carries the anchor's 3 m σ, leaving 0.1 m
// between them), landmark 1 is not. The thin closure still counts both, but only
// landmark 1's pairing is dropped; with the option off, both are.
TEST(SubmapAssociator, KeepsTheCertainPairingsOfADroppedLoopClosure) {
  const LoopFixture f;
  constexpr double kSigma = 3.0;
  const SubmapAssociator::JointCovarianceFn correlated = [](const std::vector<int>& anchors,
                                                            const std::vector<int>& landmarks) {
    Eigen::MatrixXd m = Covariance(kSigma)(anchors, landmarks);
    const int n_a = 3 * static_cast<int>(anchors.size());
    for (size_t l = 0; l < landmarks.size(); ++l) {
      if (landmarks[l] != 0) continue;
      const int o = n_a + 2 * static_cast<int>(l);
      m.block<2, 2>(o, o) += kSigma * kSigma * Eigen::Matrix2d::Identity();
      for (size_t a = 0; a < anchors.size(); ++a) {
        m.block<2, 2>(o, 3 * a) = kSigma * kSigma * Eigen::Matrix2d::Identity();
        m.block<2, 2>(3 * a, o) = kSigma * kSigma * Eigen::Matrix2d::Identity();
      }
    }
    return m;
  };
  const SubmapAssociator associator{SubmapAssociationOptions{}};
  ASSERT_TRUE(associator.options().keep_certain_loop_pairings);
  const SubmapAssociation kept = associator.Associate(f.NewMap(2), 4, f.graph, correlated);
  EXPECT_EQ(kept.loop_pairings_dropped, 2);    // both counted: a thin closure
  EXPECT_EQ(kept.landmark_of_feature[2], 0);   // old landmark 0: certain, kept
  EXPECT_EQ(kept.landmark_of_feature[3], -1);  // old landmark 1: dropped
  EXPECT_EQ(kept.landmark_of_feature[0], 5);
  SubmapAssociationOptions off;
  off.keep_certain_loop_pairings = false;
  const SubmapAssociation dropped = SubmapAssociator(off).Associate(f.NewMap(2), 4, f.graph, correlated);
  EXPECT_EQ(dropped.loop_pairings_dropped, 2);
  EXPECT_EQ(OldPairings(dropped), 0);
}

// loop_ambiguity_test: old landmarks on a row 12 m apart and a new local map that sees
// four of them. With the start anchor's σ at 6 m, the row shifted by one landmark is as
// compatible as the truth (joint d² ≈ (12 / 6)²): the test drops the loop closure. At
// σ = 2.5 m the shifted row fails the joint gate, and the closure is kept.
TEST(SubmapAssociator, AmbiguityTestDropsALoopClosureThatAShiftedRowFitsAsWell) {
  SubmapGraph graph{Pose2(0, 0, 0)};
  for (int k = 1; k <= 4; ++k) graph.AddAnchor(Pose2(10.0 * k, 0, 0));
  std::vector<int> row;
  for (int i = 0; i < 8; ++i) row.push_back(graph.AddLandmark(Eigen::Vector2d(40.0 + 12.0 * i, 8.0)));
  const LocalSubmap any;
  graph.AddFactor({any, 0, 1, row});
  graph.AddFactor({any, 1, 2, {}});
  graph.AddFactor({any, 2, 3, {}});
  graph.AddFactor({any, 3, 4, {}});
  LocalSubmap s;
  s.id = 4;
  s.mean = Eigen::VectorXd::Zero(3 + 2 * 4);
  s.mean.head<3>() << 10.0, 0.0, 0.0;
  for (int i = 0; i < 4; ++i) {
    s.mean.segment<2>(3 + 2 * i) = TransformTo(graph.anchors()[4], graph.landmarks()[row[i]]);
    LocalSubmapLandmark l;
    l.local_id = i;
    s.landmarks.push_back(l);
  }
  s.covariance = 0.01 * Eigen::MatrixXd::Identity(s.mean.size(), s.mean.size());
  const auto pairings = [](const SubmapAssociation& a) {
    int count = 0;
    for (int j : a.landmark_of_feature) count += j >= 0 ? 1 : 0;
    return count;
  };
  SubmapAssociationOptions options;
  EXPECT_TRUE(options.loop_ambiguity_test);  // the default
  options.loop_ambiguity_test = false;
  const SubmapAssociation plain = SubmapAssociator(options).Associate(s, 4, graph, Covariance(6.0));
  EXPECT_EQ(plain.landmark_of_feature, (std::vector<int>{row[0], row[1], row[2], row[3]}));
  EXPECT_FALSE(plain.loop_ambiguous);
  options.loop_ambiguity_test = true;
  const SubmapAssociator tested(options);
  const SubmapAssociation ambiguous = tested.Associate(s, 4, graph, Covariance(6.0));
  EXPECT_TRUE(ambiguous.loop_ambiguous);
  EXPECT_EQ(pairings(ambiguous), 0);
  const SubmapAssociation clear = tested.Associate(s, 4, graph, Covariance(2.5));
  EXPECT_FALSE(clear.loop_ambiguous);
  EXPECT_EQ(clear.landmark_of_feature, (std::vector<int>{row[0], row[1], row[2], row[3]}));
  // A thin closure (two of the row's landmarks) is offered for confirmation only when the
  // shifted row does not fit as well.
  LocalSubmap two = s;
  two.mean.conservativeResize(3 + 2 * 2);
  two.landmarks.resize(2);
  two.covariance = 0.01 * Eigen::MatrixXd::Identity(two.mean.size(), two.mean.size());
  const SubmapAssociation thin_ambiguous = tested.Associate(two, 4, graph, Covariance(6.0));
  EXPECT_EQ(thin_ambiguous.loop_pairings_dropped, 2);
  EXPECT_FALSE(thin_ambiguous.thin_loop_unambiguous);
  EXPECT_TRUE(thin_ambiguous.thin_loop_pairings.empty());
  const SubmapAssociation thin_clear = tested.Associate(two, 4, graph, Covariance(2.5));
  EXPECT_EQ(thin_clear.loop_pairings_dropped, 2);
  EXPECT_EQ(thin_clear.thin_loop_pairings, (std::vector<std::pair<int, int>>{{0, row[0]}, {1, row[1]}}));
}

// A whole map (tree joining) is associated group by group, each group one of its local
// maps: the loop tests weigh each group's own pairings, as sequential joins would. Two
// local maps that each see two old landmarks make two thin closures, both dropped; one
// JCBB over the whole map would see four and keep them.
TEST(SubmapAssociator, WholeMapLoopTestsApplyToEachLocalMap) {
  const LoopFixture f;
  const SubmapAssociator associator{SubmapAssociationOptions{}};
  const LocalSubmap whole = f.NewMap(4);  // features: 2 recent, then old landmarks 0-3
  const std::vector<std::vector<int>> two_maps = {{0, 1, 2, 3}, {0, 1, 4, 5}};
  const SubmapAssociation grouped =
      associator.Associate(whole, 4, f.graph, Covariance(3.0), /*anchor_prefilter=*/false, nullptr, nullptr, &two_maps);
  EXPECT_EQ(OldPairings(grouped), 0);
  EXPECT_EQ(grouped.loop_pairings_dropped, 4);  // 2 + 2
  EXPECT_EQ(grouped.landmark_of_feature[0], 5);
  EXPECT_EQ(grouped.landmark_of_feature[1], 6);
  const SubmapAssociation at_once = associator.Associate(whole, 4, f.graph, Covariance(3.0), false);
  EXPECT_EQ(OldPairings(at_once), 4);
  // One local map that sees all four closes the loop.
  const std::vector<std::vector<int>> one_map = {{0, 1}, {0, 1, 2, 3, 4, 5}};
  const SubmapAssociation closed =
      associator.Associate(whole, 4, f.graph, Covariance(3.0), false, nullptr, nullptr, &one_map);
  EXPECT_EQ(OldPairings(closed), 4);
  EXPECT_EQ(closed.uncertain_loop_features, (std::vector<int>{2, 3, 4, 5}));
}

// loop_confirmation_maps within a whole map: under a lost start anchor (3σ ≥ 60 m) a
// closure by one local map stands only if a later one pairs another old landmark; one
// made by the whole map's last local map waits for maps a later join brings, so it is
// undone here. With the anchor known better (3σ < 60 m) it stands at once.
TEST(SubmapAssociator, WholeMapLoopClosuresUnderALostAnchorNeedConfirmation) {
  const LoopFixture f;
  SubmapAssociationOptions options;
  options.loop_ambiguity_test = false;  // a row 12 m apart under σ = 25 m is ambiguous
  ASSERT_EQ(options.loop_confirmation_maps, 3);
  const SubmapAssociator associator(options);
  const LocalSubmap whole = f.NewMap(5);  // 2 recent, then old landmarks 0-4
  const auto associate = [&](const std::vector<std::vector<int>>& groups, double sigma) {
    return associator.Associate(whole, 4, f.graph, Covariance(sigma), false, nullptr, nullptr, &groups);
  };
  const SubmapAssociation confirmed = associate({{0, 1, 2, 3, 4, 5}, {0, 1}, {0, 1, 6}}, 25.0);
  EXPECT_EQ(OldPairings(confirmed), 5);
  EXPECT_EQ(confirmed.loop_closures_confirmed, 1);
  EXPECT_EQ(confirmed.loop_closures_unconfirmed, 0);
  // Landmark 4 seen only after three more maps: too late.
  const SubmapAssociation late = associate({{0, 1, 2, 3, 4, 5}, {0, 1}, {0, 1}, {0, 1}, {0, 1, 6}}, 25.0);
  EXPECT_EQ(late.loop_closures_unconfirmed, 1);
  EXPECT_EQ(late.landmark_of_feature[2], -1);  // the closing map's loop pairings are gone
  EXPECT_EQ(late.landmark_of_feature[0], 5);
  const SubmapAssociation at_end = associate({{0, 1}, {0, 1, 2, 3, 4, 5}}, 25.0);
  EXPECT_EQ(OldPairings(at_end), 0);
  EXPECT_EQ(at_end.loop_closures_unconfirmed, 1);
  EXPECT_EQ(at_end.loop_pairings_dropped, 0);  // undone, not thin
  const SubmapAssociation known = associate({{0, 1}, {0, 1, 2, 3, 4, 5}}, 15.0);
  EXPECT_EQ(OldPairings(known), 4);
  EXPECT_EQ(known.loop_closures_unconfirmed, 0);
}

// A whole map joined under a lost start anchor whose heading is 0.15 rad off (σ 0.3 rad,
// position σ 30 m): its first local map closes the loop on five landmarks 5-25 m from the
// start, its second re-observes two 300 m away. About the prior's heading the far
// features' predictions are 3.4 m off through the second-order term alone, against 0.8 m
// of σ given the closure, and the closure would go unconfirmed; linearised about the start
// anchor the closure implies, the second map pairs them and confirms it.
TEST(SubmapAssociator, WholeMapGroupsAfterAClosureAreGatedAboutTheAnchorItImplies) {
  SubmapGraph graph(Pose2(0, 0, 0));
  for (int k = 1; k <= 3; ++k) graph.AddAnchor(Pose2(0, 0, 0));
  const Pose2 true_start(0, 0, 0.15);
  const std::vector<Eigen::Vector2d> seen = {{5, 3}, {10, -4}, {15, 6}, {20, -5}, {25, 2}, {300, 10}, {310, -12}};
  std::vector<int> landmarks;
  for (const Eigen::Vector2d& l : seen) landmarks.push_back(graph.AddLandmark(TransformFrom(true_start, l)));
  const LocalSubmap any;
  graph.AddFactor({any, 0, 1, landmarks});
  graph.AddFactor({any, 1, 2, {}});
  graph.AddFactor({any, 2, 3, {}});
  LocalSubmap whole;
  whole.mean = Eigen::VectorXd::Zero(3 + 2 * seen.size());
  for (size_t i = 0; i < seen.size(); ++i) {
    whole.mean.segment<2>(3 + 2 * i) = seen[i];
    LocalSubmapLandmark l;
    l.local_id = static_cast<int>(i);
    whole.landmarks.push_back(l);
  }
  whole.covariance = 0.01 * Eigen::MatrixXd::Identity(whole.mean.size(), whole.mean.size());
  const SubmapAssociator::JointCovarianceFn covariance = [](const std::vector<int>& anchors,
                                                            const std::vector<int>& ls) {
    const int n = 3 * static_cast<int>(anchors.size()) + 2 * static_cast<int>(ls.size());
    Eigen::MatrixXd m = 0.01 * Eigen::MatrixXd::Identity(n, n);
    for (size_t a = 0; a < anchors.size(); ++a)
      m.block<3, 3>(3 * a, 3 * a) = Eigen::Vector3d(900, 900, 0.09).asDiagonal();
    return m;
  };
  const SubmapAssociator associator{SubmapAssociationOptions{}};
  const std::vector<std::vector<int>> two_maps = {{0, 1, 2, 3, 4}, {5, 6}};
  const SubmapAssociation a =
      associator.Associate(whole, 3, graph, covariance, /*anchor_prefilter=*/false, nullptr, nullptr, &two_maps);
  EXPECT_EQ(a.landmark_of_feature, landmarks);
  EXPECT_EQ(a.loop_closures_confirmed, 1);
  EXPECT_EQ(a.loop_closures_unconfirmed, 0);
  // The same through the pairwise [anchor, landmark] marginals, as the EIF gives them.
  const SubmapAssociator::PairCovarianceFn pair_covariance = [](int, const std::vector<int>& ls) {
    Matrix5d m = Matrix5d::Zero();
    m.topLeftCorner<3, 3>() = Eigen::Vector3d(900, 900, 0.09).asDiagonal();
    m.bottomRightCorner<2, 2>() = 0.01 * Eigen::Matrix2d::Identity();
    return std::vector<Matrix5d>(ls.size(), m);
  };
  const SubmapAssociation pairwise =
      associator.Associate(whole, 3, graph, covariance, false, pair_covariance, nullptr, &two_maps);
  EXPECT_EQ(pairwise.landmark_of_feature, landmarks);
  EXPECT_EQ(pairwise.loop_closures_confirmed, 1);
  // The first map alone: its closure waits for maps a later join brings, and is undone.
  const std::vector<std::vector<int>> first_only = {{0, 1, 2, 3, 4}};
  const SubmapAssociation alone =
      associator.Associate(whole, 3, graph, covariance, false, nullptr, nullptr, &first_only);
  EXPECT_EQ(alone.loop_closures_unconfirmed, 1);
  EXPECT_EQ(alone.landmark_of_feature[0], -1);
}

TEST(SubmapAssociationOptions, ValidationRejectsNonsense) {
  SubmapAssociationOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.loop_test_min_sigma_radius_m = -1.0;
  EXPECT_FALSE(o.Validate().ok());
  o = SubmapAssociationOptions();
  o.loop_confirmation_maps = -1;
  EXPECT_FALSE(o.Validate().ok());
  o = SubmapAssociationOptions();
  o.loop_confirmation_min_sigma_radius_m = NAN;
  EXPECT_FALSE(o.Validate().ok());
}

}  // namespace
}  // namespace subslam::association
