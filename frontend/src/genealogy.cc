#include "subslam/frontend/genealogy.h"

#include <algorithm>

#include "subslam/core/check.h"

namespace subslam::frontend {

void Genealogy::Reset() {
  resamplings_.clear();
  scans_ = 0;
  coalesced_scans_ = 0;
}

void Genealogy::AddResampling(std::span<const int> parent) {
  const int n = static_cast<int>(parent.size());
  for (int p : parent) SUBSLAM_CHECK(p >= 0 && p < n) << "parent slot " << p << " of " << n;
  if (!resamplings_.empty()) {
    SUBSLAM_CHECK(static_cast<int>(resamplings_.back().parent.size()) == n) << "the particle count changed";
  }
  resamplings_.push_back({std::vector<int>(parent.begin(), parent.end()), scans_});
  // Drop the resamplings before the latest one from which every particle descends.
  ancestor_.resize(n);
  for (int i = 0; i < n; ++i) ancestor_[i] = i;
  for (size_t r = resamplings_.size(); r-- > 0;) {
    bool one = true;
    for (int i = 0; i < n; ++i) {
      ancestor_[i] = resamplings_[r].parent[ancestor_[i]];
      one = one && ancestor_[i] == ancestor_[0];
    }
    if (one) {
      coalesced_scans_ = resamplings_[r].scans;
      resamplings_.erase(resamplings_.begin(), resamplings_.begin() + static_cast<long>(r) + 1);
      return;
    }
  }
}

double Genealogy::SharedAncestry(std::span<const double> weights) const {
  if (scans_ == 0) return 0.0;
  const int n = static_cast<int>(weights.size());
  if (!resamplings_.empty()) {
    SUBSLAM_CHECK(static_cast<int>(resamplings_.back().parent.size()) == n) << "one weight per particle";
  }
  // R = (1/T) Σ over scans t of Σ_g W_g², the groups g those of the particles with one
  // ancestor at scan t and W_g their weight. The groups change only at resamplings: walk
  // them back from the newest, carrying each group's weight to its parent slot. Groups
  // only merge going back (a few ancestors stand behind many particles), so a walk costs
  // the number of distinct ancestors at each resampling, not the particles'.
  groups_.clear();
  double sum_sq = 0.0;  // after the newest resampling every particle is a group of one
  for (int p = 0; p < n; ++p) {
    groups_.push_back({p, weights[p]});
    sum_sq += weights[p] * weights[p];
  }
  group_weight_.assign(n, 0.0);
  slot_reached_.assign(n, 0);
  double shared = 0.0;
  long later = scans_;
  for (size_t r = resamplings_.size(); r-- > 0;) {
    shared += static_cast<double>(later - resamplings_[r].scans) * sum_sq;
    later = resamplings_[r].scans;
    reached_.clear();
    for (const auto& [slot, weight] : groups_) {
      const int a = resamplings_[r].parent[slot];
      if (!slot_reached_[a]) {
        slot_reached_[a] = 1;
        reached_.push_back(a);
      }
      group_weight_[a] += weight;
    }
    std::sort(reached_.begin(), reached_.end());
    next_groups_.clear();
    sum_sq = 0.0;
    for (int a : reached_) {
      next_groups_.push_back({a, group_weight_[a]});
      sum_sq += group_weight_[a] * group_weight_[a];
      group_weight_[a] = 0.0;
      slot_reached_[a] = 0;
    }
    groups_.swap(next_groups_);
  }
  // Before the oldest kept resampling its groups hold, and before the coalescence one
  // group holds every particle.
  shared += static_cast<double>(later - coalesced_scans_) * sum_sq + static_cast<double>(coalesced_scans_);
  return shared / static_cast<double>(scans_);
}

}  // namespace subslam::frontend
