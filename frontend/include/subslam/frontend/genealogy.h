// The genealogy of a particle filter's particles since its last reset, and the share of
// their spread that they hold in common through shared ancestors.
//
// Each scan, every particle draws its pose once, independently of the others (the
// FastSLAM 2.0 proposal sample). A resampling copies particles: new slot i copies old
// slot parent[i], and the copies then draw independently again. Two particles p and q
// therefore share the draws of every scan up to their last common ancestor, and
// ρ_pq = (scans before it) / (all scans) is the share of their deviations they hold in
// common — the approximation being that every scan's draw adds the same amount of
// spread. With weights w (summing to 1), SharedAncestry returns
//   R = Σ_pq w_p w_q ρ_pq,
// and the particles' weighted spread S = Σ_p w_p (x_p − x̄)(x_p − x̄)ᵀ has expectation
// (1 − R) Σ, Σ the spread of one particle's deviation, while their weighted mean x̄ has
// covariance R Σ about the centre (moment_matching.h). Without resampling R = Σ_p w_p²,
// the familiar correction of a weighted sample covariance.
//
// Cost: AddResampling is O(N · d) and SharedAncestry O(N · d), d the resamplings since
// the latest one from which every particle descends (older ones are dropped: all
// particles share what came before).
#ifndef SUBSLAM_FRONTEND_GENEALOGY_H_
#define SUBSLAM_FRONTEND_GENEALOGY_H_

#include <span>
#include <utility>
#include <vector>

namespace subslam::frontend {

class Genealogy {
 public:
  // All particles identical, no scan yet.
  void Reset();
  // One scan: every particle drew its pose once.
  void AddScan() { ++scans_; }
  // Slot i of the new particle set is a copy of slot parent[i] of the old one.
  void AddResampling(std::span<const int> parent);
  // R = Σ_pq w_p w_q ρ_pq (see above) for the current particles' weights (normalised,
  // one per slot); 0 before the first scan.
  double SharedAncestry(std::span<const double> weights) const;

  long scans() const { return scans_; }
  // Resamplings kept (since the latest that every particle descends from).
  int resamplings_kept() const { return static_cast<int>(resamplings_.size()); }

 private:
  struct Resampling {
    std::vector<int> parent;
    long scans = 0;  // scans before it
  };
  std::vector<Resampling> resamplings_;
  long scans_ = 0;
  long coalesced_scans_ = 0;                  // scans whose draws every particle shares
  mutable std::vector<int> ancestor_;         // scratch
  mutable std::vector<double> group_weight_;  // scratch, zero between uses
  // Scratch of SharedAncestry: the distinct ancestors at the resampling being walked and
  // their weights, in slot order, and the slots the next one reaches (listed, and flagged
  // per slot; all 0 between uses).
  mutable std::vector<std::pair<int, double>> groups_, next_groups_;
  mutable std::vector<int> reached_;
  mutable std::vector<char> slot_reached_;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_GENEALOGY_H_
