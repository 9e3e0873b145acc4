#include "grouped_association.h"

#include <algorithm>
#include <cmath>
#include <memory>

namespace subslam::association::submap_matching {
namespace {

// Step 4 for a whole map, group by group (the features of each of its local maps, in
// order): each group's JCBB given the pairings the groups before it kept (required, their
// innovations gated conditionally on them, as if fused), then the loop tests on that
// group's pairings alone, as sequential joining applies them to each local map. A feature
// left unpaired is decided again by a later group that holds it. Once a group has closed a
// loop (min_loop_pairings kept), the later groups are gated given that closure and the
// loop tests no longer apply, as after a sequential join has fused it; under a lost
// anchor the closure must be confirmed by one of the next loop_confirmation_maps groups,
// or the decisions from its group on are made again without its loop pairings.
class GroupedAssociation {
 public:
  // `relinearization`: rebuilds the problem about the start anchor the decided pairings imply (null:
  // the prior's linearisation throughout).
  GroupedAssociation(const SubmapAssociationOptions& o, const LocalSubmap& s, const std::vector<int>& candidates,
                     const LoopFlags& loop, const association::AssociationProblem& problem,
                     Relinearization* relinearization, SubmapAssociation* out)
      : o_(o),
        s_(s),
        candidates_(candidates),
        loop_(loop),
        problem_(&problem),
        relinearization_(relinearization),
        out_(out) {}

  association::AssociationResult Solve(const std::vector<std::vector<int>>& groups) {
    State state;
    state.landmark_of_feature.assign(s_.num_landmarks(), -1);
    state.paired_landmark.assign(candidates_.size(), 0);
    state.loop_open = loop_.regime;
    state.problem = problem_;
    const bool confirm = loop_.regime && o_.loop_confirmation_maps > 0 &&
                         3.0 * loop_.sigma_xy >= o_.loop_confirmation_min_sigma_radius_m;
    std::optional<State> before_closure;  // the state before a closure waiting for confirmation
    int closing_group = -1, suppressed_group = -1;
    const int num_groups = static_cast<int>(groups.size());
    for (int g = 0; g <= num_groups; ++g) {
      // Unconfirmed by the next loop_confirmation_maps groups, or still waiting after the
      // last one (the maps that would confirm it come in a later join, which can close the
      // loop with them): the decisions from the closing group on are made again, without
      // its loop pairings. Closing groups only move on, so this ends.
      const bool waiting_at_end = g == num_groups && before_closure.has_value();
      if (waiting_at_end || (before_closure.has_value() && g - closing_group > o_.loop_confirmation_maps)) {
        ++out_->loop_closures_unconfirmed;
        state = std::move(*before_closure);
        before_closure.reset();
        problem_ = state.problem;
        suppressed_group = closing_group;
        g = closing_group;
      }
      if (g == num_groups) break;
      State before = confirm && !before_closure.has_value() ? state : State();
      const GroupOutcome outcome = AssociateGroup(groups[g], /*suppress_loop=*/g == suppressed_group, &state);
      if (outcome.closed_loop && relinearization_ != nullptr) {
        std::vector<std::pair<int, int>> pairs;
        for (int i : state.decided) pairs.push_back({i, state.landmark_of_feature[i]});
        problem_ = &relinearization_->At(relinearization_->Fit(pairs), pairs);
        state.problem = problem_;
      }
      if (before_closure.has_value()) {
        if (outcome.found_old_landmark) {
          ++out_->loop_closures_confirmed;
          before_closure.reset();
        }
      } else if (outcome.closed_loop && confirm) {
        before_closure = std::move(before);
        closing_group = g;
      }
    }
    association::AssociationResult result;
    result.landmark_of_detection = std::move(state.landmark_of_feature);
    result.pairings = static_cast<int>(state.decided.size());
    out_->uncertain_loop_features = std::move(state.uncertain_loop_features);
    return result;
  }

 private:
  struct State {
    std::vector<int> landmark_of_feature;  // candidate index per feature (−1: none yet)
    std::vector<int> decided;              // features paired so far, in order
    std::vector<char> paired_landmark;     // by candidate index
    std::vector<int> uncertain_loop_features;
    bool loop_open = false;
    const association::AssociationProblem* problem = nullptr;  // the linearisation in use
  };
  struct GroupOutcome {
    bool closed_loop = false;         // kept at least min_loop_pairings loop pairings
    bool found_old_landmark = false;  // paired an old landmark no earlier group had paired
  };

  // Associates the group's undecided features given the decided ones.
  GroupOutcome AssociateGroup(const std::vector<int>& group, bool suppress_loop, State* state) {
    const int n = s_.num_landmarks();
    std::vector<int> detections = state->decided;
    for (int i : group) {
      if (i < 0 || i >= n || state->landmark_of_feature[i] >= 0 || problem_->candidates[i].empty()) continue;
      if (std::find(detections.begin() + state->decided.size(), detections.end(), i) == detections.end()) {
        detections.push_back(i);
      }
    }
    const int num_decided = static_cast<int>(state->decided.size()), count = static_cast<int>(detections.size());
    GroupOutcome outcome;
    if (count == num_decided) return outcome;
    association::AssociationProblem sub;
    sub.candidates.resize(count);
    sub.required.assign(count, 0);
    for (int d = 0; d < count; ++d) {
      const int i = detections[d];
      if (d < num_decided) {
        for (const association::AssociationCandidate& cand : problem_->candidates[i]) {
          if (cand.landmark == state->landmark_of_feature[i]) sub.candidates[d].push_back(cand);
        }
        sub.required[d] = 1;
      } else {
        sub.candidates[d] = problem_->candidates[i];
      }
    }
    sub.covariance_block = [&](int d1, int a, int d2, int b) {
      return problem_->covariance_block(detections[d1], a, detections[d2], b);
    };
    // An old landmark: one no recent map saw and no earlier group paired (outside the
    // loop regime no landmark is flagged recent, and none is needed).
    const auto old = [&](int c) {
      return c >= 0 && (loop_.recent.empty() || !loop_.recent[candidates_[c]]) && !state->paired_landmark[c];
    };
    const auto loop_pairings_of = [&](const association::AssociationResult& r) {
      int k = 0;
      for (int d = num_decided; d < count; ++d) k += old(r.landmark_of_detection[d]) ? 1 : 0;
      return k;
    };
    association::AssociationResult r = association::JointCompatibility(sub, o_.gate_probability, o_.jcbb_max_nodes);
    out_->jcbb_truncated = out_->jcbb_truncated || r.truncated;
    for (int d = 0; d < num_decided; ++d) {
      if (r.landmark_of_detection[d] < 0) return outcome;  // could not condition on them: unpaired
    }
    const int loop_pairings = loop_pairings_of(r);
    outcome.found_old_landmark = loop_pairings > 0;
    if (state->loop_open && loop_pairings > 0) {
      bool drop = suppress_loop || loop_pairings < o_.min_loop_pairings;
      if (!suppress_loop && loop_pairings < o_.min_loop_pairings) out_->loop_pairings_dropped += loop_pairings;
      if (!drop && o_.loop_ambiguity_test) {
        association::AssociationProblem alternative = sub;
        for (int d = num_decided; d < count; ++d) {
          const int c = r.landmark_of_detection[d];
          if (!old(c)) continue;
          std::erase_if(alternative.candidates[d],
                        [c](const association::AssociationCandidate& x) { return x.landmark == c; });
        }
        const association::AssociationResult other =
            association::JointCompatibility(alternative, o_.gate_probability, o_.jcbb_max_nodes);
        if (loop_pairings_of(other) >= o_.min_loop_pairings) {
          drop = true;
          out_->loop_ambiguous = true;
        }
      }
      if (drop) {
        for (int d = num_decided; d < count; ++d) {
          int& c = r.landmark_of_detection[d];
          if (old(c) && !loop_.certain[candidates_[c]]) c = -1;
        }
      } else {
        for (int d = num_decided; d < count; ++d) {
          if (old(r.landmark_of_detection[d])) state->uncertain_loop_features.push_back(detections[d]);
        }
        state->loop_open = false;
        outcome.closed_loop = true;
      }
    }
    for (int d = num_decided; d < count; ++d) {
      const int i = detections[d], c = r.landmark_of_detection[d];
      if (c < 0) continue;
      state->landmark_of_feature[i] = c;
      state->paired_landmark[c] = 1;
      state->decided.push_back(i);
    }
    return outcome;
  }

  const SubmapAssociationOptions& o_;
  const LocalSubmap& s_;
  const std::vector<int>& candidates_;
  const LoopFlags& loop_;
  const association::AssociationProblem* problem_;
  Relinearization* relinearization_;
  SubmapAssociation* out_;
};

}  // namespace

association::AssociationResult JointlyCompatible(const SubmapAssociationOptions& o, const LocalSubmap& s,
                                                 int start_anchor, const std::vector<int>& candidates,
                                                 const CandidateGeometry& geometry, const LoopFlags& loop,
                                                 const TimedCovariance& timed_covariance,
                                                 const std::vector<std::vector<int>>* groups,
                                                 Relinearization* relinearization,
                                                 association::AssociationProblem* problem, SubmapAssociation* out) {
  const InnovationCovariance covariance(*problem, start_anchor, candidates, geometry, timed_covariance);
  problem->covariance_block = [&](int i, int a, int k, int b) { return covariance(s.covariance, i, a, k, b); };
  if (groups != nullptr) {
    return GroupedAssociation(o, s, candidates, loop, *problem, relinearization, out).Solve(*groups);
  }
  association::AssociationResult result =
      association::JointCompatibility(*problem, o.gate_probability, o.jcbb_max_nodes);
  out->jcbb_truncated = result.truncated;
  out->pairings_d2 = result.pairings > 0 ? result.joint_d2 : 0.0;
  out->pairings_dof = 2 * result.pairings;
  const auto closes_loop = [&](int c) { return c >= 0 && !loop.recent[candidates[c]]; };
  const auto loop_pairings_of = [&](const association::AssociationResult& r) {
    return static_cast<int>(std::count_if(r.landmark_of_detection.begin(), r.landmark_of_detection.end(), closes_loop));
  };
  // With the hypothesis' loop pairings struck out: how many features does the best other
  // jointly compatible hypothesis pair with old landmarks?
  const auto other_loop_pairings = [&]() {
    association::AssociationProblem alternative = *problem;
    for (int i = 0; i < s.num_landmarks(); ++i) {
      const int c = result.landmark_of_detection[i];
      if (!closes_loop(c)) continue;
      std::erase_if(alternative.candidates[i],
                    [c](const association::AssociationCandidate& x) { return x.landmark == c; });
    }
    return loop_pairings_of(association::JointCompatibility(alternative, o.gate_probability, o.jcbb_max_nodes));
  };
  const int loop_pairings = loop.regime ? loop_pairings_of(result) : 0;  // (flags only in the regime)
  if (o.confirm_thin_loops && o.loop_ambiguity_test && loop.regime && loop_pairings > 0 &&
      loop_pairings < o.min_loop_pairings) {
    // A thin closure: offered for confirmation (SubmapAssociation::thin_loop_pairings)
    // only if no other hypothesis pairs as many features with old landmarks.
    out->thin_loop_unambiguous = other_loop_pairings() < loop_pairings;
  }
  if (o.loop_ambiguity_test && loop.regime && loop_pairings >= o.min_loop_pairings &&
      other_loop_pairings() >= o.min_loop_pairings) {
    for (int& c : result.landmark_of_detection) {
      if (closes_loop(c) && !loop.certain[candidates[c]]) c = -1;
    }
    out->loop_ambiguous = true;
  }
  return result;
}

void ApplyLoopPairingTest(const SubmapAssociationOptions& o, const LoopFlags& flags, SubmapAssociation* out) {
  if (!flags.regime) return;
  int loop_pairings = 0;
  for (int j : out->landmark_of_feature) loop_pairings += (j >= 0 && !flags.recent[j]) ? 1 : 0;
  if (loop_pairings > 0 && loop_pairings < o.min_loop_pairings) {
    for (size_t i = 0; i < out->landmark_of_feature.size(); ++i) {
      int& j = out->landmark_of_feature[i];
      if (j < 0 || flags.recent[j] || flags.certain[j]) continue;
      if (out->thin_loop_unambiguous) out->thin_loop_pairings.push_back({static_cast<int>(i), j});
      j = -1;
    }
    if (!out->thin_loop_unambiguous) out->thin_loop_pairings.clear();
    out->loop_pairings_dropped = loop_pairings;
  } else {
    for (size_t i = 0; i < out->landmark_of_feature.size(); ++i) {
      const int j = out->landmark_of_feature[i];
      if (j >= 0 && !flags.recent[j]) out->uncertain_loop_features.push_back(static_cast<int>(i));
    }
  }
}

}  // namespace subslam::association::submap_matching
