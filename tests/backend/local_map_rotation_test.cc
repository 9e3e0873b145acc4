#include "subslam/association/local_map_rotation.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <boost/math/distributions/binomial.hpp>
#include <cmath>
#include <memory>
#include <optional>
#include <random>
#include <vector>

#include "subslam/association/submap_association.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/ekf_joiner.h"
#include "subslam/backend/tree_joiner.h"
#include "subslam/models/gating.h"
#include "synthetic_run.h"

namespace subslam::backend {
namespace {

// The first synthetic local map: an end pose and a few landmarks 5-20 m away, with a
// correlated covariance.
LocalSubmap SomeMap() { return MakeRun(3, 2).submaps[0]; }

// The rotation of a Gaussian by δ about the origin, with the transformation written out.
TEST(LocalMapRotation, RotatedAboutStartIsARigidMotionOfTheGaussian) {
  const LocalSubmap s = SomeMap();
  constexpr double kDelta = 0.4;
  const LocalSubmap r = association::RotatedAboutStart(s, kDelta);
  const int dim = static_cast<int>(s.mean.size());
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(dim, dim);
  const Eigen::Matrix2d R = Eigen::Rotation2Dd(kDelta).toRotationMatrix();
  A.topLeftCorner<2, 2>() = R;
  for (int i = 0; i < s.num_landmarks(); ++i) A.block<2, 2>(3 + 2 * i, 3 + 2 * i) = R;
  EXPECT_TRUE(r.covariance.isApprox(A * s.covariance * A.transpose(), 1e-12));
  EXPECT_TRUE(r.end_pose().translation().isApprox(R * s.end_pose().translation(), 1e-12));
  EXPECT_NEAR(r.mean[2], WrapAngle(s.mean[2] + kDelta), 1e-12);
  for (int i = 0; i < s.num_landmarks(); ++i) {
    EXPECT_TRUE(r.landmark(i).isApprox(R * s.landmark(i), 1e-12));
    EXPECT_NEAR(r.landmark(i).norm(), s.landmark(i).norm(), 1e-12);  // ranges from the start kept
  }
  const LocalSubmap back = association::RotatedAboutStart(r, -kDelta);
  EXPECT_TRUE(back.mean.isApprox(s.mean, 1e-12));
  EXPECT_TRUE(back.covariance.isApprox(s.covariance, 1e-12));
  EXPECT_TRUE(r.Validate().ok());
}

// association::RotationAboutStart is ∂mean/∂δ of association::RotatedAboutStart at 0 (central differences).
TEST(LocalMapRotation, RotationJacobianMatchesNumericalDerivative) {
  const LocalSubmap s = SomeMap();
  constexpr double h = 1e-6;
  const Eigen::VectorXd plus = association::RotatedAboutStart(s, h).mean,
                        minus = association::RotatedAboutStart(s, -h).mean;
  Eigen::VectorXd numerical = (plus - minus) / (2 * h);
  numerical[2] = WrapAngle(plus[2] - minus[2]) / (2 * h);
  EXPECT_TRUE(association::RotationAboutStart(s).isApprox(numerical, 1e-6))
      << association::RotationAboutStart(s).transpose() << "\n"
      << numerical.transpose();
}

TEST(LocalMapRotation, WideningAddsTheRotationNuisanceAndRecordsIt) {
  const LocalSubmap s = SomeMap();
  const Eigen::VectorXd g = association::RotationAboutStart(s);
  const LocalSubmap w = association::WidenedByRotation(s, 0.3);
  EXPECT_EQ(w.mean, s.mean);
  EXPECT_TRUE(w.covariance.isApprox(s.covariance + 0.09 * g * g.transpose(), 1e-12));
  EXPECT_DOUBLE_EQ(w.rotation_widening_rad, 0.3);
  EXPECT_NEAR(association::WidenedByRotation(w, 0.4).rotation_widening_rad, 0.5, 1e-12);  // in quadrature
  EXPECT_TRUE(w.Validate().ok());
  EXPECT_EQ(s.rotation_widening_rad, 0.0);
}

// The previous local map's landmarks at 6-12 m from the start anchor, known to 0.05 m
// (its factor saw them); a new map of the same landmarks whose content is rotated by
// `rotation` about its start beyond its own covariance (0.05 m per feature).
struct RecentFixture {
  SubmapGraph graph{Pose2(0, 0, 0)};
  std::vector<Eigen::Vector2d> landmarks = {{8, 6}, {14, -5}, {20, 3}, {6, -9}, {16, 10}};

  RecentFixture() {
    graph.AddAnchor(Pose2(10, 0, 0));
    std::vector<int> seen;
    for (const Eigen::Vector2d& l : landmarks) seen.push_back(graph.AddLandmark(l));
    graph.AddFactor({LocalSubmap{}, 0, 1, seen});
  }

  LocalSubmap NewMap(double rotation) const {
    LocalSubmap s;
    s.id = 1;
    s.mean = Eigen::VectorXd::Zero(3 + 2 * landmarks.size());
    s.mean.head<3>() << 5.0, 0.0, 0.0;
    for (size_t i = 0; i < landmarks.size(); ++i) {
      s.mean.segment<2>(3 + 2 * i) = TransformTo(graph.anchors()[1], landmarks[i]);
      s.landmarks.push_back({static_cast<int>(i), NAN, 1.0, static_cast<int>(i), 1, {}});
    }
    s.covariance = 0.0025 * Eigen::MatrixXd::Identity(s.mean.size(), s.mean.size());
    return association::RotatedAboutStart(s, rotation);
  }

  static Eigen::MatrixXd Covariance(const std::vector<int>& anchors, const std::vector<int>& landmarks) {
    const int n = 3 * static_cast<int>(anchors.size()) + 2 * static_cast<int>(landmarks.size());
    Eigen::MatrixXd m = 0.0025 * Eigen::MatrixXd::Identity(n, n);
    for (size_t a = 0; a < anchors.size(); ++a) m.block<3, 3>(3 * a, 3 * a) = 1e-6 * Eigen::Matrix3d::Identity();
    return m;
  }
};

int Pairings(const association::SubmapAssociation& a) {
  int k = 0;
  for (int j : a.landmark_of_feature) k += j >= 0 ? 1 : 0;
  return k;
}

// A map rotated by 0.15 rad (0.9-1.8 m at its features) pairs none of the landmarks the
// previous map saw; the rotation test fits the rotation, and the map rotated back pairs
// every feature with its own landmark. An unrotated map passes the test and is left alone.
TEST(SubmapAssociator, FindsAMapRotatedAboutItsStartAndPairsItRotatedBack) {
  const RecentFixture f;
  association::SubmapAssociationOptions off;
  off.map_rotation_sigma_rad = 0.0;
  const association::SubmapAssociation plain =
      association::SubmapAssociator(off).Associate(f.NewMap(0.15), 1, f.graph, RecentFixture::Covariance);
  EXPECT_LE(Pairings(plain), 1);
  EXPECT_FALSE(plain.map_rotated);

  const association::SubmapAssociator associator{association::SubmapAssociationOptions{}};
  ASSERT_GT(associator.options().map_rotation_sigma_rad, 0.0);
  const association::SubmapAssociation a = associator.Associate(f.NewMap(0.15), 1, f.graph, RecentFixture::Covariance);
  EXPECT_TRUE(a.map_rotated);
  EXPECT_NEAR(a.map_rotation_rad, -0.15, 0.01);
  EXPECT_GE(a.map_rotation_statistic, models::ChiSquareQuantile(associator.options().map_rotation_probability, 1));
  EXPECT_GT(a.map_widening_rad, 0.0);
  EXPECT_LE(a.map_widening_rad, std::abs(a.map_rotation_rad));
  for (int i = 0; i < static_cast<int>(f.landmarks.size()); ++i) EXPECT_EQ(a.landmark_of_feature[i], i);
  // What the joiners join: the map rotated back onto the landmarks, widened, and only once.
  const std::optional<LocalSubmap> back = association::RotatedBack(f.NewMap(0.15), a);
  ASSERT_TRUE(back.has_value());
  EXPECT_DOUBLE_EQ(back->rotation_widening_rad, a.map_widening_rad);
  for (int i = 0; i < static_cast<int>(f.landmarks.size()); ++i) {
    EXPECT_LT((back->landmark(i) - TransformTo(f.graph.anchors()[1], f.landmarks[i])).norm(), 0.05);
  }
  EXPECT_FALSE(association::RotatedBack(*back, a).has_value());

  const association::SubmapAssociation still =
      associator.Associate(f.NewMap(0.0), 1, f.graph, RecentFixture::Covariance);
  EXPECT_FALSE(still.map_rotated);
  EXPECT_TRUE(std::isfinite(still.map_rotation_statistic));
  EXPECT_LT(still.map_rotation_statistic, 1e-6);
  EXPECT_FALSE(association::RotatedBack(f.NewMap(0.0), still).has_value());
  for (int i = 0; i < static_cast<int>(f.landmarks.size()); ++i) EXPECT_EQ(still.landmark_of_feature[i], i);

  // A map already widened (joined so before an undone loop closure) is not tested again.
  const association::SubmapAssociation again =
      associator.Associate(association::WidenedByRotation(f.NewMap(0.15), 0.01), 1, f.graph, RecentFixture::Covariance);
  EXPECT_FALSE(again.map_rotated);
  EXPECT_TRUE(std::isnan(again.map_rotation_statistic));
}

TEST(SubmapAssociationOptions, RejectsBadRotationSettings) {
  association::SubmapAssociationOptions o;
  o.map_rotation_sigma_rad = -0.1;
  EXPECT_EQ(o.Validate().code(), absl::StatusCode::kInvalidArgument);
  o.map_rotation_sigma_rad = NAN;
  EXPECT_EQ(o.Validate().code(), absl::StatusCode::kInvalidArgument);
  o.map_rotation_sigma_rad = 0.0;
  EXPECT_TRUE(o.Validate().ok());
  for (double p : {0.0, 1.0, std::nan("")}) {
    o.map_rotation_probability = p;
    EXPECT_EQ(o.Validate().code(), absl::StatusCode::kInvalidArgument) << p;
  }
  o.map_rotation_probability = 0.99;
  for (double p : {-0.1, 1.0, std::nan("")}) {
    o.map_rotation_spread_probability = p;
    const absl::Status s = o.Validate();
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << p;
    EXPECT_NE(s.message().find("map_rotation_spread_probability"), std::string::npos) << s;
  }
  o.map_rotation_spread_probability = 0.0;  // off
  EXPECT_TRUE(o.Validate().ok());
}

// Unknown association, without revision (the association alone is under test).
template <typename Options>
Options AssociationOnly(Options o) {
  o.association.known_association = false;
  o.revision.merge = o.revision.split = false;
  return o;
}

enum class Kind { kEif, kEkf, kTreeEif, kTreeEkf };

std::unique_ptr<MapJoiner> MakeJoiner(Kind kind, const Pose2& initial, double sigma_rotation) {
  std::unique_ptr<MapJoiner> node;
  if (kind == Kind::kEkf || kind == Kind::kTreeEkf) {
    EkfJoinerOptions o = AssociationOnly(EkfJoinerOptions{});
    o.association.map_rotation_sigma_rad = sigma_rotation;
    node = std::make_unique<EkfJoiner>(initial, o);
  } else {
    EifJoinerOptions o = AssociationOnly(ConvergingKnownAssociation());
    o.association.map_rotation_sigma_rad = sigma_rotation;
    node = std::make_unique<EifJoiner>(initial, o);
  }
  if (kind == Kind::kEif || kind == Kind::kEkf) return node;
  return std::make_unique<TreeJoiner>(std::move(node), TreeJoinerOptions{});
}

// The joint NEES of every anchor but the fixed first against the truth.
double AnchorNees(const MapJoiner& j, const SyntheticRun& run) {
  std::vector<int> anchors;
  Eigen::VectorXd e(3 * (j.num_anchors() - 1));
  for (int k = 1; k < j.num_anchors(); ++k) {
    anchors.push_back(k);
    e.segment<2>(3 * (k - 1)) = j.anchor(k).translation() - run.anchors[k].translation();
    e[3 * (k - 1) + 2] = WrapAngle(j.anchor(k).theta - run.anchors[k].theta);
  }
  return e.dot(j.JointCovariance(anchors, {}).ldlt().solve(e));
}

// One straight leg's map of a synthetic run rotated by 0.12 rad about its start with its
// covariance unchanged (as a particle filter's map over a turn can be): without the test
// its features become duplicates and the estimate is inconsistent; with it, the sequential
// back-ends pair them as in the untouched run, and the estimate is consistent. The tree
// joiners test the map against the map before it, before it becomes a leaf.
TEST(RotatedLocalMap, IsJoinedRotatedBackBySequentialAndTreeJoiners) {
  for (Kind kind : {Kind::kEif, Kind::kEkf, Kind::kTreeEif, Kind::kTreeEkf}) {
    SCOPED_TRACE(::testing::Message() << "joiner " << static_cast<int>(kind));
    const SyntheticRun run = MakeRun(7, 9);
    std::vector<LocalSubmap> rotated = run.submaps;
    rotated[3] = association::RotatedAboutStart(rotated[3], 0.12);
    const auto join_all = [&](const std::vector<LocalSubmap>& maps, double sigma) {
      std::unique_ptr<MapJoiner> j = MakeJoiner(kind, run.anchors[0], sigma);
      for (const LocalSubmap& s : maps) EXPECT_TRUE(j->Join(s).ok());
      EXPECT_TRUE(j->Finish().ok());
      return j;
    };
    const std::unique_ptr<MapJoiner> clean = join_all(run.submaps, 0.3), off = join_all(rotated, 0.0),
                                     on = join_all(rotated, 0.3);
    const TruthCount c = CountByTruth(clean->graph()), a = CountByTruth(off->graph()), b = CountByTruth(on->graph());
    EXPECT_GT(a.landmarks - a.truths, c.landmarks - c.truths);
    EXPECT_EQ(b.landmarks - b.truths, c.landmarks - c.truths);
    EXPECT_EQ(b.mixed, 0);
    EXPECT_GE(on->counters().maps_widened, 1);
    EXPECT_EQ(off->counters().maps_widened, 0);
    // The anchors' joint NEES: the map widened leaves the estimate consistent with its
    // covariance; the map taken as it is does not.
    const double bound = models::ChiSquareQuantile(0.999, 3.0 * (run.anchors.size() - 1));
    EXPECT_LE(AnchorNees(*on, run), bound);
    EXPECT_GT(AnchorNees(*off, run), bound);
  }
}

// On consistent local maps the test is a χ²₁ test at map_rotation_probability: the number
// of maps it widens is bounded by the binomial quantile over the maps joined, in the
// sequential EIF (against the recent maps' landmarks) and in the tree (against the map
// before).
TEST(RotatedLocalMap, FewConsistentMapsAreWidened) {
  for (Kind kind : {Kind::kEif, Kind::kTreeEif}) {
    SCOPED_TRACE(kind == Kind::kEif ? "eif" : "tree-eif");
    long joins = 0, widened = 0;
    for (uint64_t seed = 101; seed < 116; ++seed) {
      const SyntheticRun run = MakeRun(seed, 15);
      std::unique_ptr<MapJoiner> j =
          MakeJoiner(kind, run.anchors[0], association::SubmapAssociationOptions{}.map_rotation_sigma_rad);
      for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(j->Join(s).ok());
      joins += j->counters().joins;
      widened += j->counters().maps_widened;
    }
    ASSERT_GT(joins, 200);
    const double level = 1.0 - association::SubmapAssociationOptions{}.map_rotation_probability;
    const double bound = boost::math::quantile(boost::math::binomial(static_cast<double>(joins), level), 0.999);
    EXPECT_LE(widened, bound) << widened << " of " << joins << " maps widened";
  }
}

// The rotation fit of a map widened along the rotation it fits: the same δ̂, and a variance
// larger by the widening's (what association::MapRotationSpread::Add takes off again).
TEST(SubmapAssociator, WideningTheFeaturesAddsItsVarianceToTheRotationFit) {
  const RecentFixture f;
  association::SubmapAssociator associator{association::SubmapAssociationOptions{}};
  const LocalSubmap s = f.NewMap(0.02);
  const LocalSubmap w = association::WidenedFeaturesByRotation(s, 0.01);
  const association::SubmapAssociation a = associator.Associate(s, 1, f.graph, RecentFixture::Covariance);
  const association::SubmapAssociation b = associator.Associate(w, 1, f.graph, RecentFixture::Covariance);
  ASSERT_TRUE(std::isfinite(a.map_rotation_fit_rad));
  ASSERT_TRUE(std::isfinite(b.map_rotation_fit_rad));
  EXPECT_NEAR(a.map_rotation_fit_rad, -0.02, 3.0 * std::sqrt(a.map_rotation_fit_variance_rad2));
  EXPECT_NEAR(b.map_rotation_fit_rad, a.map_rotation_fit_rad, 1e-3 * std::sqrt(a.map_rotation_fit_variance_rad2));
  EXPECT_NEAR(b.map_rotation_fit_variance_rad2 - 1e-4, a.map_rotation_fit_variance_rad2,
              1e-3 * a.map_rotation_fit_variance_rad2);
}

// Local maps whose features each turn about their start by a rotation of their own (σ 0.03
// rad, the end pose as it is: what the rotation test measures on Victoria Park's maps): every
// joining back-end finds the spread and joins the later maps widened by it; it finds none
// in the same maps as built.
TEST(RotatedLocalMap, MapsWithARotationSpreadOfTheirOwnAreJoinedWidened) {
  for (Kind kind : {Kind::kEif, Kind::kEkf, Kind::kTreeEif}) {
    SCOPED_TRACE(::testing::Message() << "joiner " << static_cast<int>(kind));
    long spread_on = 0, spread_off = 0, joins = 0;
    std::mt19937_64 rng(29);
    std::normal_distribution<double> normal(0.0, 0.03);
    for (uint64_t seed = 201; seed < 206; ++seed) {
      const SyntheticRun run = MakeRun(seed, 15);
      std::vector<LocalSubmap> turned = run.submaps;
      for (size_t k = 1; k < turned.size(); ++k) {
        const Eigen::Matrix2d R = Eigen::Rotation2Dd(normal(rng)).toRotationMatrix();
        for (int i = 0; i < turned[k].num_landmarks(); ++i) {
          turned[k].mean.segment<2>(3 + 2 * i) = R * turned[k].mean.segment<2>(3 + 2 * i);
        }
      }
      using Maps = const std::vector<LocalSubmap>;
      for (Maps* maps : std::vector<Maps*>{&turned, &run.submaps}) {
        std::unique_ptr<MapJoiner> j =
            MakeJoiner(kind, run.anchors[0], association::SubmapAssociationOptions{}.map_rotation_sigma_rad);
        for (const LocalSubmap& s : *maps) ASSERT_TRUE(j->Join(s).ok());
        ASSERT_TRUE(j->Finish().ok());
        (maps == &turned ? spread_on : spread_off) += j->counters().maps_spread;
        if (maps == &turned) joins += j->counters().joins;
      }
    }
    EXPECT_GT(spread_on, joins / 4) << spread_on << " of " << joins;
    EXPECT_EQ(spread_off, 0);
  }
}

}  // namespace
}  // namespace subslam::backend
