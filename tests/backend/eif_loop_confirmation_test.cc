// The EIF joiner's confirmation of loop closures made under a lost anchor, and of thin ones.

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <sstream>

#include "dense_gauss_newton.h"
#include "subslam/association/local_map_rotation.h"
#include "subslam/backend/ceres_joiner.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/frontend/moment_matching.h"
#include "synthetic_run.h"
#include "test_util.h"

namespace subslam::backend {
namespace {

using testing::MatricesNear;

namespace loop_confirmation {

struct Tree {
  int truth_id;
  Eigen::Vector2d world;
};

// A local map from `start` to `end` (world poses, as the map's own estimate places them)
// seeing `trees`, its mean exact, with diagonal covariance.
LocalSubmap Map(int id, const Pose2& start, const Pose2& end, const std::vector<Tree>& trees, double sigma_end_xy,
                double sigma_end_theta) {
  LocalSubmap m;
  m.id = id;
  m.t_start = 10.0 * id;
  m.t_end = 10.0 * (id + 1);
  std::vector<Eigen::Vector2d> seen;
  for (const Tree& t : trees) {
    seen.push_back(t.world);
    m.landmarks.push_back({static_cast<int>(m.landmarks.size()), NAN, 1.0, t.truth_id, 1, {}});
  }
  m.mean = PredictSubmap(start, end, seen);
  Eigen::VectorXd sigma = Eigen::VectorXd::Constant(m.mean.size(), 0.1);
  sigma.head<3>() << sigma_end_xy, sigma_end_xy, sigma_end_theta;
  m.covariance = sigma.cwiseAbs2().asDiagonal();
  return m;
}

const std::vector<Tree> kOld = {{0, {5, 8}},  {1, {12, -6}}, {2, {18, 9}}, {3, {25, -4}},
                                {4, {30, 7}}, {5, {36, -8}}, {6, {42, 5}}, {7, {50, -3}}};

// Map 0 seeing the old trees, then a loop of four maps back to the origin, two new trees
// near each start; odometry good on the first leg, then σ `sigma_leg` per map.
std::vector<LocalSubmap> Loop(double sigma_leg) {
  const Pose2 origin(0, 0, 0), a(20, 0, 0), b(120, 0, kPi / 2), c(120, 150, kPi), d(0, 150, -kPi / 2);
  std::vector<LocalSubmap> maps;
  maps.push_back(Map(0, origin, a, kOld, 0.1, 0.005));
  const std::vector<Pose2> loop = {a, b, c, d, origin};
  for (int k = 0; k < 4; ++k) {
    const Pose2& s = loop[k];
    maps.push_back(Map(1 + k, s, loop[k + 1],
                       {{100 + 2 * k, TransformFrom(s, Eigen::Vector2d(5, 10))},
                        {101 + 2 * k, TransformFrom(s, Eigen::Vector2d(8, -10))}},
                       k == 0 ? 0.5 : sigma_leg, 0.02));
  }
  return maps;
}

std::vector<LocalSubmap> Run(bool true_closure) {
  const std::vector<Tree>& old = kOld;
  const Pose2 origin(0, 0, 0), a(20, 0, 0);
  // σ 20 m per map: the closing map's start anchor has 3σ ≈ 100 m.
  std::vector<LocalSubmap> maps = Loop(20.0);
  // The closing map: where its estimate puts it, it sees trees 0-3's layout.
  std::vector<Tree> closing(old.begin(), old.begin() + 4);
  if (!true_closure) {
    for (Tree& t : closing) t.truth_id += 300;  // other trees, laid out alike
  }
  const Pose2 e(40, 0, 0), f(60, 0, 0), g(80, 0, 0), h(100, 0, 0);
  maps.push_back(Map(5, origin, a, closing, 0.1, 0.005));
  // The next map sees trees 4-7 if the closure is true, and two trees far from any old one
  // if not — and then it sees again one of the trees the closure took for tree 3: an old
  // landmark, but one the closure used, which confirms nothing.
  maps.push_back(Map(6, a, e,
                     true_closure ? std::vector<Tree>(old.begin() + 4, old.end())
                                  : std::vector<Tree>{{304, {45, 20}}, {305, {50, -20}}, {303, old[3].world}},
                     0.1, 0.005));
  maps.push_back(Map(7, e, f, {{200, {55, 15}}, {201, {70, -15}}}, 0.1, 0.005));
  maps.push_back(Map(8, f, g, {{202, {78, 12}}, {203, {90, -14}}}, 0.1, 0.005));
  maps.push_back(Map(9, g, h, {{204, {95, 15}}, {205, {110, -12}}}, 0.1, 0.005));
  return maps;
}

// How many of the closing map's features (local map 5) were joined to map 0's landmarks.
int ClosingPairings(const EifJoiner& j) {
  const std::vector<int>& map0 = j.graph().factors()[0].landmark_of_feature;
  int n = 0;
  for (int l : j.graph().factors()[5].landmark_of_feature) n += std::count(map0.begin(), map0.end(), l) > 0 ? 1 : 0;
  return n;
}

// A loop of four legs whose odometry leaves the closing map's start anchor uncertain but
// not lost (3σ ≈ 25 m), then a closing map that sees two of map 0's trees, and three more
// maps: the first of them sees `confirming` more of map 0's trees, the others new ones.
std::vector<LocalSubmap> ThinRun(int confirming) {
  const std::vector<Tree>& old = kOld;
  const Pose2 origin(0, 0, 0);
  std::vector<LocalSubmap> maps = Loop(4.0);
  maps.push_back(Map(5, origin, Pose2(10, 0, 0), {old[0], old[1]}, 0.1, 0.005));
  const Pose2 e(30, 0, 0), f(50, 0, 0), g(70, 0, 0);
  std::vector<Tree> next(old.begin() + 2, old.begin() + 2 + confirming);
  next.push_back({200, {30, 20}});
  maps.push_back(Map(6, Pose2(10, 0, 0), e, next, 0.1, 0.005));
  maps.push_back(Map(7, e, f, {{202, {55, 15}}, {203, {60, -15}}}, 0.1, 0.005));
  maps.push_back(Map(8, f, g, {{204, {75, 12}}, {205, {80, -14}}}, 0.1, 0.005));
  return maps;
}

}  // namespace loop_confirmation

TEST(EifJoiner, UndoesALoopClosureOfALostAnchorThatTheNextMapsDoNotConfirm) {
  using loop_confirmation::ClosingPairings;
  EifJoinerOptions options;
  ASSERT_EQ(options.association.loop_confirmation_maps, 3);
  EifJoinerOptions off = options;
  off.association.loop_confirmation_maps = 0;
  // A true closure: confirmed by the next map, and kept.
  {
    EifJoiner eif(Pose2(0, 0, 0), options);
    for (const LocalSubmap& s : loop_confirmation::Run(true)) ASSERT_TRUE(eif.Join(s).ok());
    EXPECT_EQ(ClosingPairings(eif), 4);
    EXPECT_EQ(eif.counters().loop_closures_confirmed, 1);
    EXPECT_EQ(eif.counters().loop_closures_unconfirmed, 0);
    EXPECT_EQ(eif.num_landmarks(), 8 + 8 + 6);  // map 6 saw trees 4-7 again
  }
  // A chance fit: it stands while the next maps may still confirm it, then it is undone.
  const std::vector<LocalSubmap> wrong = loop_confirmation::Run(false);
  EifJoiner eif(Pose2(0, 0, 0), options), unconfirmed(Pose2(0, 0, 0), off);
  for (const LocalSubmap& s : wrong) {
    ASSERT_TRUE(eif.Join(s).ok());
    ASSERT_TRUE(unconfirmed.Join(s).ok());
    if (s.id >= 5) {
      EXPECT_EQ(ClosingPairings(unconfirmed), 4) << "after map " << s.id;
    }
    if (s.id >= 5 && s.id < 8) {
      EXPECT_EQ(ClosingPairings(eif), 4) << "after map " << s.id;  // waiting for confirmation
    }
  }
  EXPECT_EQ(ClosingPairings(eif), 0);
  EXPECT_EQ(eif.counters().loop_closures_unconfirmed, 1);
  EXPECT_EQ(eif.counters().loop_closures_confirmed, 0);
  // The closing map joined again with its first association (the joiner restored to the
  // state it was made in), not a second search.
  EXPECT_EQ(eif.counters().associations_replayed, 1);
  EXPECT_EQ(eif.counters().joins, 10);
  EXPECT_EQ(eif.num_landmarks(), 8 + 8 + 4 + 2 + 6);  // every tree once
  EXPECT_EQ(eif.num_anchors(), 11);
  // Validated joins (their own snapshot and undo) make no difference here: every join
  // fits (exact means), and the closure is undone the same way.
  EifJoinerOptions validated_options = options;
  validated_options.validate_joins = true;
  EifJoiner validated(Pose2(0, 0, 0), validated_options);
  for (const LocalSubmap& s : wrong) ASSERT_TRUE(validated.Join(s).ok());
  EXPECT_EQ(ClosingPairings(validated), 0);
  EXPECT_EQ(validated.counters().loop_closures_unconfirmed, 1);
  EXPECT_EQ(validated.counters().rejected_joins, 0);
  EXPECT_EQ(validated.counters().associations_replayed, 1);
  EXPECT_EQ(validated.num_landmarks(), eif.num_landmarks());
  // With a single linearisation there is no confirmation: the closure stays.
  EifJoinerOptions single = options;
  single.relinearize_heading_change = 0.0;
  single.relinearize_linearization_chi2 = 0.0;
  EifJoiner single_linearisation(Pose2(0, 0, 0), single);
  for (const LocalSubmap& s : wrong) ASSERT_TRUE(single_linearisation.Join(s).ok());
  EXPECT_EQ(ClosingPairings(single_linearisation), 4);
  EXPECT_EQ(single_linearisation.counters().loop_closures_unconfirmed, 0);
  // Undone and joined again, the maps give what a joiner that never took the closure
  // gives: one whose loop test drops a four-pairing closure as too thin.
  EifJoinerOptions thin = off;
  thin.association.min_loop_pairings = 5;
  EifJoiner never(Pose2(0, 0, 0), thin);
  for (const LocalSubmap& s : wrong) ASSERT_TRUE(never.Join(s).ok());
  ASSERT_EQ(never.num_landmarks(), eif.num_landmarks());
  // (to rounding, amplified by anchors known to 35 m against features to 0.1 m: the
  // undone run refactorised where the other updated its factor)
  for (int k = 0; k < eif.num_anchors(); ++k) {
    EXPECT_LT(PoseDifference(eif.anchor(k), never.anchor(k)).cwiseAbs().maxCoeff(), 1e-6) << "anchor " << k;
  }
  EXPECT_TRUE(MatricesNear(eif.AnchorCovariance(10), never.AnchorCovariance(10), 1e-6));
}

// A thin loop closure (two pairings where min_loop_pairings asks four) is held until the
// next maps pair as many other old landmarks as one map would have needed, and undone when
// they do not — also when the run ends first. Without the rule it is dropped at once.
TEST(EifJoiner, HoldsAThinLoopClosureUntilTheNextMapsConfirmIt) {
  EifJoinerOptions options;
  ASSERT_EQ(options.association.min_loop_pairings, 4);
  ASSERT_TRUE(options.association.confirm_thin_loops);
  EifJoinerOptions off = options;
  off.association.confirm_thin_loops = false;
  const auto closing_pairings = [](const EifJoiner& j) {
    const std::vector<int>& map0 = j.graph().factors()[0].landmark_of_feature;
    int n = 0;
    for (int l : j.graph().factors()[5].landmark_of_feature) n += std::count(map0.begin(), map0.end(), l) > 0 ? 1 : 0;
    return n;
  };
  {
    // Confirmed by the next map's four other old trees: the loop is closed, every tree once.
    EifJoiner eif(Pose2(0, 0, 0), options);
    const std::vector<LocalSubmap> maps = loop_confirmation::ThinRun(4);
    for (const LocalSubmap& s : maps) ASSERT_TRUE(eif.Join(s).ok());
    ASSERT_TRUE(eif.Finish().ok());
    EXPECT_EQ(eif.counters().loop_closures_thin, 1);
    EXPECT_EQ(eif.counters().loop_closures_confirmed, 1);
    EXPECT_EQ(eif.counters().loop_closures_unconfirmed, 0);
    EXPECT_EQ(closing_pairings(eif), 2);
    EXPECT_EQ(eif.num_landmarks(), 8 + 8 + 1 + 4);
    // Dropped at once without the rule: the closing map's trees become copies.
    EifJoiner dropped(Pose2(0, 0, 0), off);
    for (const LocalSubmap& s : maps) ASSERT_TRUE(dropped.Join(s).ok());
    EXPECT_EQ(dropped.counters().loop_closures_thin, 1);
    EXPECT_EQ(closing_pairings(dropped), 0);
  }
  for (int confirming : {0, 2}) {
    // Fewer than four other old trees in the next three maps: undone, the closing map's
    // trees new.
    SCOPED_TRACE(confirming);
    EifJoiner eif(Pose2(0, 0, 0), options);
    const std::vector<LocalSubmap> maps = loop_confirmation::ThinRun(confirming);
    for (const LocalSubmap& s : maps) {
      ASSERT_TRUE(eif.Join(s).ok());
      if (s.id >= 5 && s.id < 8) {
        EXPECT_EQ(closing_pairings(eif), 2) << "after map " << s.id;  // held
      }
    }
    EXPECT_EQ(closing_pairings(eif), 0);
    EXPECT_EQ(eif.counters().loop_closures_unconfirmed, 1);
    EXPECT_EQ(eif.counters().loop_closures_confirmed, 0);
    ASSERT_TRUE(eif.Finish().ok());
    if (confirming == 0) {
      EXPECT_EQ(closing_pairings(eif), 0);
      EXPECT_EQ(eif.counters().loop_closures_unconfirmed, 1);
      EXPECT_EQ(eif.num_landmarks(), 8 + 8 + 2 + 1 + 4);
    } else {
      // Joined again, map 6's two old trees held a thin closure of their own, undone at
      // Finish(); the revision's loop merges then take the four copies together (four
      // agreeing pairs, landmark_revision.h): every tree once.
      EXPECT_EQ(eif.counters().loop_closures_unconfirmed, 2);
      EXPECT_EQ(eif.counters().landmarks_merged, 4);
      EXPECT_EQ(closing_pairings(eif), 2);
      EXPECT_EQ(eif.num_landmarks(), 8 + 8 + 1 + 4);
    }
  }
  {
    // The run ends while the closure waits: undone at Finish().
    EifJoiner eif(Pose2(0, 0, 0), options);
    std::vector<LocalSubmap> maps = loop_confirmation::ThinRun(0);
    maps.resize(7);
    for (const LocalSubmap& s : maps) ASSERT_TRUE(eif.Join(s).ok());
    EXPECT_EQ(closing_pairings(eif), 2);
    ASSERT_TRUE(eif.Finish().ok());
    EXPECT_EQ(closing_pairings(eif), 0);
    EXPECT_EQ(eif.counters().loop_closures_unconfirmed, 1);
  }
}

// While a loop closure waits for confirmation, the online anchor (LastAnchor) is the
// estimate without it — what a joiner that dropped the closure reports —, though the
// graph carries it; once the closure is undone, that joiner's again, and once it is
// confirmed, the graph's, which carries it. The same through Ceres, which joins by the EIF.
TEST(EifJoiner, OnlineAnchorDoesNotCarryAHeldLoopClosure) {
  const auto same_pose = [](const Pose2& a, const Pose2& b) {
    return PoseDifference(a, b).cwiseAbs().maxCoeff() < 1e-6;
  };
  const auto same_covariance = [](const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
    return (a - b).norm() <= 1e-6 * b.norm();
  };
  const auto make = [](bool ceres, bool confirm) -> std::unique_ptr<MapJoiner> {
    EifJoinerOptions o;
    o.association.confirm_thin_loops = confirm;
    if (!ceres) return std::make_unique<EifJoiner>(Pose2(0, 0, 0), o);
    CeresJoinerOptions c;
    c.eif = o;
    return std::make_unique<CeresJoiner>(Pose2(0, 0, 0), c);
  };
  for (bool ceres : {false, true}) {
    for (int confirming : {0, 4}) {
      SCOPED_TRACE(::testing::Message() << (ceres ? "ceres" : "eif") << ", " << confirming << " confirming trees");
      std::unique_ptr<MapJoiner> held = make(ceres, true), dropped = make(ceres, false);
      double waiting_trace = 0.0;  // of the online anchor's covariance, while the closure waits
      for (const LocalSubmap& s : loop_confirmation::ThinRun(confirming)) {
        ASSERT_TRUE(held->Join(s).ok());
        ASSERT_TRUE(dropped->Join(s).ok());
        const int last = held->num_anchors() - 1;
        const bool waiting = s.id == 5 || (confirming == 0 && s.id > 5 && s.id < 8);
        const bool confirmed = confirming == 4 && s.id >= 6;
        if (confirmed) {
          // The graph's last anchor, which carries the closure: far more certain than
          // the estimate reported while it waited.
          EXPECT_TRUE(same_pose(held->LastAnchor(), held->anchor(last))) << "map " << s.id;
          EXPECT_LT(held->LastAnchorCovariance().trace(), 0.01 * waiting_trace) << "map " << s.id;
          continue;
        }
        if (waiting) {
          waiting_trace = held->LastAnchorCovariance().trace();
          // The graph's last anchor carries the two held pairings: far more certain.
          EXPECT_LT(held->AnchorCovariance(last).trace(), 0.5 * held->LastAnchorCovariance().trace()) << "map " << s.id;
        }
        EXPECT_TRUE(same_pose(held->LastAnchor(), dropped->LastAnchor())) << "map " << s.id;
        EXPECT_TRUE(same_covariance(held->LastAnchorCovariance(), dropped->LastAnchorCovariance())) << "map " << s.id;
      }
      EXPECT_EQ(held->counters().loop_closures_confirmed, confirming == 4 ? 1 : 0);
      EXPECT_EQ(held->counters().loop_closures_unconfirmed, confirming == 4 ? 0 : 1);
    }
  }
}

// A closing map that the rotation test finds rotated is joined rotated back and widened;
// when its thin closure goes unconfirmed it is joined again with its first association
// from the graph's copy, which is rotated back already: not rotated a second time.
TEST(EifJoiner, ReplaysARotatedClosingMapWithoutRotatingItAgain) {
  using loop_confirmation::Map;
  using loop_confirmation::Tree;
  std::vector<LocalSubmap> maps = loop_confirmation::ThinRun(0);
  // Two trees by the loop's end that the last leg's map sees and the closing map again.
  const std::vector<Tree> shared = {{150, {-6, 5}}, {151, {-9, -4}}};
  const Pose2 d(0, 150, -kPi / 2);
  std::vector<Tree> leg = {{106, TransformFrom(d, Eigen::Vector2d(5, 10))},
                           {107, TransformFrom(d, Eigen::Vector2d(8, -10))}};
  leg.insert(leg.end(), shared.begin(), shared.end());
  maps[4] = Map(4, d, Pose2(0, 0, 0), leg, 0.1, 0.005);  // tied to its end: the shared trees are recent
  std::vector<Tree> closing = {loop_confirmation::kOld[0], loop_confirmation::kOld[1]};
  closing.insert(closing.end(), shared.begin(), shared.end());
  const LocalSubmap as_built = Map(5, Pose2(0, 0, 0), Pose2(10, 0, 0), closing, 0.1, 0.005);
  constexpr double kRotation = 0.15;
  maps[5] = association::RotatedAboutStart(as_built, kRotation);
  EifJoiner eif(Pose2(0, 0, 0), EifJoinerOptions{});
  for (const LocalSubmap& s : maps) ASSERT_TRUE(eif.Join(s).ok());
  EXPECT_EQ(eif.counters().loop_closures_unconfirmed, 1);
  EXPECT_EQ(eif.counters().associations_replayed, 1);
  EXPECT_EQ(eif.counters().maps_widened, 1);
  // The closing map as the graph holds it: rotated back once, to the map as built.
  const LocalSubmap& joined = eif.graph().factors()[5].submap;
  EXPECT_GT(joined.rotation_widening_rad, 0.0);
  EXPECT_NEAR(joined.end_pose().theta, as_built.end_pose().theta, 0.01);
  EXPECT_LT((joined.mean - as_built.mean).cwiseAbs().maxCoeff(), 0.05);
  // Its rotation fit is kept with it and counted once for the maps' rotation spread, though
  // it was associated twice.
  EXPECT_NEAR(joined.rotation_fit_rad, -kRotation, 0.05);  // the turn that takes it back
  int fitted = 0;
  for (const SubmapFactor& f : eif.graph().factors()) fitted += std::isfinite(f.submap.rotation_fit_rad) ? 1 : 0;
  EXPECT_EQ(eif.associator().rotation_spread().fits(), fitted);
}

}  // namespace
}  // namespace subslam::backend
