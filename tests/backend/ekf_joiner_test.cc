#include "subslam/backend/ekf_joiner.h"

#include <gtest/gtest.h>

#include <numeric>

#include "subslam/backend/eif_joiner.h"
#include "synthetic_run.h"
#include "test_util.h"

namespace subslam::backend {
namespace {

Eigen::MatrixXd FullCovariance(const MapJoiner& j) {
  std::vector<int> anchors(j.num_anchors() - 1), landmarks(j.num_landmarks());
  std::iota(anchors.begin(), anchors.end(), 1);
  std::iota(landmarks.begin(), landmarks.end(), 0);
  return j.JointCovariance(anchors, landmarks);
}

// |expected − actual| ≤ tolerance · max|expected| (relative to the matrix's own scale).
::testing::AssertionResult RelativelyNear(const Eigen::MatrixXd& expected, const Eigen::MatrixXd& actual,
                                          double tolerance) {
  if (expected.rows() != actual.rows() || expected.cols() != actual.cols()) {
    return ::testing::AssertionFailure() << "size mismatch";
  }
  const double err = (expected - actual).cwiseAbs().maxCoeff();
  const double scale = expected.cwiseAbs().maxCoeff();
  if (err <= tolerance * scale) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "max abs difference " << err << " > " << tolerance << " × " << scale;
}

EkfJoinerOptions KnownAssociation(EkfFusion fusion, bool keep_anchors = true) {
  EkfJoinerOptions o;
  o.association.known_association = true;
  o.fusion = fusion;
  o.keep_anchors = keep_anchors;
  return o;
}

// The covariance-form join conditioned on the augmented part is the EIF's factor update
// on the same linearisation: estimates and the whole covariance agree to rounding after
// every join of a loop (known association, no relinearisation).
TEST(EkfJoiner, ConditionalUpdateEqualsTheEifOnOneLinearization) {
  const SyntheticRun run = MakeRun(5, 12, 2.0);
  EifJoinerOptions eif_options;
  eif_options.association.known_association = true;
  EifJoiner eif(run.anchors[0], eif_options.SingleLinearization());
  EkfJoiner ekf(run.anchors[0], KnownAssociation(EkfFusion::kConditionalUpdate));
  for (const LocalSubmap& s : run.submaps) {
    ASSERT_TRUE(eif.Join(s).ok());
    ASSERT_TRUE(ekf.Join(s).ok());
    ASSERT_EQ(ekf.num_landmarks(), eif.num_landmarks());
    EXPECT_TRUE(RelativelyNear(StackedEstimate(eif), StackedEstimate(ekf), 1e-8)) << "after map " << s.id;
    EXPECT_TRUE(RelativelyNear(FullCovariance(eif), FullCovariance(ekf), 1e-8)) << "after map " << s.id;
  }
  EXPECT_GT(ekf.counters().associated, 20);  // the loop is closed: many fusions
  EXPECT_EQ(ekf.counters().associated, eif.counters().associated);
}

// HybridSLAM's augment-then-fuse-by-zero-noise-constraint linearises the matched rows at
// the copy P̂_s ⊕ l_i instead of at L̂_j: when the matched features agree exactly with the
// current estimate, the two linearisation points coincide and the join equals the EIF's.
TEST(EkfJoiner, ZeroNoiseConstraintEqualsTheEifWhenMatchedFeaturesAgree) {
  const SyntheticRun run = MakeRun(9, 4);
  EifJoinerOptions eif_options;
  eif_options.association.known_association = true;
  EifJoiner eif(run.anchors[0], eif_options.SingleLinearization());
  EkfJoiner ekf(run.anchors[0], KnownAssociation(EkfFusion::kZeroNoiseConstraint));
  for (size_t k = 0; k < run.submaps.size(); ++k) {
    LocalSubmap s = run.submaps[k];
    if (k > 0) {  // every re-observed landmark exactly where the estimate has it
      std::map<int, int> global_of_truth;
      for (const SubmapFactor& f : eif.graph().factors()) {
        for (int i = 0; i < f.submap.num_landmarks(); ++i) {
          global_of_truth[*f.submap.landmarks[i].truth_id] = f.landmark_of_feature[i];
        }
      }
      for (int i = 0; i < s.num_landmarks(); ++i) {
        auto it = global_of_truth.find(*s.landmarks[i].truth_id);
        if (it == global_of_truth.end()) continue;
        s.mean.segment<2>(3 + 2 * i) = TransformTo(eif.anchor(eif.num_anchors() - 1), eif.landmark(it->second));
      }
    }
    ASSERT_TRUE(eif.Join(s).ok());
    ASSERT_TRUE(ekf.Join(s).ok());
    EXPECT_TRUE(RelativelyNear(StackedEstimate(eif), StackedEstimate(ekf), 1e-8)) << "after map " << k;
    EXPECT_TRUE(RelativelyNear(FullCovariance(eif), FullCovariance(ekf), 1e-8)) << "after map " << k;
  }
  EXPECT_GT(ekf.counters().associated, 5);
}

// With real innovations the two fusions differ only to second order (innovation times
// the start anchor's heading uncertainty): on this loop by much less than one σ.
TEST(EkfJoiner, ZeroNoiseConstraintIsCloseToTheConditionalUpdate) {
  const SyntheticRun run = MakeRun(5, 12, 2.0);
  EkfJoiner zero(run.anchors[0], KnownAssociation(EkfFusion::kZeroNoiseConstraint));
  EkfJoiner conditional(run.anchors[0], KnownAssociation(EkfFusion::kConditionalUpdate));
  for (const LocalSubmap& s : run.submaps) {
    ASSERT_TRUE(zero.Join(s).ok());
    ASSERT_TRUE(conditional.Join(s).ok());
  }
  const Eigen::VectorXd d = StackedEstimate(zero) - StackedEstimate(conditional);
  const Eigen::VectorXd sigma = FullCovariance(conditional).diagonal().cwiseSqrt();
  EXPECT_LT(d.cwiseQuotient(sigma).cwiseAbs().maxCoeff(), 0.1);
  EXPECT_GT(d.cwiseAbs().maxCoeff(), 0.0);  // but they are different algorithms
}

// Marginalising each start anchor out ("replace the vehicle pose") is exact for what
// stays: the landmarks and the current anchor, with their joint covariance.
TEST(EkfJoiner, DroppingAnchorsKeepsTheMapAndTheCurrentAnchor) {
  const SyntheticRun run = MakeRun(8, 12, 2.0);
  EkfJoiner kept(run.anchors[0], KnownAssociation(EkfFusion::kZeroNoiseConstraint, true));
  EkfJoiner dropped(run.anchors[0], KnownAssociation(EkfFusion::kZeroNoiseConstraint, false));
  for (const LocalSubmap& s : run.submaps) {
    ASSERT_TRUE(kept.Join(s).ok());
    ASSERT_TRUE(dropped.Join(s).ok());
  }
  const int last = kept.num_anchors() - 1;
  EXPECT_EQ(dropped.state_dimension(), 3 + 2 * dropped.num_landmarks());
  std::vector<int> landmarks(kept.num_landmarks());
  std::iota(landmarks.begin(), landmarks.end(), 0);
  EXPECT_TRUE(
      RelativelyNear(kept.JointCovariance({last}, landmarks), dropped.JointCovariance({last}, landmarks), 1e-9));
  EXPECT_TRUE(testing::MatricesNear(kept.anchor(last).vector(), dropped.anchor(last).vector(), 1e-9));
  for (int j = 0; j < kept.num_landmarks(); ++j) {
    EXPECT_TRUE(testing::MatricesNear(kept.landmark(j), dropped.landmark(j), 1e-9)) << "landmark " << j;
  }
  // A dropped anchor keeps its estimate and marginal from when it was dropped.
  EXPECT_GT(dropped.AnchorCovariance(3).trace(), 0.0);
  EXPECT_EQ(dropped.anchor_offset(3), -1);
}

// Association is the shared module's: on the same local maps, the EKF (conditional) and
// the EIF, whose states agree, make the same decisions with unknown association.
TEST(EkfJoiner, AssociatesLikeTheEif) {
  for (uint64_t seed : {11, 12}) {
    const SyntheticRun run = MakeRun(seed);
    // The decisions at join time (the joiners revise them on schedules of their own).
    EifJoinerOptions eif_options;
    eif_options.revision.merge = eif_options.revision.split = false;
    EifJoiner eif(run.anchors[0], eif_options);
    EkfJoinerOptions o;
    o.revision = eif_options.revision;
    o.fusion = EkfFusion::kConditionalUpdate;
    EkfJoiner ekf(run.anchors[0], o);
    for (const LocalSubmap& s : run.submaps) {
      ASSERT_TRUE(eif.Join(s).ok());
      ASSERT_TRUE(ekf.Join(s).ok());
      EXPECT_EQ(ekf.last_association(), eif.last_association()) << "seed " << seed << " map " << s.id;
    }
    EXPECT_GT(ekf.counters().associated, 20);
  }
}

TEST(EkfJoiner, RejectsInvalidInput) {
  const SyntheticRun run = MakeRun(2, 3);
  EkfJoiner ekf(run.anchors[0], {});
  LocalSubmap bad = run.submaps[0];
  bad.covariance(0, 0) = -1.0;
  EXPECT_FALSE(ekf.Join(bad).ok());
  ASSERT_TRUE(ekf.Join(run.submaps[1]).ok());
  EXPECT_FALSE(ekf.Join(run.submaps[0]).ok());  // starts before the previous one ended
  EkfJoinerOptions o;
  o.association.landmark_search_radius_m = -1.0;
  EXPECT_FALSE(o.Validate().ok());
}

}  // namespace
}  // namespace subslam::backend
