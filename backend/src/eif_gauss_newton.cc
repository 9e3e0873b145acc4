// EifJoiner: relinearisation — Gauss-Newton over the submap graph with its stopping rules,
// and adopting an estimate solved elsewhere (the Ceres back-end).

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "eif_joiner_impl.h"
#include "state_blocks.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/internal/sparse_cholesky.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/core/check.h"
#include "subslam/core/stage_timer.h"
#include "subslam/models/gating.h"

namespace subslam::backend {

bool EifJoiner::Impl::PredictedStepConverged(const Eigen::VectorXd& x) {
  // The factors are linearised at x: Σ_f (H_f x_f − b_f) = Σ_f J_fᵀ Q_f⁻¹ r_f(x) is the
  // gradient g of Cost()/2 at x, and the Gauss-Newton step is −Λ(x)⁻¹ g. The factor at
  // hand is of Λ at the previous linearisation point, a step away, whose headings differ
  // by that step's (the factor is nonlinear only through the headings): δ = −Λ_prev⁻¹ g.
  Eigen::VectorXd g = Eigen::VectorXd::Zero(estimate_.dim), eta = Eigen::VectorXd::Zero(estimate_.dim);
  for (const EifFactor& f : factors_) {
    f.AddInformationTimes(x, &g);
    f.AddToEta(&eta);
  }
  g -= eta;
  Eigen::VectorXd step;
  {
    StageTimer timer(&times_, "recovery");
    step = -solver_.factor.Solve(g);
  }
  if (!step.allFinite()) return false;
  // With each step at most half the last (linear convergence), the steps still to come sum
  // to less than twice this one: it is held to half the tolerance and a quarter of the χ²
  // bound, so that the stopped estimate is as close to the converged one as when a step
  // taken is below them.
  if (step.cwiseAbs().maxCoeff() < 0.5 * options_.relinearize_tolerance) return true;
  return options_.relinearize_step_chi2 > 0.0 && -g.dot(step) < 0.25 * options_.relinearize_step_chi2;
}

absl::Status EifJoiner::Impl::Relinearize() {
  if (absl::Status st = GaussNewton(); !st.ok()) return st;
  // Every factor moved, so the landmarks' marginal bounds were forgotten: today's exact
  // marginals, all at once from the sparse inverse, bound every later one until the next
  // relinearisation (Λ only grows), so association can skip candidates at once again
  // (association by truth ids has no candidates).
  if (options_.bound_candidate_marginals && !options_.association.known_association &&
      estimate_.graph.num_landmarks() > 0) {
    StageTimer timer(&times_, "covariance_recovery");
    marginal_bound_ = LandmarkCovariances();
  }
  return absl::OkStatus();
}

absl::Status EifJoiner::Impl::GaussNewton() {
  // Gauss-Newton need not lower the cost at every iteration (a first step often raises
  // it a little on the way to a lower minimum), but `divergence_rises` rises in a row
  // mean divergence (seen with wrong associations): then the best iterate is restored —
  // the factors' linearisation whose solution it was — and the iterations end. An
  // iterate's cost comes with the factors' linearisation at it (EifFactor::cost), at the
  // start of the next iteration; a step that ends the iterations as converged is below
  // the tolerances, and its cost is not asked for.
  const int max_rises = options_.divergence_rises;
  const bool watch = max_rises > 0 && options_.max_relinearizations >= max_rises;
  double best_cost = 0.0, last_cost = 0.0;
  int rises = 0;
  // Linearisations set aside, swapped, never copied: `previous` holds the one the factor
  // and the estimate belong to while the factors take the next; `best` the one whose
  // solution is the best iterate, once `previous` is needed for a later one.
  std::vector<EifFactor::Linearization> previous, best;
  bool best_is_previous = false;
  const auto restore = [this](std::vector<EifFactor::Linearization>* from) {
    for (size_t k = 0; k < factors_.size(); ++k) factors_[k].SwapLinearization(&(*from)[k]);
  };
  for (int it = 0; it <= options_.max_relinearizations; ++it) {
    // One more linearisation after the last step, for the watch alone.
    if (it == options_.max_relinearizations && !watch) break;
    const Eigen::VectorXd before = estimate_.StateVector();
    const bool check = it > 0 && options_.predict_convergence;
    if (watch || check) {
      if (best_is_previous) {
        best.swap(previous);
        best_is_previous = false;
      }
      previous.resize(factors_.size());
      restore(&previous);
    }
    double cost = 0.0;
    {
      StageTimer timer(&times_, "update");
      for (EifFactor& f : factors_) {
        f.Linearize(estimate_);
        cost += f.cost;
      }
    }
    if (watch) {  // `cost` is the estimate's, the solution of `previous`
      // Near convergence the cost changes by its rounding error only (about 1e-12 of it
      // here), up or down: a rise counts when it is well above that.
      constexpr double kRoundingFloor = 1e-8;
      rises = it > 0 && cost > last_cost * (1.0 + kRoundingFloor) ? rises + 1 : 0;
      last_cost = cost;
      if (it == 0 || cost < best_cost) {
        best_cost = cost;
        best_is_previous = true;
      } else if (rises >= max_rises || !std::isfinite(cost)) {
        ++counters_.relinearizations_diverged;
        restore(best_is_previous ? &previous : &best);
        return Rebuild(/*only_last_factor=*/false);
      }
    }
    if (it == options_.max_relinearizations) {
      // No step left: the estimate stays the solution of the linearisation before.
      restore(&previous);
      break;
    }
    if (check && PredictedStepConverged(before)) {
      // The estimate solves the previous linearisation and the step from it is already
      // small: that linearisation stays, without another factorisation.
      restore(&previous);
      ++counters_.relinearizations_predicted_converged;
      converged_ = true;
      break;
    }
    if (absl::Status s = Rebuild(/*only_last_factor=*/false); !s.ok()) return s;
    ++counters_.relinearizations;
    const Eigen::VectorXd step = estimate_.StateVector() - before;
    if (step.cwiseAbs().maxCoeff() < options_.relinearize_tolerance) {
      converged_ = true;
      break;
    }
    // The step's length in the information metric of the linearisation that produced it
    // (ΔxᵀΛΔx, the decrease of Cost() it predicts): a small fraction of the estimate's
    // uncertainty is converged for estimation, however far it moved an ill-determined
    // variable in metres.
    if (InformationNorm(step) < options_.relinearize_step_chi2) {
      converged_ = true;
      break;
    }
  }
  return absl::OkStatus();
}

absl::Status EifJoiner::Impl::AdoptEstimate(const SubmapGraph& solved) {
  if (solved.num_anchors() != estimate_.graph.num_anchors() ||
      solved.num_landmarks() != estimate_.graph.num_landmarks()) {
    return absl::InvalidArgumentError("AdoptEstimate: not the joiner's graph");
  }
  for (int k = 1; k < estimate_.graph.num_anchors(); ++k) {
    const Pose2& p = solved.anchors()[k];
    estimate_.anchor_theta[k] += WrapAngle(p.theta - estimate_.anchor_theta[k]);  // stay continuous
    estimate_.graph.anchor(k) = Pose2(p.x, p.y, WrapAngle(p.theta));
  }
  for (int j = 0; j < estimate_.graph.num_landmarks(); ++j) estimate_.graph.landmark(j) = solved.landmarks()[j];
  {
    StageTimer timer(&times_, "update");
    for (EifFactor& f : factors_) f.Linearize(estimate_);
  }
  return Rebuild(/*only_last_factor=*/false);
}

double EifJoiner::Impl::Cost() const {
  double cost = 0.0;
  for (const EifFactor& f : factors_) cost += f.NormalizedResidual(estimate_);
  return cost;
}

double EifJoiner::Impl::MaxLinearizationError() const {
  double worst = 0.0;
  for (const EifFactor& f : factors_) worst = std::max(worst, f.LinearizationError(estimate_));
  return worst;
}

bool EifJoiner::Impl::LinearizationErrorAbove(double chi2) {
  bool all = true;
  std::vector<int> which;
  linearization_watch_.FactorsToTest(factors_, estimate_.dim, &all, &which);
  const int count = all ? static_cast<int>(factors_.size()) : static_cast<int>(which.size());
  Eigen::VectorXd e;
  for (int c = 0; c < count; ++c) {
    if (factors_[all ? c : which[c]].LinearizationErrorAbove(estimate_, chi2, &e)) return true;
  }
  return false;
}

double EifJoiner::Impl::MaxHeadingDrift() const {
  double drift = 0.0;
  for (const EifFactor& f : factors_) drift = std::max(drift, f.HeadingDrift(estimate_));
  return drift;
}

}  // namespace subslam::backend
