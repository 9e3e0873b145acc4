#include "subslam/backend/ekf_joiner.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <memory>

#include "absl/strings/str_cat.h"
#include "state_blocks.h"
#include "subslam/backend/submap_factor.h"
#include "subslam/core/check.h"
#include "subslam/core/enum_names.h"
#include "subslam/core/stage_timer.h"

namespace subslam::backend {

namespace {
constexpr EnumName<EkfFusion> kEkfFusionNames[] = {{EkfFusion::kZeroNoiseConstraint, "zero-noise"},
                                                   {EkfFusion::kConditionalUpdate, "conditional"}};
}  // namespace

const char* ToString(EkfFusion fusion) { return NameOf(kEkfFusionNames, fusion); }
absl::StatusOr<EkfFusion> EkfFusionFromString(const std::string& name) {
  return ParseEnum(kEkfFusionNames, name, "EKF fusion");
}

absl::Status EkfJoinerOptions::Validate() const {
  if (absl::Status st = association.Validate(); !st.ok()) return st;
  return revision.Validate();
}

EkfJoiner::EkfJoiner(const Pose2& initial_pose, const EkfJoinerOptions& options)
    : options_(options), graph_(initial_pose), associator_(options.association) {
  SUBSLAM_CHECK(options_.Validate().ok()) << options_.Validate().message();
  anchor_offset_.push_back(-1);  // P0 is fixed
  for (const char* stage : {"association", "covariance_recovery", "augmentation", "update", "marginalization"}) {
    times_[stage] = 0.0;
  }
}

Pose2 EkfJoiner::StatePose(int k) const {
  const int o = anchor_offset_[k];
  if (o < 0) return graph_.anchors()[k];  // P0, or frozen (its heading is only needed wrapped)
  return Pose2(x_[o], x_[o + 1], x_[o + 2]);
}

void EkfJoiner::WriteBack() {
  for (int k = 1; k < graph_.num_anchors(); ++k) {
    const int o = anchor_offset_[k];
    if (o >= 0) graph_.anchor(k) = Pose2(x_[o], x_[o + 1], WrapAngle(x_[o + 2]));
  }
  for (int j = 0; j < graph_.num_landmarks(); ++j) graph_.landmark(j) = x_.segment<2>(landmark_offset_[j]);
}

Eigen::MatrixXd EkfJoiner::JointCovariance(const std::vector<int>& anchors, const std::vector<int>& landmarks) const {
  const StateBlocks blocks = SelectBlocks(anchors, landmarks, anchor_offset_, landmark_offset_);
  const std::vector<int>& offsets = blocks.offsets;
  const std::vector<int>& sizes = blocks.sizes;
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(blocks.total, blocks.total);
  int r = 0;
  for (size_t a = 0; a < offsets.size(); ++a) {
    if (offsets[a] < 0) {  // P0 (zero) or an anchor marginalised out (frozen, uncorrelated)
      if (a < anchors.size() && anchors[a] > 0) out.block<3, 3>(r, r) = frozen_covariance_[anchors[a]];
      r += sizes[a];
      continue;
    }
    int c = 0;
    for (size_t b = 0; b < offsets.size(); ++b) {
      if (offsets[b] >= 0) out.block(r, c, sizes[a], sizes[b]) = P_.block(offsets[a], offsets[b], sizes[a], sizes[b]);
      c += sizes[b];
    }
    r += sizes[a];
  }
  return out;
}

std::vector<int> EkfJoiner::Augment(int start, const Eigen::VectorXd& z, const Eigen::MatrixXd& Q,
                                    const std::vector<Block>& blocks) {
  const Pose2 P_s = StatePose(start);
  const int N = static_cast<int>(x_.size());
  std::vector<int> z_rows, offsets;
  int a = 0;
  for (const Block& b : blocks) {
    offsets.push_back(N + a);
    for (int i = 0; i < b.size; ++i) z_rows.push_back(b.offset + i);
    a += b.size;
  }
  Eigen::MatrixXd G_s(a, 3), G_z = Eigen::MatrixXd::Zero(a, a);
  Eigen::VectorXd x_new(a);
  int row = 0;
  for (const Block& b : blocks) {
    if (b.size == 3) {
      Eigen::Matrix3d J_a, J_b;
      const Pose2 local(z[b.offset], z[b.offset + 1], z[b.offset + 2]);
      const Pose2 e = Compose(P_s, local, &J_a, &J_b);
      x_new.segment<3>(row) << e.x, e.y, P_s.theta + local.theta;  // continuous heading
      G_s.middleRows<3>(row) = J_a;
      G_z.block<3, 3>(row, row) = J_b;
    } else {
      Matrix23d J_frame;
      Eigen::Matrix2d J_point;
      x_new.segment<2>(row) = TransformFrom(P_s, z.segment<2>(b.offset), &J_frame, &J_point);
      G_s.middleRows<2>(row) = J_frame;
      G_z.block<2, 2>(row, row) = J_point;
    }
    row += b.size;
  }
  const Eigen::MatrixXd Q_sel = Q(z_rows, z_rows);
  Eigen::MatrixXd P_new = G_z * Q_sel * G_z.transpose();
  Eigen::MatrixXd cross;  // N × a
  const int os = anchor_offset_[start];
  if (os >= 0) {
    cross = P_.middleCols<3>(os) * G_s.transpose();
    P_new += G_s * P_.block<3, 3>(os, os) * G_s.transpose();
  }
  P_.conservativeResize(N + a, N + a);
  x_.conservativeResize(N + a);
  x_.tail(a) = x_new;
  if (os >= 0) {
    P_.topRightCorner(N, a) = cross;
    P_.bottomLeftCorner(a, N) = cross.transpose();
  } else {
    P_.topRightCorner(N, a).setZero();
    P_.bottomLeftCorner(a, N).setZero();
  }
  P_.bottomRightCorner(a, a) = 0.5 * (P_new + P_new.transpose());
  return offsets;
}

void EkfJoiner::SubtractOuter(const Eigen::MatrixXd& W) {
  // Lower triangle by a rank update (half the flops), then mirrored.
  P_.selfadjointView<Eigen::Lower>().rankUpdate(W, -1.0);
  P_.triangularView<Eigen::StrictlyUpper>() = P_.transpose();
}

absl::Status EkfJoiner::FuseZeroNoise(const std::vector<std::pair<int, int>>& pairs) {
  const int N = static_cast<int>(x_.size()), m = static_cast<int>(pairs.size());
  Eigen::MatrixXd PH(N, 2 * m);  // P Hᵀ for H = [… I (copy) … −I (landmark) …]
  Eigen::VectorXd nu(2 * m);     // 0 − (ĉ − L̂)
  for (int p = 0; p < m; ++p) {
    const auto [oc, oj] = pairs[p];
    PH.middleCols<2>(2 * p) = P_.middleCols<2>(oc) - P_.middleCols<2>(oj);
    nu.segment<2>(2 * p) = x_.segment<2>(oj) - x_.segment<2>(oc);
  }
  Eigen::MatrixXd S(2 * m, 2 * m);
  for (int p = 0; p < m; ++p) {
    const auto [oc, oj] = pairs[p];
    S.middleRows<2>(2 * p) = PH.middleRows<2>(oc) - PH.middleRows<2>(oj);
  }
  S = 0.5 * (S + S.transpose());
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() != Eigen::Success) {
    return absl::InternalError("EKF join: the fusion's innovation covariance is not positive definite");
  }
  // K = PH S⁻¹; with S = L Lᵀ and W = PH L⁻ᵀ: x += W L⁻¹ ν, P −= W Wᵀ.
  const Eigen::MatrixXd W = llt.matrixL().solve(PH.transpose()).transpose();
  x_ += W * llt.matrixL().solve(nu);
  SubtractOuter(W);
  return absl::OkStatus();
}

absl::Status EkfJoiner::FuseConditional(const LocalSubmap& s, int start, int end,
                                        const std::vector<int>& landmark_of_feature, const std::vector<char>& matched) {
  const int n = s.num_landmarks();
  std::vector<Eigen::Vector2d> landmarks;
  for (int j : landmark_of_feature) landmarks.push_back(x_.segment<2>(landmark_offset_[j]));
  const SubmapFactorLinearization lin = LinearizeSubmapFactor(s, StatePose(start), StatePose(end), landmarks);
  // Columns: the variables' state indices and the Jacobian over them.
  std::vector<int> state_index;
  const bool start_free = anchor_offset_[start] >= 0;
  const int cols = (start_free ? 3 : 0) + 3 + 2 * n;
  Eigen::MatrixXd J(lin.residual.size(), cols);
  int c = 0;
  if (start_free) {
    J.middleCols<3>(c) = lin.J_start;
    for (int i = 0; i < 3; ++i) state_index.push_back(anchor_offset_[start] + i);
    c += 3;
  }
  J.middleCols<3>(c) = lin.J_end;
  for (int i = 0; i < 3; ++i) state_index.push_back(anchor_offset_[end] + i);
  c += 3;
  J.rightCols(2 * n) = lin.J_landmarks;
  for (int i = 0; i < n; ++i) {
    for (int d = 0; d < 2; ++d) state_index.push_back(landmark_offset_[landmark_of_feature[i]] + d);
  }
  std::vector<int> rows_n = {0, 1, 2}, rows_m;
  for (int i = 0; i < n; ++i) {
    std::vector<int>& rows = matched[i] ? rows_m : rows_n;
    rows.push_back(3 + 2 * i);
    rows.push_back(4 + 2 * i);
  }
  // Condition the matched rows on the augmented ones: C = Q_MN Q_NN⁻¹.
  const Eigen::MatrixXd Q_NN = s.covariance(rows_n, rows_n), Q_MN = s.covariance(rows_m, rows_n);
  const Eigen::LLT<Eigen::MatrixXd> llt_n(Q_NN);
  if (llt_n.info() != Eigen::Success) return absl::InternalError("EKF join: Q_NN not positive definite");
  const Eigen::MatrixXd C = llt_n.solve(Q_MN.transpose()).transpose();
  const Eigen::MatrixXd H = J(rows_m, Eigen::all) - C * J(rows_n, Eigen::all);
  const Eigen::MatrixXd R = s.covariance(rows_m, rows_m) - C * Q_MN.transpose();
  const Eigen::VectorXd nu = -(lin.residual(rows_m) - C * lin.residual(rows_n));
  const Eigen::MatrixXd PH = P_(Eigen::all, state_index) * H.transpose();  // N × 2m
  Eigen::MatrixXd S = H * PH(state_index, Eigen::all) + R;
  S = 0.5 * (S + S.transpose());
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() != Eigen::Success) return absl::InternalError("EKF join: innovation covariance not positive definite");
  const Eigen::MatrixXd W = llt.matrixL().solve(PH.transpose()).transpose();
  x_ += W * llt.matrixL().solve(nu);
  SubtractOuter(W);
  return absl::OkStatus();
}

void EkfJoiner::DropVariable(int offset, int size) {
  const int N = static_cast<int>(x_.size()), tail = N - offset - size;
  if (tail > 0) {
    P_.block(offset, 0, tail, offset) = P_.block(offset + size, 0, tail, offset).eval();
    P_.block(0, offset, offset, tail) = P_.block(0, offset + size, offset, tail).eval();
    P_.block(offset, offset, tail, tail) = P_.block(offset + size, offset + size, tail, tail).eval();
    x_.segment(offset, tail) = x_.segment(offset + size, tail).eval();
  }
  P_.conservativeResize(N - size, N - size);
  x_.conservativeResize(N - size);
  for (int& o : anchor_offset_) {
    if (o > offset) o -= size;
  }
  for (int& o : landmark_offset_) {
    if (o > offset) o -= size;
  }
}

association::SubmapAssociation EkfJoiner::AssociateAt(const LocalSubmap& s, int start,
                                                      const std::vector<std::vector<int>>* whole_map_groups) {
  StageTimer timer(&times_, "association");
  association::SubmapAssociation a = associator_.Associate(
      s, start, graph_,
      [this](const std::vector<int>& anchors, const std::vector<int>& landmarks) {
        return JointCovariance(anchors, landmarks);
      },
      /*anchor_prefilter=*/whole_map_groups == nullptr, nullptr, nullptr, whole_map_groups);
  times_["covariance_recovery"] += a.covariance_seconds;
  if (a.jcbb_truncated) ++counters_.jcbb_truncated;
  if (a.loop_pairings_dropped > 0) ++counters_.loop_closures_thin;
  if (a.loop_ambiguous) ++counters_.loop_closures_ambiguous;
  counters_.loop_closures_confirmed += a.loop_closures_confirmed;
  counters_.loop_closures_unconfirmed += a.loop_closures_unconfirmed;
  if (a.map_rotated) ++counters_.maps_widened;
  return a;
}

absl::Status EkfJoiner::JoinLocalMap(const LocalSubmap& s) {
  if (absl::Status v = s.Validate(); !v.ok()) return v;
  if (s.t_start < last_t_end_ - 1e-9) {
    return absl::InvalidArgumentError(absl::StrCat("local map ", s.id, " starts at ", s.t_start,
                                                   " before the previous one ended (", last_t_end_, ")"));
  }
  const int start = graph_.num_anchors() - 1;
  const LocalSubmap widened = associator_.WithRotationSpread(s);  // by the maps' rotation spread so far
  association::SubmapAssociation a = AssociateAt(widened, start);
  const std::optional<LocalSubmap> rotated_back =
      association::RotatedBack(widened, a);  // found rotated by the rotation test
  LocalSubmap joined = rotated_back ? *rotated_back : widened;
  association::StampRotationFit(a, &joined);
  associator_.RecordRotationFit(joined);
  if (absl::Status st = JoinAssociated(joined, std::move(a.landmark_of_feature)); !st.ok()) return st;
  if (widened.rotation_spread_rad > 0) ++counters_.maps_spread;
  const int every = options_.revision.every_joins;
  if (every > 0 && counters_.joins % every == 0) return ReviseAssociation();
  return absl::OkStatus();
}

absl::Status EkfJoiner::JoinAssociated(const LocalSubmap& s, std::vector<int> assoc) {
  const int start = graph_.num_anchors() - 1;
  const int n = s.num_landmarks();
  std::vector<char> matched(n, 0);
  std::vector<int> features;  // in the order they are augmented
  for (int i = 0; i < n; ++i) {
    matched[i] = assoc[i] >= 0;
    if (!matched[i]) features.push_back(i);
  }
  const bool zero_noise = options_.fusion == EkfFusion::kZeroNoiseConstraint;
  if (zero_noise) {  // the matched features' copies go last, to be dropped after fusion
    for (int i = 0; i < n; ++i) {
      if (matched[i]) features.push_back(i);
    }
  }
  std::vector<Block> blocks = {{0, 3}};
  for (int i : features) blocks.push_back({3 + 2 * i, 2});
  const int first_new_landmark = graph_.num_landmarks();
  std::vector<int> offsets;
  {
    StageTimer timer(&times_, "augmentation");
    offsets = Augment(start, s.mean, s.covariance, blocks);
  }
  const int end = graph_.AddAnchor(Pose2());
  anchor_offset_.push_back(offsets[0]);
  frozen_covariance_.resize(graph_.num_anchors(), Eigen::Matrix3d::Zero());
  std::vector<std::pair<int, int>> copies;
  for (size_t b = 1; b < blocks.size(); ++b) {
    const int i = features[b - 1];
    if (matched[i]) {
      copies.emplace_back(offsets[b], landmark_offset_[assoc[i]]);
    } else {
      assoc[i] = graph_.AddLandmark(Eigen::Vector2d::Zero());
      landmark_offset_.push_back(offsets[b]);
      ++counters_.new_landmarks;
    }
  }
  const long num_matched = static_cast<long>(std::count(matched.begin(), matched.end(), 1));
  counters_.associated += num_matched;
  {
    StageTimer timer(&times_, "update");
    if (zero_noise && !copies.empty()) {
      if (absl::Status st = FuseZeroNoise(copies); !st.ok()) return st;
      const int keep = static_cast<int>(x_.size()) - 2 * static_cast<int>(copies.size());
      P_.conservativeResize(keep, keep);
      x_.conservativeResize(keep);
    } else if (!zero_noise && num_matched > 0) {
      if (absl::Status st = FuseConditional(s, start, end, assoc, matched); !st.ok()) return st;
    }
  }
  if (!options_.keep_anchors && start > 0) {
    StageTimer timer(&times_, "marginalization");
    frozen_covariance_[start] = P_.block<3, 3>(anchor_offset_[start], anchor_offset_[start]);
    graph_.anchor(start) =
        Pose2(x_[anchor_offset_[start]], x_[anchor_offset_[start] + 1], WrapAngle(x_[anchor_offset_[start] + 2]));
    DropVariable(anchor_offset_[start], 3);
    anchor_offset_[start] = -1;
  }
  if (!x_.allFinite() || !P_.allFinite()) return absl::InternalError("EKF join produced a non-finite value");
  WriteBack();
  associator_.Record(s, assoc, first_new_landmark, /*define_truth=*/true);
  graph_.AddFactor({s, start, end, assoc});
  last_association_ = assoc;
  last_t_end_ = s.t_end;
  ++counters_.joins;
  return absl::OkStatus();
}

absl::Status EkfJoiner::Finish() { return ReviseUntilSettled(*this); }

absl::Status EkfJoiner::ReviseAssociation() {
  if (!options_.revision.enabled() || options_.association.known_association || graph_.factors().empty()) {
    return absl::OkStatus();
  }
  StageTimer timer(&times_, "revision");
  ++counters_.revision_passes;
  const std::vector<association::FeatureSplit> splits = association::FindFeatureSplits(
      graph_,
      [this](int anchor, const std::vector<int>& landmarks) {
        const Eigen::MatrixXd S = JointCovariance({anchor}, landmarks);
        std::vector<association::Matrix5d> out(landmarks.size());
        for (size_t c = 0; c < landmarks.size(); ++c) {
          const std::vector<int> rows = {0, 1, 2, 3 + 2 * static_cast<int>(c), 4 + 2 * static_cast<int>(c)};
          out[c] = S(rows, rows);
        }
        return out;
      },
      options_.revision);
  // A split joins everything again: the merges are tested on the next pass.
  if (!splits.empty()) return SplitFeature(splits[0].factor, splits[0].feature);
  std::vector<Eigen::Matrix2d> marginals(graph_.num_landmarks());
  for (int j = 0; j < graph_.num_landmarks(); ++j)
    marginals[j] = P_.block<2, 2>(landmark_offset_[j], landmark_offset_[j]);
  const std::vector<association::LandmarkMerge> merges = association::FindLandmarkMerges(
      graph_, marginals,
      [this](int a, int b) -> Eigen::Matrix4d {
        return JointCovariance({}, {a, b});
      },
      options_.revision, options_.association.loop_test_min_sigma_radius_m, {},
      association::LoopMergeTests{
          options_.association.min_loop_pairings, options_.association.loop_confirmation_min_sigma_radius_m,
          [this](const std::vector<int>& landmarks) { return JointCovariance({}, landmarks); }});
  for (const association::LandmarkMerge& m : merges) {  // drop descending: later indices stay valid
    if (absl::Status st = MergeLandmarks(m.keep, m.drop); !st.ok()) return st;
  }
  return absl::OkStatus();
}

absl::Status EkfJoiner::MergeLandmarks(int keep, int drop) {
  if (absl::Status st = graph_.ValidateMerge(keep, drop); !st.ok()) return st;
  if (keep > drop) std::swap(keep, drop);
  // L_drop = L_keep as a zero-noise constraint, then L_drop dropped.
  const int o_drop = landmark_offset_[drop];
  if (absl::Status st = FuseZeroNoise({{o_drop, landmark_offset_[keep]}}); !st.ok()) return st;
  DropVariable(o_drop, 2);
  landmark_offset_.erase(landmark_offset_.begin() + drop);
  if (!x_.allFinite() || !P_.allFinite()) return absl::InternalError("EKF merge produced a non-finite value");
  if (absl::Status st = graph_.MergeLandmarks(keep, drop); !st.ok()) return st;
  associator_.MergeLandmarks(keep, drop);
  for (int& j : last_association_) j = SubmapGraph::RenumberAfterMerge(j, keep, drop);
  WriteBack();
  ++counters_.landmarks_merged;
  return absl::OkStatus();
}

absl::Status EkfJoiner::SplitFeature(int factor, int feature) {
  if (absl::StatusOr<int> st = graph_.SplitFeature(factor, feature); !st.ok()) return st.status();
  ++counters_.features_split;
  return Replay();
}

absl::Status EkfJoiner::Replay() {
  EkfJoiner fresh(graph_.anchors()[0], options_);
  std::vector<int> new_of_old(graph_.num_landmarks(), -1);
  for (const SubmapFactor& f : graph_.factors()) {
    std::vector<int> assoc;
    for (int j : f.landmark_of_feature) assoc.push_back(new_of_old[j]);
    if (absl::Status st = fresh.JoinAssociated(f.submap, assoc); !st.ok()) return st;
    fresh.associator_.RecordRotationFit(f.submap);  // the maps' rotation spread kept
    for (size_t i = 0; i < assoc.size(); ++i) new_of_old[f.landmark_of_feature[i]] = fresh.last_association_[i];
  }
  for (int& j : last_association_) j = new_of_old[j];
  graph_ = std::move(fresh.graph_);
  associator_ = std::move(fresh.associator_);
  x_ = std::move(fresh.x_);
  P_ = std::move(fresh.P_);
  anchor_offset_ = std::move(fresh.anchor_offset_);
  landmark_offset_ = std::move(fresh.landmark_offset_);
  frozen_covariance_ = std::move(fresh.frozen_covariance_);
  return absl::OkStatus();
}

std::unique_ptr<MapJoiner> EkfJoiner::NewEmpty(const Pose2& initial_pose) const {
  return std::make_unique<EkfJoiner>(initial_pose, options_);
}

std::unique_ptr<MapJoiner> EkfJoiner::Clone() const { return std::make_unique<EkfJoiner>(*this); }

absl::Status EkfJoiner::JoinMap(const MapJoiner& right_base) {
  const auto* right_ptr = dynamic_cast<const EkfJoiner*>(&right_base);
  if (right_ptr == nullptr) return absl::InvalidArgumentError("EKF JoinMap: the right map is not an EKF map");
  const EkfJoiner& right = *right_ptr;
  if (!options_.keep_anchors || !right.options_.keep_anchors) {
    return absl::FailedPreconditionError("EKF JoinMap needs keep_anchors on both maps");
  }
  if (right.graph_.factors().empty()) return absl::OkStatus();
  absl::StatusOr<LocalSubmap> summary = SummarizeForJoin(right, last_t_end_);
  if (!summary.ok()) return summary.status();
  const int start = graph_.num_anchors() - 1;
  const int n = right.graph_.num_landmarks();
  std::vector<int> assoc(n, -1);
  if (!graph_.factors().empty()) {
    const std::vector<std::vector<int>> groups = association::WholeMapGroups(right.graph_);
    assoc = AssociateAt(*summary, start, &groups).landmark_of_feature;
  }
  // Augment right's anchors, its new landmarks, then the copies of its matched ones.
  std::vector<Block> blocks;
  for (int k = 1; k < right.graph_.num_anchors(); ++k) blocks.push_back({right.anchor_offset_[k], 3});
  std::vector<int> order;
  for (int pass = 0; pass < 2; ++pass) {
    for (int l = 0; l < n; ++l) {
      if ((assoc[l] >= 0) == (pass == 1)) {
        order.push_back(l);
        blocks.push_back({right.landmark_offset_[l], 2});
      }
    }
  }
  const int first_new_landmark = graph_.num_landmarks();
  std::vector<int> offsets;
  {
    StageTimer timer(&times_, "augmentation");
    offsets = Augment(start, right.x_, right.P_, blocks);
  }
  std::vector<int> anchor_map = {start};
  const int right_anchors = right.graph_.num_anchors() - 1;
  for (int k = 1; k <= right_anchors; ++k) {
    anchor_map.push_back(graph_.AddAnchor(Pose2()));
    anchor_offset_.push_back(offsets[k - 1]);
  }
  frozen_covariance_.resize(graph_.num_anchors(), Eigen::Matrix3d::Zero());
  std::vector<std::pair<int, int>> copies;
  for (size_t b = 0; b < order.size(); ++b) {
    const int l = order[b];
    if (assoc[l] >= 0) {
      copies.emplace_back(offsets[right_anchors + b], landmark_offset_[assoc[l]]);
    } else {
      assoc[l] = graph_.AddLandmark(Eigen::Vector2d::Zero());
      landmark_offset_.push_back(offsets[right_anchors + b]);
    }
  }
  if (!copies.empty()) {
    StageTimer timer(&times_, "update");
    if (absl::Status st = FuseZeroNoise(copies); !st.ok()) return st;
    const int keep = static_cast<int>(x_.size()) - 2 * static_cast<int>(copies.size());
    P_.conservativeResize(keep, keep);
    x_.conservativeResize(keep);
  }
  if (!x_.allFinite() || !P_.allFinite()) return absl::InternalError("EKF map join produced a non-finite value");
  WriteBack();
  associator_.Record(*summary, assoc, first_new_landmark, /*define_truth=*/true);
  for (const SubmapFactor& f : right.graph_.factors()) {
    std::vector<int> landmarks;
    for (int l : f.landmark_of_feature) landmarks.push_back(assoc[l]);
    graph_.AddFactor({f.submap, anchor_map[f.start_anchor], anchor_map[f.end_anchor], landmarks});
  }
  last_association_.clear();
  for (int l : right.last_association_) last_association_.push_back(assoc[l]);
  const long matched = static_cast<long>(copies.size());
  counters_ += right.counters_;  // its joins, then this join's merges
  counters_.associated += matched;
  counters_.new_landmarks -= matched;
  for (const auto& [stage, seconds] : right.times_) times_[stage] += seconds;
  last_t_end_ = right.last_t_end_;
  return ReviseAssociation();
}

}  // namespace subslam::backend
