// The EIF joiner: its information form, marginals, factorisation, association and
// validation against dense references and the truth.

#include "subslam/backend/eif_joiner.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>

#include "dense_gauss_newton.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/frontend/moment_matching.h"
#include "synthetic_run.h"
#include "test_util.h"

namespace subslam::backend {
namespace {

using testing::MatricesNear;

// Λ is Σ_f J_fᵀ Q_f⁻¹ J_f over the factors, however it was assembled. After Gauss-Newton
// (rebuilt from the factors' variable blocks, then refilled) it equals that sum formed
// here from LinearizeSubmapFactor at the converged estimate; local map 0 starts at the
// fixed P0, and local map 13 joins two of its features to one landmark. After
// single-linearisation joins that each refactorise (each factor added to the last Λ) it
// equals a copy's Λ, assembled afresh from the same factors.
TEST(EifJoiner, InformationIsTheSumOfItsFactorsHoweverAssembled) {
  SyntheticRun run = MakeRun(5, 24, 1.0);
  LocalSubmap& twice = run.submaps[13];
  ASSERT_GE(twice.num_landmarks(), 2);
  twice.landmarks[1].truth_id = twice.landmarks[0].truth_id;
  EifJoiner converged(run.anchors[0], ConvergingKnownAssociation());
  EifJoinerOptions added_options;
  added_options.association.known_association = true;
  added_options.relinearize_heading_change = 0.0;
  added_options.relinearize_linearization_chi2 = 0.0;
  added_options.incremental_factorization = false;
  EifJoiner added(run.anchors[0], added_options);
  for (const LocalSubmap& s : run.submaps) {
    ASSERT_TRUE(converged.Join(s).ok());
    ASSERT_TRUE(added.Join(s).ok());
  }
  ASSERT_TRUE(converged.Finish().ok());
  ASSERT_GT(converged.counters().relinearizations, 1);
  const int dim = converged.state_dimension();
  Eigen::MatrixXd expected = Eigen::MatrixXd::Zero(dim, dim);
  int repeated = 0;
  for (const SubmapFactor& f : converged.graph().factors()) {
    std::vector<Eigen::Vector2d> landmarks;
    for (int j : f.landmark_of_feature) landmarks.push_back(converged.landmark(j));
    const SubmapFactorLinearization lin =
        LinearizeSubmapFactor(f.submap, converged.anchor(f.start_anchor), converged.anchor(f.end_anchor), landmarks);
    std::vector<int> rows;  // of the state, per column of J
    std::vector<Eigen::MatrixXd> blocks;
    if (f.start_anchor != 0) {
      for (int i = 0; i < 3; ++i) rows.push_back(converged.anchor_offset(f.start_anchor) + i);
      blocks.push_back(lin.J_start);
    }
    for (int i = 0; i < 3; ++i) rows.push_back(converged.anchor_offset(f.end_anchor) + i);
    blocks.push_back(lin.J_end);
    for (int j : f.landmark_of_feature) {
      for (int i = 0; i < 2; ++i) rows.push_back(converged.landmark_offset(j) + i);
    }
    blocks.push_back(lin.J_landmarks);
    std::set<int> distinct(f.landmark_of_feature.begin(), f.landmark_of_feature.end());
    repeated += static_cast<int>(f.landmark_of_feature.size() - distinct.size());
    Eigen::MatrixXd J(lin.residual.size(), static_cast<Eigen::Index>(rows.size()));
    int c = 0;
    for (const Eigen::MatrixXd& b : blocks) {
      J.middleCols(c, b.cols()) = b;
      c += static_cast<int>(b.cols());
    }
    const Eigen::MatrixXd H = J.transpose() * f.submap.covariance.ldlt().solve(J);
    for (size_t a = 0; a < rows.size(); ++a) {
      for (size_t b = 0; b < rows.size(); ++b) expected(rows[a], rows[b]) += H(a, b);
    }
  }
  EXPECT_EQ(repeated, 1);
  const Eigen::MatrixXd lambda = Eigen::MatrixXd(converged.information());
  EXPECT_LT((lambda - expected).norm(), 1e-8 * expected.norm());
  const std::unique_ptr<MapJoiner> copy = added.Clone();
  const auto* fresh = dynamic_cast<const EifJoiner*>(copy.get());
  ASSERT_NE(fresh, nullptr);
  const Eigen::MatrixXd sum = Eigen::MatrixXd(added.information());
  EXPECT_LT((sum - Eigen::MatrixXd(fresh->information())).norm(), 1e-12 * sum.norm());
}

// The recovered marginals are the blocks of the dense inverse of Λ.
TEST(EifJoiner, MarginalsEqualBlocksOfTheDenseInverse) {
  const SyntheticRun run = MakeRun(5);
  EifJoinerOptions options;
  options.association.known_association = true;
  EifJoiner eif(run.anchors[0], options);
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(eif.Join(s).ok());
  const Eigen::MatrixXd inverse = Eigen::MatrixXd(eif.information()).inverse();
  const std::vector<int> anchors = {3, 7, 12}, landmarks = {2, 5, 9};
  const Eigen::MatrixXd joint = eif.JointCovariance(anchors, landmarks);
  std::vector<int> rows;
  for (int k : anchors) {
    for (int i = 0; i < 3; ++i) rows.push_back(eif.anchor_offset(k) + i);
  }
  for (int j : landmarks) {
    for (int i = 0; i < 2; ++i) rows.push_back(eif.landmark_offset(j) + i);
  }
  EXPECT_TRUE(MatricesNear(inverse(rows, rows), joint, 1e-9));
  EXPECT_TRUE(MatricesNear(joint.block<3, 3>(0, 0), eif.AnchorCovariance(3), 1e-12));
  EXPECT_TRUE(MatricesNear(Eigen::Matrix3d::Zero(), eif.AnchorCovariance(0), 0.0));  // P0 fixed
  // Every marginal at once (the sparse-inverse recursion on the factor's pattern).
  const std::vector<Eigen::Matrix3d> all_anchors = eif.AnchorCovariances();
  const std::vector<Eigen::Matrix2d> all_landmarks = eif.LandmarkCovariances();
  ASSERT_EQ(static_cast<int>(all_anchors.size()), eif.num_anchors());
  ASSERT_EQ(static_cast<int>(all_landmarks.size()), eif.num_landmarks());
  EXPECT_TRUE(MatricesNear(Eigen::Matrix3d::Zero(), all_anchors[0], 0.0));
  for (int k = 1; k < eif.num_anchors(); ++k) {
    const int o = eif.anchor_offset(k);
    EXPECT_TRUE(MatricesNear(inverse.block<3, 3>(o, o), all_anchors[k], 1e-9)) << "anchor " << k;
  }
  for (int j = 0; j < eif.num_landmarks(); ++j) {
    const int o = eif.landmark_offset(j);
    EXPECT_TRUE(MatricesNear(inverse.block<2, 2>(o, o), all_landmarks[j], 1e-9)) << "landmark " << j;
  }
}

// Two joiners of the same local maps agree: every anchor, and the joint marginal of the
// last anchor, anchor 7 and every landmark, to `tolerance` (absolute, per entry).
void ExpectSameEstimates(const EifJoiner& a, const EifJoiner& b, double tolerance) {
  ASSERT_EQ(a.num_anchors(), b.num_anchors());
  ASSERT_EQ(a.num_landmarks(), b.num_landmarks());
  for (int k = 1; k < a.num_anchors(); ++k) {
    EXPECT_TRUE(MatricesNear(a.anchor(k).vector(), b.anchor(k).vector(), tolerance)) << "anchor " << k;
  }
  std::vector<int> landmarks(a.num_landmarks());
  for (int j = 0; j < a.num_landmarks(); ++j) landmarks[j] = j;
  EXPECT_TRUE(MatricesNear(a.JointCovariance({a.num_anchors() - 1, 7}, landmarks),
                           b.JointCovariance({a.num_anchors() - 1, 7}, landmarks), tolerance));
}

// The incremental factor (rank updates of the LDLᵀ factor, new variables in spare slots)
// gives the estimate and the marginals of a full factorisation per join, through loop
// closures, with unknown association — and with known association where one local map
// has two features of one true landmark (the factor then lists that landmark twice).
TEST(EifJoiner, IncrementalFactorEqualsRefactorizingEveryJoin) {
  for (uint64_t seed : {5, 11, 0}) {
    SyntheticRun run = MakeRun(seed == 0 ? 5 : seed, 24, 1.0);
    EifJoinerOptions options;
    options.relinearize_heading_change = 0.0;  // one factorisation per join, no more
    options.relinearize_linearization_chi2 = 0.0;
    if (seed == 0) {
      options.association.known_association = true;
      LocalSubmap& s = run.submaps[13];
      ASSERT_GE(s.num_landmarks(), 2);
      std::set<int> seen;
      for (int k = 0; k < 13; ++k) {
        for (const LocalSubmapLandmark& l : run.submaps[k].landmarks) seen.insert(*l.truth_id);
      }
      ASSERT_TRUE(seen.count(*s.landmarks[0].truth_id) > 0);
      s.landmarks[1].truth_id = s.landmarks[0].truth_id;  // both joined to one landmark
    }
    // Each join's own factorisation only (a revision of the association factorises too).
    options.revision.merge = options.revision.split = false;
    options.incremental_factorization = false;
    EifJoiner full(run.anchors[0], options);
    options.incremental_factorization = true;
    EifJoiner incremental(run.anchors[0], options);
    for (const LocalSubmap& s : run.submaps) {
      ASSERT_TRUE(full.Join(s).ok());
      ASSERT_TRUE(incremental.Join(s).ok());
      ASSERT_EQ(incremental.last_association(), full.last_association()) << "map " << s.id;
    }
    EXPECT_EQ(full.counters().incremental_updates, 0);
    EXPECT_EQ(full.counters().full_factorizations, 24);
    EXPECT_GT(incremental.counters().incremental_updates, 12) << seed;
    EXPECT_EQ(incremental.counters().failed_updates, 0) << seed;
    EXPECT_GT(incremental.counters().associated, 50) << seed;  // loops closed on the way
    if (seed == 0) {
      const std::vector<int>& a = incremental.graph().factors()[13].landmark_of_feature;
      EXPECT_EQ(a[0], a[1]);
    }
    ExpectSameEstimates(full, incremental, 1e-9);
  }
}

// The partial state recovery leaves out changes below its threshold along the way, and
// Finish() makes them good. At the default threshold (10⁻⁹) the joins give the exact
// solves' estimates. With a coarse one (0.1 m, rad) each join's estimate stays within
// about the threshold of the exact one; Finish() (no Gauss-Newton at the end) then solves
// the joiner's own Λx = η, which differs from the exact joiner's only where a factor was
// linearised at a slightly different estimate — far closer than before it.
TEST(EifJoiner, PartialRecoveryStaysNearTheExactEstimateAndFinishSolvesExactly) {
  SyntheticRun run = MakeRun(7, 28, 1.0);
  EifJoinerOptions options;
  options.relinearize_heading_change = 0.0;
  options.relinearize_linearization_chi2 = 0.0;
  options.relinearize_at_end = false;
  options.revision.merge = options.revision.split = false;
  options.association.known_association = true;
  options.recovery_change_threshold = 0.0;  // Λx = η solved afresh at every join
  EifJoiner exact(run.anchors[0], options);
  options.recovery_change_threshold = EifJoinerOptions().recovery_change_threshold;
  EifJoiner fine(run.anchors[0], options);
  options.recovery_change_threshold = 0.1;
  EifJoiner coarse(run.anchors[0], options);
  const auto max_difference = [](const EifJoiner& a, const EifJoiner& b) {
    double worst = 0.0;
    for (int k = 0; k < a.num_anchors(); ++k) {
      worst = std::max(worst, PoseDifference(a.anchor(k), b.anchor(k)).cwiseAbs().maxCoeff());
    }
    return worst;
  };
  for (const LocalSubmap& s : run.submaps) {
    ASSERT_TRUE(exact.Join(s).ok());
    ASSERT_TRUE(fine.Join(s).ok());
    ASSERT_TRUE(coarse.Join(s).ok());
    ASSERT_LT(max_difference(exact, fine), 1e-9) << "map " << s.id;
    ASSERT_LT(max_difference(exact, coarse), 0.1) << "map " << s.id;
  }
  EXPECT_GT(coarse.counters().incremental_updates, 12);
  const double before_finish = max_difference(exact, coarse);
  EXPECT_GT(before_finish, 1e-3);  // something was left out (else Finish() would not be tested)
  ASSERT_TRUE(exact.Finish().ok());
  ASSERT_TRUE(fine.Finish().ok());
  ASSERT_TRUE(coarse.Finish().ok());
  ExpectSameEstimates(exact, fine, 1e-9);
  EXPECT_LT(max_difference(exact, coarse), 0.05 * before_finish);
}

// The fill-reducing ordering changes the factor, not the estimate: joins ordered by
// METIS nested dissection (from the first variable on) make the associations, anchors
// and marginals of joins ordered by AMD, through loop closures with unknown association
// and with the incremental factor's rank updates in between.
TEST(EifJoiner, NestedDissectionOrderingGivesTheJoinsOfAmd) {
  for (uint64_t seed : {5, 11}) {
    SyntheticRun run = MakeRun(seed, 24, 1.0);
    EifJoinerOptions options;
    options.relinearize_heading_change = 0.0;  // the same linearisation in both
    options.relinearize_linearization_chi2 = 0.0;
    options.ordering = FillReducingOrdering::kAmd;
    EifJoiner amd(run.anchors[0], options);
    options.ordering = FillReducingOrdering::kNestedDissection;
    EifJoiner nested(run.anchors[0], options);
    for (const LocalSubmap& s : run.submaps) {
      ASSERT_TRUE(amd.Join(s).ok());
      ASSERT_TRUE(nested.Join(s).ok());
      ASSERT_EQ(nested.last_association(), amd.last_association()) << "map " << s.id;
    }
    EXPECT_EQ(amd.counters().nested_dissection_factorizations, 0);
    EXPECT_GT(nested.counters().full_factorizations, 0);
    EXPECT_EQ(nested.counters().nested_dissection_factorizations, nested.counters().full_factorizations);
    EXPECT_GT(nested.counters().incremental_updates, 12) << seed;
    EXPECT_GT(nested.counters().associated, 50) << seed;
    ExpectSameEstimates(amd, nested, 1e-9);
  }
}

// The automatic ordering on a square driven round many times (every lap re-observes the
// same landmarks, as on a world revisited at random): AMD at first, nested dissection
// once AMD's factor gets costly, with the joins of AMD throughout; a copy made after the
// switch stays switched and joins on as the original does.
TEST(EifJoiner, AutomaticOrderingSwitchesOnARevisitedMapAndACopyKeepsTheSwitch) {
  const SyntheticRun run = MakeRun(5, 60, 1.0);
  EifJoinerOptions options;
  options.association.known_association = true;
  options.relinearize_heading_change = 0.0;  // the same linearisation in both
  options.relinearize_linearization_chi2 = 0.0;
  options.ordering = FillReducingOrdering::kAmd;
  EifJoiner amd(run.anchors[0], options);
  options.ordering = FillReducingOrdering::kAmdOrNestedDissection;
  EifJoiner automatic(run.anchors[0], options);
  const size_t split = run.submaps.size() - 5;
  for (size_t k = 0; k < split; ++k) {
    ASSERT_TRUE(amd.Join(run.submaps[k]).ok());
    ASSERT_TRUE(automatic.Join(run.submaps[k]).ok());
  }
  EXPECT_EQ(amd.counters().nested_dissection_factorizations, 0);
  EXPECT_GT(automatic.counters().nested_dissection_factorizations, 0);
  EXPECT_LT(automatic.counters().nested_dissection_factorizations, automatic.counters().full_factorizations);
  EXPECT_EQ(automatic.factor_ordering(), FillReducingOrdering::kNestedDissection);
  const std::unique_ptr<MapJoiner> copy_base = automatic.Clone();
  auto* copy = dynamic_cast<EifJoiner*>(copy_base.get());
  ASSERT_NE(copy, nullptr);
  EXPECT_EQ(copy->factor_ordering(), FillReducingOrdering::kNestedDissection);
  for (size_t k = split; k < run.submaps.size(); ++k) {
    ASSERT_TRUE(amd.Join(run.submaps[k]).ok());
    ASSERT_TRUE(automatic.Join(run.submaps[k]).ok());
    ASSERT_TRUE(copy->Join(run.submaps[k]).ok());
  }
  EXPECT_EQ(copy->factor_ordering(), FillReducingOrdering::kNestedDissection);
  ExpectSameEstimates(amd, automatic, 1e-9);
  ExpectSameEstimates(automatic, *copy, 1e-9);
}

// The candidates' marginal bounds (bound_candidate_marginals) are upper bounds: after
// every join of loops with unknown association, each [last anchor, landmark] bound minus
// the exact marginal is positive semi-definite — for landmarks bounded at creation and
// for those whose marginal was recovered by an earlier association.
TEST(EifJoiner, CandidateMarginalBoundsAreUpperBounds) {
  for (uint64_t seed : {5, 11}) {
    const SyntheticRun run = MakeRun(seed, 24, 1.0);
    EifJoiner eif(run.anchors[0], {});
    long checked = 0;
    for (const LocalSubmap& s : run.submaps) {
      ASSERT_TRUE(eif.Join(s).ok());
      std::vector<int> landmarks(eif.num_landmarks());
      for (int j = 0; j < eif.num_landmarks(); ++j) landmarks[j] = j;
      // The last anchor, and the fixed P0 (zero anchor block and cross-covariance).
      for (const int anchor : {eif.num_anchors() - 1, 0}) {
        const std::vector<std::optional<association::Matrix5d>> bounds = eif.AnchorLandmarkBounds(anchor, landmarks);
        const std::vector<association::Matrix5d> exact = eif.AnchorLandmarkCovariances(anchor, landmarks);
        for (int j = 0; j < eif.num_landmarks(); ++j) {
          if (!bounds[j].has_value()) continue;
          const Eigen::SelfAdjointEigenSolver<association::Matrix5d> eig(*bounds[j] - exact[j]);
          EXPECT_GE(eig.eigenvalues().minCoeff(), -1e-9 * exact[j].norm()) << "map " << s.id << " landmark " << j;
          // The anchor block and the cross-covariance are exact.
          EXPECT_TRUE(MatricesNear(bounds[j]->leftCols<3>(), exact[j].leftCols<3>(), 1e-9));
          if (anchor == 0) {
            EXPECT_TRUE(bounds[j]->leftCols<3>().isZero(0.0));
          }
          ++checked;
        }
      }
    }
    EXPECT_GT(checked, 500) << seed;
  }
}

// The bounds change the work of association, never its decisions: the same association
// after every join with and without them, and fewer columns of L⁻¹ solved with them.
TEST(EifJoiner, CandidateMarginalBoundsKeepEveryDecision) {
  for (uint64_t seed : {5, 11, 12}) {
    const SyntheticRun run = MakeRun(seed, 24, 1.0);
    EifJoinerOptions options;
    options.bound_candidate_marginals = false;
    EifJoiner exact(run.anchors[0], options);
    options.bound_candidate_marginals = true;
    EifJoiner bounded(run.anchors[0], options);
    for (const LocalSubmap& s : run.submaps) {
      ASSERT_TRUE(exact.Join(s).ok());
      ASSERT_TRUE(bounded.Join(s).ok());
      ASSERT_EQ(bounded.last_association(), exact.last_association()) << "seed " << seed << " map " << s.id;
    }
    EXPECT_GT(bounded.counters().associated, 50) << seed;  // loops closed on the way
    EXPECT_LT(bounded.counters().covariance_columns, exact.counters().covariance_columns) << seed;
    for (int k = 1; k < exact.num_anchors(); ++k) {
      EXPECT_TRUE(MatricesNear(exact.anchor(k).vector(), bounded.anchor(k).vector(), 1e-9)) << "anchor " << k;
    }
  }
}

// Relinearised to convergence, the EIF is batch Gauss-Newton on the submap graph.
TEST(EifJoiner, IteratedToConvergenceEqualsBatchGaussNewton) {
  const SyntheticRun run = MakeRun(7, 12, 3.0);
  EifJoiner eif(run.anchors[0], ConvergingKnownAssociation());
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(eif.Join(s).ok());
  // Reference from the EIF's pre-relinearisation state.
  const SubmapGraph before = eif.graph();
  ASSERT_TRUE(eif.Finish().ok());
  EXPECT_GT(eif.counters().relinearizations, 0);
  const Eigen::VectorXd gn = DenseGaussNewton(before, 50);
  const int A = eif.num_anchors() - 1;
  for (int k = 1; k <= A; ++k) {
    Eigen::Vector3d e = eif.anchor(k).vector() - gn.segment<3>(3 * (k - 1));
    e[2] = WrapAngle(e[2]);
    EXPECT_LT(e.cwiseAbs().maxCoeff(), 1e-8) << "anchor " << k;
  }
  for (int j = 0; j < eif.num_landmarks(); ++j) {
    EXPECT_LT((eif.landmark(j) - gn.segment<2>(3 * A + 2 * j)).cwiseAbs().maxCoeff(), 1e-8) << "landmark " << j;
  }
}

// Unknown association (nearest neighbour with χ² gating on recovered covariances)
// reproduces the true association on these maps.
TEST(EifJoiner, NearestNeighbourAssociationMatchesTruth) {
  for (uint64_t seed : {11, 12, 13}) {
    const SyntheticRun run = MakeRun(seed);
    // The decisions at join time (a revision renumbers the landmarks).
    EifJoinerOptions options;
    options.revision.merge = options.revision.split = false;
    EifJoiner eif(run.anchors[0], options);
    std::map<int, int> global_of_truth;
    int wrong = 0, missed = 0, correct = 0;
    for (const LocalSubmap& s : run.submaps) {
      ASSERT_TRUE(eif.Join(s).ok());
      const std::vector<int>& a = eif.last_association();
      for (int i = 0; i < s.num_landmarks(); ++i) {
        const int truth = *s.landmarks[i].truth_id;
        auto it = global_of_truth.find(truth);
        if (it == global_of_truth.end()) {
          global_of_truth[truth] = a[i];  // first sighting defines the global landmark
        } else if (it->second == a[i]) {
          ++correct;
        } else {
          // A new landmark for a known one is a miss; another known landmark is wrong.
          bool to_other = false;
          for (const auto& [t, g] : global_of_truth) to_other = to_other || (g == a[i] && t != truth);
          (to_other ? wrong : missed) += 1;
        }
      }
    }
    EXPECT_EQ(wrong, 0) << "seed " << seed;
    EXPECT_LE(missed, correct / 20) << "seed " << seed;
    EXPECT_GT(correct, 20) << "seed " << seed;
  }
}

// A local map whose features are grossly wrong (a 5 m shift) but associated by their true
// ids fails validation: the join is undone and redone without associations, so the map
// stays closer to the truth than when the bad map is fused.
TEST(EifJoiner, ValidationRejectsAnInconsistentJoin) {
  SyntheticRun run = MakeRun(6, 12);
  for (int i = 0; i < run.submaps[6].num_landmarks(); ++i) run.submaps[6].mean[3 + 2 * i] += 5.0;
  EifJoinerOptions options;
  options.association.known_association = true;
  EifJoiner fused(run.anchors[0], options);
  options.validate_joins = true;
  EifJoiner validated(run.anchors[0], options);
  for (const LocalSubmap& s : run.submaps) {
    ASSERT_TRUE(fused.Join(s).ok());
    ASSERT_TRUE(validated.Join(s).ok());
  }
  EXPECT_EQ(fused.counters().rejected_joins, 0);
  EXPECT_EQ(validated.counters().rejected_joins, 1);
  EXPECT_EQ(validated.rejected(), std::vector<int>{6});
  EXPECT_EQ(validated.num_anchors(), fused.num_anchors());  // the chain is kept
  EXPECT_LT(AnchorRms(validated.graph(), run), AnchorRms(fused.graph(), run));
}

// One wrong association injected (a feature's truth id swapped for that of another,
// already mapped landmark at least 4 m away; known association then fuses them) is
// caught by validation: that join alone is rejected and redone without associations.
TEST(EifJoiner, ValidationCatchesAnInjectedWrongAssociation) {
  SyntheticRun run = MakeRun(6, 12);
  LocalSubmap& bad = run.submaps[9];
  // A feature of map 9 whose landmark was seen before, and another mapped landmark.
  std::set<int> seen_before;
  for (int k = 0; k < 9; ++k) {
    for (const LocalSubmapLandmark& l : run.submaps[k].landmarks) seen_before.insert(*l.truth_id);
  }
  int feature = -1, wrong_truth = -1;
  for (int i = 0; i < bad.num_landmarks() && feature < 0; ++i) {
    const int t = *bad.landmarks[i].truth_id;
    if (!seen_before.count(t)) continue;
    for (int other : seen_before) {
      bool in_map = false;
      for (const LocalSubmapLandmark& l : bad.landmarks) in_map = in_map || *l.truth_id == other;
      if (!in_map && (run.landmarks[other] - run.landmarks[t]).norm() > 4.0) {
        feature = i;
        wrong_truth = other;
        break;
      }
    }
  }
  ASSERT_GE(feature, 0);
  bad.landmarks[feature].truth_id = wrong_truth;
  EifJoinerOptions options;
  options.association.known_association = true;
  options.validate_joins = true;
  EifJoiner eif(run.anchors[0], options);
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(eif.Join(s).ok());
  EXPECT_EQ(eif.rejected(), std::vector<int>{9});
  EXPECT_EQ(eif.counters().rejected_joins, 1);
  // Without the injection, the same maps pass validation.
  EifJoiner clean(run.anchors[0], options);
  bad.landmarks[feature].truth_id = *MakeRun(6, 12).submaps[9].landmarks[feature].truth_id;
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(clean.Join(s).ok());
  EXPECT_TRUE(clean.rejected().empty());
}

// A one-step local map whose covariance is singular (rank 2: y and θ move together) is
// refused with the reason, and joined once repaired.
TEST(EifJoiner, JoinsAOneStepLocalMapOnceItsCovarianceIsRepaired) {
  const SyntheticRun run = MakeRun(3, 2);
  LocalSubmap one_step;
  one_step.id = run.submaps[1].id + 1;
  one_step.t_start = run.submaps[1].t_end;
  one_step.t_end = one_step.t_start + 0.1;
  one_step.mean = Eigen::Vector3d(0.1, 0.0, 0.0);
  Eigen::Matrix<double, 3, 2> J;  // ∂(x, y, θ)/∂(v, ω) of a 0.1 s step at 1 m/s
  J << 0.1, 0.0, 0.0, 0.005, 0.0, 0.1;
  one_step.covariance = J * Eigen::Vector2d(0.26 * 0.26, 0.0093 * 0.0093).asDiagonal() * J.transpose() +
                        1e-22 * Eigen::Matrix3d::Identity();
  EifJoiner eif(run.anchors[0], {});
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(eif.Join(s).ok());
  const absl::Status rejected = eif.Join(one_step);
  EXPECT_FALSE(rejected.ok());
  EXPECT_NE(rejected.message().find("numerically singular"), std::string::npos) << rejected;
  // The moment matcher's relative floor makes it positive definite but leaves it nearly
  // rigid (smallest eigenvalue below LocalSubmap::kMinVariance); the regularisation rule
  // (which the local mapper and the reader apply) makes it joinable.
  ASSERT_TRUE(frontend::RepairCovariance(&one_step.covariance, 1e-9));
  const absl::Status rigid = eif.Join(one_step);
  EXPECT_NE(rigid.message().find("nearly rigid"), std::string::npos) << rigid;
  EXPECT_EQ(one_step.RegularizeDegenerateCovariance(), 1);
  ASSERT_TRUE(eif.Join(one_step).ok());
  ASSERT_TRUE(eif.Finish().ok());
  EXPECT_EQ(eif.num_anchors(), 4);
  EXPECT_TRUE(eif.LastAnchorCovariance().allFinite());
  EXPECT_EQ(Eigen::LLT<Eigen::Matrix3d>(eif.LastAnchorCovariance()).info(), Eigen::Success);
}

TEST(EifJoiner, RejectsInvalidInput) {
  const SyntheticRun run = MakeRun(2, 3);
  EifJoiner eif(run.anchors[0], {});
  LocalSubmap bad = run.submaps[0];
  bad.covariance(0, 0) = -1.0;
  EXPECT_FALSE(eif.Join(bad).ok());
  ASSERT_TRUE(eif.Join(run.submaps[1]).ok());
  EXPECT_FALSE(eif.Join(run.submaps[0]).ok());  // starts before the previous one ended
  EifJoinerOptions o;
  o.association.gate_probability = 1.0;
  EXPECT_FALSE(o.Validate().ok());
  EifJoinerOptions threshold;
  threshold.recovery_change_threshold = -1e-9;
  EXPECT_FALSE(threshold.Validate().ok());
  threshold.recovery_change_threshold = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(threshold.Validate().ok());
}

}  // namespace
}  // namespace subslam::backend
