// The Ceres back-end as a MapJoiner: the EIF joiner associates each local map and gives
// the online estimate; every `solve_every` joins (0: never during the run) and at
// Finish() the whole submap graph is solved with Ceres (ceres_solver.h), warm-started
// from the current estimate (ISEIF's schedule, with Ceres doing the iterations), and the
// EIF adopts the solution (EifJoiner::AdoptEstimate: every factor relinearised there),
// so the anchors, the map and the marginals that this joiner answers all follow it.
//
// As a node of a binary tree (tree_joiner.h) it joins whole maps by the EIF's tree join;
// the nodes' periodic solves count their own joins, and the root's Finish() solves the
// whole graph once: Ceres from the tree's estimate, which on thousands of small local
// maps comes much sooner than the sequential EIF's (bench/RESULTS.md).
#ifndef SUBSLAM_BACKEND_CERES_JOINER_H_
#define SUBSLAM_BACKEND_CERES_JOINER_H_

#include <optional>

#include "subslam/backend/ceres_solver.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/backend/map_joiner.h"

namespace subslam::backend {

struct CeresJoinerOptions {
  // Association and the online estimate. Its relinearize_at_end is not used: Ceres
  // solves after the last join, and the EIF's own Gauss-Newton there would only be
  // done again.
  EifJoinerOptions eif;
  CeresSolveOptions solve;
  int solve_every = 0;  // also solve every K joins during the run (0: at the end only)

  absl::Status Validate() const;
};

class CeresJoiner final : public MapJoiner {
 public:
  CeresJoiner(const Pose2& initial_pose, const CeresJoinerOptions& options);

  std::string Name() const override { return "ceres"; }
  // The EIF's Finish (its revision passes; no Gauss-Newton), then a Ceres solve.
  absl::Status Finish() override;

  const SubmapGraph& graph() const override { return eif_.graph(); }
  Eigen::MatrixXd JointCovariance(const std::vector<int>& anchors, const std::vector<int>& landmarks) const override {
    return eif_.JointCovariance(anchors, landmarks);
  }
  std::vector<Eigen::Matrix3d> AnchorCovariances() const override { return eif_.AnchorCovariances(); }
  std::vector<Eigen::Matrix2d> LandmarkCovariances() const override { return eif_.LandmarkCovariances(); }
  // The EIF's (without a loop closure that waits for confirmation).
  Pose2 LastAnchor() const override { return eif_.LastAnchor(); }
  Eigen::Matrix3d LastAnchorCovariance() const override { return eif_.LastAnchorCovariance(); }
  const std::vector<int>& last_association() const override { return eif_.last_association(); }
  // The EIF's stages, and "ceres_solve_and_adopt".
  std::map<std::string, double> stage_times() const override;
  const JoinerCounters& counters() const override { return eif_.counters(); }
  JoinerExtras Extras() const override;
  const association::SubmapAssociator& associator() const override { return eif_.associator(); }
  absl::Status ReviseAssociation() override { return eif_.ReviseAssociation(); }
  absl::Status MergeLandmarks(int keep, int drop) override { return eif_.MergeLandmarks(keep, drop); }
  absl::Status SplitFeature(int factor, int feature) override { return eif_.SplitFeature(factor, feature); }

  // Tree nodes: an empty Ceres joiner with the same options, a copy, and the whole-map
  // join of another Ceres joiner (its EIF's JoinMap; no solve).
  std::unique_ptr<MapJoiner> NewEmpty(const Pose2& initial_pose) const override;
  std::unique_ptr<MapJoiner> Clone() const override;
  absl::Status JoinMap(const MapJoiner& right) override;

  // Ceres's summary of the last solve (nullopt before the first).
  const std::optional<CeresSolveReport>& last_solve() const { return last_solve_; }

 protected:
  absl::Status JoinLocalMap(const LocalSubmap& submap) override;

 private:
  absl::Status SolveAndAdopt();

  CeresJoinerOptions options_;
  EifJoiner eif_;
  int joins_ = 0;
  std::optional<CeresSolveReport> last_solve_;
  int solves_ = 0;
  long iterations_ = 0;
  double seconds_ = 0.0, max_seconds_ = 0.0;  // solve and adopt, wall time
};

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_CERES_JOINER_H_
