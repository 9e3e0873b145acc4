// The EIF joiner's relinearisation: its triggers, Gauss-Newton's stopping rules and
// their agreement with the converged solution.

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <sstream>

#include "dense_gauss_newton.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/frontend/moment_matching.h"
#include "synthetic_run.h"
#include "test_util.h"

namespace subslam::backend {
namespace {

using testing::MatricesNear;

void ExpectAnchorsAtGaussNewtonsSolution(const EifJoiner& joiner, int map_id) {
  const Eigen::VectorXd gn = DenseGaussNewton(joiner.graph(), 50);
  for (int k = 1; k < joiner.num_anchors(); ++k) {
    Eigen::Vector3d e = joiner.anchor(k).vector() - gn.segment<3>(3 * (k - 1));
    e[2] = WrapAngle(e[2]);
    EXPECT_LT(e.cwiseAbs().maxCoeff(), 1e-8) << "map " << map_id << ", anchor " << k;
  }
}

// relinearize_heading_change: a join is followed by a relinearisation exactly when an
// anchor's heading has moved that far from one of its factors' linearisation. With a
// threshold no move reaches, the joiner never relinearises and equals the single
// linearisation; with a zero-width one it relinearises (to convergence) after every join,
// so after every join it is the batch Gauss-Newton solution of the graph so far.
TEST(EifJoiner, RelinearizesWhenAHeadingHasMovedFromItsLinearization) {
  const SyntheticRun run = MakeRun(7, 12, 3.0);
  const auto options = [](double heading_change) {
    EifJoinerOptions o = ConvergingKnownAssociation();
    o.relinearize_at_end = false;
    o.relinearize_heading_change = heading_change;
    o.relinearize_linearization_chi2 = 0.0;  // the heading trigger alone
    return o;
  };
  EifJoiner off(run.anchors[0], options(0.0)), never(run.anchors[0], options(10.0));
  EifJoiner always(run.anchors[0], options(1e-12)), some(run.anchors[0], options(0.02));
  for (const LocalSubmap& s : run.submaps) {
    for (EifJoiner* j : {&off, &never, &always, &some}) ASSERT_TRUE(j->Join(s).ok());
    if (s.id == 0) continue;  // nothing moved yet
    ExpectAnchorsAtGaussNewtonsSolution(always, s.id);
  }
  EXPECT_EQ(never.counters().relinearizations, 0);
  // Gauss-Newton iterations after the first refactorise the same pattern: its analysis is reused.
  EXPECT_GT(always.counters().reused_analyses, 0);
  EXPECT_LT(always.counters().reused_analyses, always.counters().full_factorizations);
  for (int k = 0; k < off.num_anchors(); ++k) {
    EXPECT_EQ(never.anchor(k).vector(), off.anchor(k).vector()) << "anchor " << k;
  }
  // A threshold between: some relinearisation, and fewer Gauss-Newton iterations.
  EXPECT_GT(some.counters().relinearizations, 0);
  EXPECT_LT(some.counters().relinearizations, always.counters().relinearizations);
}

// The largest whitened error, at the estimate `now`, of the factors' linear models, each
// taken at the linearisation point lin_point(k) = (start anchor, end anchor, landmarks in
// the factor's order): residual and Jacobian from LinearizeSubmapFactor.
struct LinearizationPoint {
  Pose2 start, end;
  std::vector<Eigen::Vector2d> landmarks;
};
double DefinedMaxLinearizationError(const SubmapGraph& now,
                                    const std::function<LinearizationPoint(size_t)>& lin_point) {
  double worst = 0.0;
  for (size_t k = 0; k < now.factors().size(); ++k) {
    const SubmapFactor& f = now.factors()[k];
    const LocalSubmap& s = f.submap;
    const LinearizationPoint x0 = lin_point(k);
    std::vector<Eigen::Vector2d> landmarks;
    for (int i = 0; i < s.num_landmarks(); ++i) landmarks.push_back(now.landmarks()[f.landmark_of_feature[i]]);
    const SubmapFactorLinearization lin0 = LinearizeSubmapFactor(s, x0.start, x0.end, x0.landmarks);
    const Pose2 start = now.anchors()[f.start_anchor], end = now.anchors()[f.end_anchor];
    const SubmapFactorLinearization lin = LinearizeSubmapFactor(s, start, end, landmarks);
    Eigen::Vector3d d_start = start.vector() - x0.start.vector(), d_end = end.vector() - x0.end.vector();
    d_start[2] = WrapAngle(d_start[2]);
    d_end[2] = WrapAngle(d_end[2]);
    Eigen::VectorXd d_landmarks(2 * s.num_landmarks());
    for (int i = 0; i < s.num_landmarks(); ++i) d_landmarks.segment<2>(2 * i) = landmarks[i] - x0.landmarks[i];
    Eigen::VectorXd e = lin.residual - lin0.residual - lin0.J_end * d_end - lin0.J_landmarks * d_landmarks;
    if (f.start_anchor != 0) e -= lin0.J_start * d_start;  // P0 is fixed
    e[2] = WrapAngle(e[2]);
    const Eigen::LLT<Eigen::MatrixXd> llt(s.covariance);
    llt.matrixL().solveInPlace(e);
    worst = std::max(worst, e.squaredNorm());
  }
  return worst;
}

// MaxLinearizationError against its definition: each factor's linearisation point
// rebuilt from the estimate before its join (the new end anchor and landmarks placed
// through the start anchor, as the joiner does), the error of that linear model at the
// final estimate. After Gauss-Newton to convergence it is ~0.
TEST(EifJoiner, MaxLinearizationErrorIsTheWhitenedErrorOfTheLinearModels) {
  const SyntheticRun run = MakeRun(7, 12, 3.0);
  EifJoinerOptions options = ConvergingKnownAssociation().SingleLinearization();
  EifJoiner eif(run.anchors[0], options);
  std::vector<SubmapGraph> before;  // the estimate before each join
  for (const LocalSubmap& s : run.submaps) {
    before.push_back(eif.graph());
    ASSERT_TRUE(eif.Join(s).ok());
  }
  const double expected = DefinedMaxLinearizationError(eif.graph(), [&](size_t k) {
    const SubmapFactor& f = eif.graph().factors()[k];
    const SubmapGraph& b = before[k];
    LinearizationPoint x0;
    x0.start = b.anchors()[f.start_anchor];
    x0.end = Compose(x0.start, f.submap.end_pose());
    for (int i = 0; i < f.submap.num_landmarks(); ++i) {
      const int j = f.landmark_of_feature[i];
      x0.landmarks.push_back(j < b.num_landmarks() ? b.landmarks()[j] : TransformFrom(x0.start, f.submap.landmark(i)));
    }
    return x0;
  });
  EXPECT_GT(expected, 1e-3);  // the estimate has moved from the linearisation points
  EXPECT_NEAR(eif.MaxLinearizationError(), expected, 1e-9 * expected);

  EifJoiner converged(run.anchors[0], ConvergingKnownAssociation());
  for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(converged.Join(s).ok());
  ASSERT_TRUE(converged.Finish().ok());
  EXPECT_LT(converged.MaxLinearizationError(), 1e-12);
}

// After Gauss-Newton stopped on a predicted step (predict_convergence) the factors are
// back at the previous iterate's linearisation — headings and levers — while the
// estimate is that linearisation's solution. Two iterations at most, from the single
// linearisation's estimate x: the first relinearises every factor at x and steps to x₁;
// the second's predicted step stops it, so the linear models are x's, evaluated at x₁.
TEST(EifJoiner, LinearizationErrorAfterAPredictedStopIsThePreviousLinearizations) {
  const SyntheticRun run = MakeRun(7, 12, 3.0);
  bool seen = false;
  for (double tolerance : {1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 3e-4, 1e-4}) {
    EifJoinerOptions options = ConvergingKnownAssociation().SingleLinearization();
    options.relinearize_at_end = true;
    options.predict_convergence = true;
    options.max_relinearizations = 2;
    options.relinearize_tolerance = tolerance;
    EifJoiner eif(run.anchors[0], options);
    for (const LocalSubmap& s : run.submaps) ASSERT_TRUE(eif.Join(s).ok());
    const SubmapGraph x = eif.graph();
    ASSERT_TRUE(eif.Finish().ok());
    if (eif.counters().relinearizations_predicted_converged != 1) continue;
    seen = true;
    const double expected = DefinedMaxLinearizationError(eif.graph(), [&](size_t k) {
      const SubmapFactor& f = x.factors()[k];
      LinearizationPoint x0{x.anchors()[f.start_anchor], x.anchors()[f.end_anchor], {}};
      for (int j : f.landmark_of_feature) x0.landmarks.push_back(x.landmarks()[j]);
      return x0;
    });
    EXPECT_GT(expected, 1e-12) << "tolerance " << tolerance;
    EXPECT_NEAR(eif.MaxLinearizationError(), expected, 1e-6 * expected) << "tolerance " << tolerance;
  }
  EXPECT_TRUE(seen) << "no tolerance gave a predicted stop on the second iteration";
}

// relinearize_linearization_chi2: as the heading trigger, but on the factors' whitened
// linearisation error. A threshold no error reaches never relinearises (the single
// linearisation); a zero-width one relinearises after every join (the batch Gauss-Newton
// solution of the graph so far); one between does some of that work.
TEST(EifJoiner, RelinearisesWhenAFactorsLinearModelIsOffByMoreThanItsNoise) {
  const SyntheticRun run = MakeRun(7, 12, 3.0);
  const auto options = [](double chi2) {
    EifJoinerOptions o = ConvergingKnownAssociation();
    o.relinearize_at_end = false;
    o.relinearize_heading_change = 0.0;  // this trigger alone
    o.relinearize_linearization_chi2 = chi2;
    return o;
  };
  EifJoiner off(run.anchors[0], options(0.0)), never(run.anchors[0], options(1e12));
  const double between = 0.01;  // the synthetic run's single linearisation ends at 0.06
  EifJoiner always(run.anchors[0], options(1e-15)), some(run.anchors[0], options(between));
  for (const LocalSubmap& s : run.submaps) {
    for (EifJoiner* j : {&off, &never, &always, &some}) ASSERT_TRUE(j->Join(s).ok());
    EXPECT_LE(some.MaxLinearizationError(), between) << "map " << s.id;
    if (s.id == 0) continue;
    ExpectAnchorsAtGaussNewtonsSolution(always, s.id);
  }
  EXPECT_EQ(never.counters().relinearizations, 0);
  for (int k = 0; k < off.num_anchors(); ++k) {
    EXPECT_EQ(never.anchor(k).vector(), off.anchor(k).vector()) << "anchor " << k;
  }
  EXPECT_GT(off.MaxLinearizationError(), between);  // so `some` had something to do
  EXPECT_GT(some.counters().relinearized_on_linearization_error, 0);
  EXPECT_EQ(some.counters().relinearized_on_heading, 0);
  EXPECT_LT(some.counters().relinearizations, always.counters().relinearizations);
}

// The divergence stop of relinearisation (divergence_rises), on local maps whose end
// headings were corrupted by ±1.5 rad: a case where the first Gauss-Newton step raises
// the cost before later ones lower it. With one rise allowed (the default: two in a row
// stop) the iterations go on to a lower cost; with none (monotone Gauss-Newton) the
// first step is undone — the starting linearisation and its estimate restored, counted.
TEST(EifJoiner, RelinearisationStopsAtItsBestIterateAfterTooManyCostRises) {
  SyntheticRun run = MakeRun(4, 24);
  for (int k = 5; k < 24; k += 6) run.submaps[k].mean[2] += (k % 12 == 5 ? 1.5 : -1.5);
  const auto joined = [&](bool relinearize, int rises) {
    EifJoinerOptions options;
    options.association.known_association = true;
    options.relinearize_at_end = relinearize;
    options.relinearize_heading_change = 0.0;  // relinearised only at the end, if at all
    options.relinearize_linearization_chi2 = 0.0;
    options.divergence_rises = rises;
    auto eif = std::make_unique<EifJoiner>(run.anchors[0], options);
    for (const LocalSubmap& s : run.submaps) EXPECT_TRUE(eif->Join(s).ok());
    EXPECT_TRUE(eif->Finish().ok());
    return eif;
  };
  const std::unique_ptr<EifJoiner> single = joined(false, 2);
  const std::unique_ptr<EifJoiner> allowed = joined(true, 2);
  const std::unique_ptr<EifJoiner> monotone = joined(true, 1);
  const std::unique_ptr<EifJoiner> unwatched = joined(true, 0);
  const double start = single->Cost();
  EXPECT_EQ(allowed->counters().relinearizations_diverged, 0);
  EXPECT_GT(allowed->counters().relinearizations, 2);
  EXPECT_LT(allowed->Cost(), 0.6 * start);
  EXPECT_EQ(unwatched->counters().relinearizations_diverged, 0);
  EXPECT_NEAR(unwatched->Cost(), allowed->Cost(), 1e-9 * start);
  EXPECT_EQ(monotone->counters().relinearizations_diverged, 1);
  EXPECT_EQ(monotone->counters().relinearizations, 1);
  EXPECT_NEAR(monotone->Cost(), start, 1e-9 * start);
  for (size_t k = 0; k < run.anchors.size(); ++k) {
    EXPECT_TRUE(MatricesNear(monotone->graph().anchors()[k].vector(), single->graph().anchors()[k].vector(), 1e-9))
        << "anchor " << k;
  }
}

// Gauss-Newton cut short by max_relinearizations: the watch linearises once more at the
// last iterate for its cost, and then the linearisation that iterate solves must be the
// one the factors keep, as without the watch — a copy assembles Λ from the factors again,
// and the joins after it build on them.
TEST(EifJoiner, RelinearizationCutShortKeepsTheLinearizationItsEstimateSolves) {
  SyntheticRun run = MakeRun(4, 24);
  for (int k = 5; k < 24; k += 6) run.submaps[k].mean[2] += (k % 12 == 5 ? 0.8 : -0.8);
  const auto joined = [&](int rises, int limit) {
    EifJoinerOptions options;
    options.association.known_association = true;
    options.relinearize_heading_change = 0.0;
    options.relinearize_linearization_chi2 = 0.0;
    options.relinearize_every = 6;  // Gauss-Newton after joins 6, 12 and 18
    options.relinearize_at_end = false;
    options.max_relinearizations = limit;
    options.divergence_rises = rises;
    auto eif = std::make_unique<EifJoiner>(run.anchors[0], options);
    for (int k = 0; k < 20; ++k) EXPECT_TRUE(eif->Join(run.submaps[k]).ok());
    return eif;
  };
  const std::unique_ptr<EifJoiner> watched = joined(2, 2), unwatched = joined(0, 2), uncut = joined(2, 20);
  EXPECT_GT(uncut->counters().relinearizations, watched->counters().relinearizations);  // the limit cut
  EXPECT_EQ(watched->counters().relinearizations_diverged, 0);
  EXPECT_EQ(watched->counters().relinearizations, unwatched->counters().relinearizations);
  EXPECT_TRUE(MatricesNear(StackedEstimate(*watched), StackedEstimate(*unwatched), 1e-12));
  const std::unique_ptr<MapJoiner> watched_copy = watched->Clone(), unwatched_copy = unwatched->Clone();
  const Eigen::MatrixXd lambda(dynamic_cast<const EifJoiner&>(*unwatched_copy).information());
  EXPECT_TRUE(MatricesNear(Eigen::MatrixXd(dynamic_cast<const EifJoiner&>(*watched_copy).information()), lambda,
                           1e-12 * lambda.norm()));
}

// The last local map of a run may span one step: no features, and a pose covariance of
// rank 2 that only rounding keeps positive definite. Joined as is it made CHOLMOD fail
// (and `subslam run` abort); it is now rejected with a clear error, and joins once
// repaired as the front-ends repair it.

// (x̂_stopped − x̂_converged)ᵀ Σ⁻¹ (…), Σ the converged joiner's covariance of every anchor
// and landmark (headings wrapped).
double SquaredDistanceInCovariance(const EifJoiner& stopped, const EifJoiner& converged) {
  std::vector<int> anchors, landmarks;
  for (int k = 1; k < converged.num_anchors(); ++k) anchors.push_back(k);
  for (int j = 0; j < converged.num_landmarks(); ++j) landmarks.push_back(j);
  const Eigen::MatrixXd covariance = converged.JointCovariance(anchors, landmarks);
  Eigen::VectorXd difference = StackedEstimate(stopped) - StackedEstimate(converged);
  for (size_t k = 0; k < anchors.size(); ++k) difference[3 * k + 2] = WrapAngle(difference[3 * k + 2]);
  return difference.dot(covariance.ldlt().solve(difference));
}

// relinearize_step_chi2, ISEIF's adaptive stop with the Mahalanobis length of the step:
// Gauss-Newton stops once a step is a small fraction of the estimate's uncertainty. While
// each step shrinks by at least half (linear convergence), the steps still to come sum to
// less than the last one, so the stopped estimate lies within that χ² distance of the
// converged one, measured in the converged estimate's own covariance.
TEST(EifJoiner, GaussNewtonStopsWhenTheStepIsSmallInTheInformationMetric) {
  const SyntheticRun run = MakeRun(8, 12, 3.0);
  constexpr double kStepChi2 = 1e-3;
  EifJoinerOptions converged_options = ConvergingKnownAssociation();
  EifJoinerOptions stopped_options = converged_options;
  stopped_options.relinearize_step_chi2 = kStepChi2;
  EifJoiner converged(run.anchors[0], converged_options), stopped(run.anchors[0], stopped_options);
  for (const LocalSubmap& s : run.submaps) {
    ASSERT_TRUE(converged.Join(s).ok());
    ASSERT_TRUE(stopped.Join(s).ok());
  }
  ASSERT_TRUE(converged.Finish().ok());
  ASSERT_TRUE(stopped.Finish().ok());
  EXPECT_LT(stopped.counters().relinearizations, converged.counters().relinearizations);
  const double distance2 = SquaredDistanceInCovariance(stopped, converged);
  EXPECT_GT(distance2, 0.0);  // it did stop short
  EXPECT_LT(distance2, kStepChi2);
}

// predict_convergence: before another Gauss-Newton iteration, its step is solved with the
// factor at hand (of the previous linearisation). Stopping there, when that step is below
// a quarter of the χ² bound, leaves the estimate as close to the converged one as the step
// test does, with fewer factorisations; the previous linearisation is kept, whose solution
// the estimate is, so the joins that follow still update the factor incrementally.
TEST(EifJoiner, GaussNewtonStopsOnThePredictedStepWithoutAnotherFactorization) {
  const SyntheticRun run = MakeRun(8, 12, 3.0);
  constexpr double kStepChi2 = 1e-3;
  EifJoinerOptions converged_options = ConvergingKnownAssociation();
  converged_options.relinearize_heading_change = 0.02;  // Gauss-Newton during the run too
  EifJoinerOptions confirmed_options = converged_options;
  confirmed_options.relinearize_step_chi2 = kStepChi2;
  confirmed_options.relinearize_tolerance = 1e-3;
  EifJoinerOptions predicted_options = confirmed_options;
  predicted_options.predict_convergence = true;
  EifJoiner converged(run.anchors[0], converged_options), confirmed(run.anchors[0], confirmed_options),
      predicted(run.anchors[0], predicted_options);
  long predicted_during_run = 0, updates_after_a_stop = 0;
  for (const LocalSubmap& s : run.submaps) {
    const long updates_before = predicted.counters().incremental_updates;
    for (EifJoiner* j : {&converged, &confirmed, &predicted}) ASSERT_TRUE(j->Join(s).ok());
    if (predicted_during_run > 0) updates_after_a_stop += predicted.counters().incremental_updates - updates_before;
    predicted_during_run = predicted.counters().relinearizations_predicted_converged;
  }
  for (EifJoiner* j : {&converged, &confirmed, &predicted}) ASSERT_TRUE(j->Finish().ok());
  EXPECT_GT(predicted_during_run, 0);
  EXPECT_GT(predicted.counters().relinearizations_predicted_converged, predicted_during_run);  // and at the end
  EXPECT_EQ(confirmed.counters().relinearizations_predicted_converged, 0);
  EXPECT_LT(predicted.counters().full_factorizations, confirmed.counters().full_factorizations);
  // The joins after a predicted stop updated the factor of the kept linearisation: the
  // update's check (Λx = η over the factors' H) would fail on the trial one.
  EXPECT_GT(updates_after_a_stop, 0);
  EXPECT_EQ(predicted.counters().failed_updates, 0);
  // After the stop at the end, the factor is still that of Λ.
  {
    std::vector<int> anchors, landmarks, rows;
    for (int k = 1; k < predicted.num_anchors(); ++k) {
      anchors.push_back(k);
      for (int i = 0; i < 3; ++i) rows.push_back(predicted.anchor_offset(k) + i);
    }
    for (int j = 0; j < predicted.num_landmarks(); ++j) {
      landmarks.push_back(j);
      for (int i = 0; i < 2; ++i) rows.push_back(predicted.landmark_offset(j) + i);
    }
    const Eigen::MatrixXd dense_inverse = Eigen::MatrixXd(predicted.information()).inverse();
    EXPECT_TRUE(MatricesNear(dense_inverse(rows, rows), predicted.JointCovariance(anchors, landmarks), 1e-9));
  }
  const double distance2 = SquaredDistanceInCovariance(predicted, converged);
  EXPECT_GT(distance2, 0.0);  // it did stop short
  EXPECT_LT(distance2, kStepChi2);
}

// loop_confirmation_maps: after a long loop the start anchor is lost (3σ ≈ 100 m). The
// closing map's four features fit four of map 0's trees, in both runs below: in one they
// are those trees, in the other four new ones in the same layout elsewhere. Where the
// closure is true, the next map sees map 0's other trees, which confirms it; where it is a
// chance fit, the next three maps see nothing old, and the closure is undone: the closing
// map's features become new landmarks.

}  // namespace
}  // namespace subslam::backend
