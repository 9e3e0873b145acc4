// EifJoiner: marginal covariances — by sparse solves with the factor, in bulk from the
// sparse inverse, and the 5 × 5 [anchor, landmark] blocks association needs.

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

Eigen::MatrixXd EifJoiner::Impl::JointCovariance(const std::vector<int>& anchors,
                                                 const std::vector<int>& landmarks) const {
  const StateBlocks blocks = SelectBlocks(anchors, landmarks, estimate_.anchor_offset, estimate_.landmark_offset);
  const std::vector<int>& offsets = blocks.offsets;
  const std::vector<int>& sizes = blocks.sizes;
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(blocks.total, blocks.total);
  if (estimate_.dim == 0) return out;
  SUBSLAM_CHECK(solver_.factor.ready()) << "no factorisation to recover covariances from";
  // The block of Λ⁻¹ on the free variables' rows (fixed P0: zero rows and columns), by
  // forward solves limited to each unit right-hand side's reach in the factor.
  std::vector<int> state_rows, out_rows;
  int row = 0;
  for (size_t v = 0; v < offsets.size(); ++v) {
    for (int i = 0; i < sizes[v] && offsets[v] >= 0; ++i) {
      state_rows.push_back(offsets[v] + i);
      out_rows.push_back(row + i);
    }
    row += sizes[v];
  }
  const Eigen::MatrixXd block = solver_.factor.InverseBlock(state_rows);
  out(out_rows, out_rows) = block;
  return 0.5 * (out + out.transpose());
}

Eigen::Matrix4d EifJoiner::Impl::LandmarkPairCovariance(int a, int b, std::vector<Eigen::Matrix2d>* own) const {
  SUBSLAM_CHECK(solver_.factor.ready()) << "no factorisation to recover covariances from";
  const auto rows = [this](int j) {
    return std::vector<int>{estimate_.landmark_offset[j], estimate_.landmark_offset[j] + 1};
  };
  const auto own_block = [&](int j) -> const Eigen::Matrix2d& {
    Eigen::Matrix2d& block = (*own)[j];
    if (!block.allFinite()) block = solver_.factor.InverseBlock(rows(j));
    return block;
  };
  Eigen::Matrix4d S;
  S.topLeftCorner<2, 2>() = own_block(a);
  S.bottomRightCorner<2, 2>() = own_block(b);
  S.topRightCorner<2, 2>() = solver_.factor.CrossBlock(rows(a), rows(b));
  S.bottomLeftCorner<2, 2>() = S.topRightCorner<2, 2>().transpose();
  return S;
}

std::vector<Eigen::Matrix3d> EifJoiner::Impl::AnchorCovariances() const {
  std::vector<Eigen::Matrix3d> out(estimate_.graph.num_anchors(), Eigen::Matrix3d::Zero());  // P0 fixed: zero
  std::vector<int> free;
  std::vector<std::vector<int>> groups;
  for (int k = 0; k < estimate_.graph.num_anchors(); ++k) {
    if (estimate_.anchor_offset[k] < 0) continue;
    const int o = estimate_.anchor_offset[k];
    free.push_back(k);
    groups.push_back({o, o + 1, o + 2});
  }
  if (groups.empty()) return out;
  SUBSLAM_CHECK(solver_.factor.ready()) << "no factorisation to recover covariances from";
  const std::vector<Eigen::MatrixXd> blocks = solver_.factor.DiagonalInverseBlocks(groups);
  for (size_t g = 0; g < free.size(); ++g) out[free[g]] = blocks[g];
  return out;
}

std::vector<Eigen::Matrix2d> EifJoiner::Impl::LandmarkCovariances() const {
  std::vector<std::vector<int>> groups;
  for (int j = 0; j < estimate_.graph.num_landmarks(); ++j)
    groups.push_back({estimate_.landmark_offset[j], estimate_.landmark_offset[j] + 1});
  std::vector<Eigen::Matrix2d> out;
  if (groups.empty()) return out;
  SUBSLAM_CHECK(solver_.factor.ready()) << "no factorisation to recover covariances from";
  for (const Eigen::MatrixXd& b : solver_.factor.DiagonalInverseBlocks(groups)) out.push_back(b);
  return out;
}

std::vector<association::Matrix5d> EifJoiner::Impl::AnchorLandmarkCovariances(int anchor,
                                                                              const std::vector<int>& landmarks) const {
  std::vector<association::Matrix5d> out(landmarks.size(), association::Matrix5d::Zero());
  if (estimate_.dim == 0) return out;
  SUBSLAM_CHECK(solver_.factor.ready()) << "no factorisation to recover covariances from";
  std::vector<int> hub;
  for (int i = 0; i < 3 && estimate_.anchor_offset[anchor] >= 0; ++i)
    hub.push_back(estimate_.anchor_offset[anchor] + i);
  std::vector<std::vector<int>> groups;
  for (int j : landmarks) groups.push_back({estimate_.landmark_offset[j], estimate_.landmark_offset[j] + 1});
  const std::vector<Eigen::MatrixXd> blocks = solver_.factor.InverseStarBlocks(hub, groups);
  const int h = static_cast<int>(hub.size());  // 0 for the fixed P0: zero rows and columns
  for (size_t c = 0; c < landmarks.size(); ++c) out[c].bottomRightCorner(2 + h, 2 + h) = blocks[c];
  return out;
}

std::vector<std::optional<association::Matrix5d>> EifJoiner::Impl::AnchorLandmarkBounds(
    int anchor, const std::vector<int>& landmarks) const {
  std::vector<std::optional<association::Matrix5d>> out(landmarks.size());
  if (estimate_.dim == 0) return out;
  SUBSLAM_CHECK(solver_.factor.ready()) << "no factorisation to recover covariances from";
  // The anchor's columns of Λ⁻¹ on its own rows and the bounded landmarks' (a back
  // substitution over their paths to the root only): its marginal and its exact
  // cross-covariance with each landmark (zero for the fixed P0).
  const int o = estimate_.anchor_offset[anchor];
  std::vector<int> rows, bounded;
  for (size_t c = 0; c < landmarks.size(); ++c) {
    if (!marginal_bound_[landmarks[c]].allFinite()) continue;
    bounded.push_back(static_cast<int>(c));
    rows.push_back(estimate_.landmark_offset[landmarks[c]]);
    rows.push_back(estimate_.landmark_offset[landmarks[c]] + 1);
  }
  if (bounded.empty()) return out;
  Eigen::MatrixXd columns = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()) + 3, 3);
  if (o >= 0) {
    rows.insert(rows.end(), {o, o + 1, o + 2});
    columns = solver_.factor.InverseColumnsAt({o, o + 1, o + 2}, rows);
  }
  const Eigen::Matrix3d anchor_block = columns.bottomRows<3>();
  for (size_t b = 0; b < bounded.size(); ++b) {
    const int c = bounded[b];
    const Eigen::Matrix2d& B = marginal_bound_[landmarks[c]];
    // [Σ_PP Σ_PL; Σ_LP B] ⪰ [Σ_PP Σ_PL; Σ_LP Σ_LL] since B ⪰ Σ_LL.
    association::Matrix5d m;
    m.topLeftCorner<3, 3>() = anchor_block;
    m.bottomLeftCorner<2, 3>() = columns.middleRows<2>(static_cast<Eigen::Index>(2 * b));
    m.topRightCorner<3, 2>() = m.bottomLeftCorner<2, 3>().transpose();
    m.bottomRightCorner<2, 2>() = B;
    out[c] = m;
  }
  return out;
}

std::vector<association::Matrix5d> EifJoiner::Impl::FactorMarginals(int anchor,
                                                                    const std::vector<int>& landmarks) const {
  // [anchor, landmark] is coupled in Λ by the factor that holds both, so its block lies on
  // L's pattern: all of them from one sparse-inverse recursion per factorisation.
  std::vector<std::vector<int>> groups;
  const int o = estimate_.anchor_offset[anchor];
  for (int j : landmarks) {
    std::vector<int> g;
    if (o >= 0) g = {o, o + 1, o + 2};
    g.push_back(estimate_.landmark_offset[j]);
    g.push_back(estimate_.landmark_offset[j] + 1);
    groups.push_back(std::move(g));
  }
  std::vector<association::Matrix5d> out(landmarks.size(), association::Matrix5d::Zero());
  if (groups.empty()) return out;
  const std::vector<Eigen::MatrixXd> blocks = solver_.factor.DiagonalInverseBlocks(groups);
  const int h = o >= 0 ? 3 : 0;  // the fixed P0: zero rows and columns
  for (size_t c = 0; c < landmarks.size(); ++c) out[c].bottomRightCorner(2 + h, 2 + h) = blocks[c];
  return out;
}

}  // namespace subslam::backend
