#include "subslam/backend/tree_joiner.h"

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "subslam/core/check.h"

namespace subslam::backend {

TreeJoiner::TreeJoiner(std::unique_ptr<MapJoiner> prototype, const TreeJoinerOptions& options)
    : prototype_(std::move(prototype)), options_(options) {
  SUBSLAM_CHECK(prototype_ != nullptr && prototype_->num_anchors() == 1 && prototype_->num_landmarks() == 0)
      << "the prototype must be an empty joiner";
  initial_pose_ = prototype_->anchor(0);
  SUBSLAM_CHECK(prototype_->NewEmpty(Pose2()) != nullptr) << prototype_->Name() << " cannot be a tree node";
  rotation_spread_ = prototype_->associator().rotation_spread();  // empty, with the nodes' levels
}

std::unique_ptr<MapJoiner> TreeJoiner::NewEmpty(const Pose2& initial_pose) const {
  return std::make_unique<TreeJoiner>(prototype_->NewEmpty(initial_pose), options_);
}

absl::Status TreeJoiner::JoinLocalMap(const LocalSubmap& submap) {
  if (finished_) return absl::FailedPreconditionError("the tree is finished");
  if (!status_.ok()) return status_;
  if (absl::Status v = submap.Validate(); !v.ok()) return v;
  const LocalSubmap widened = rotation_spread_.Widened(submap);  // by the maps' rotation spread so far
  const std::optional<LocalSubmap> rotated_back = RotatedAgainstPrevious(widened);
  // A leaf lives in the frame of its start anchor; the leftmost in the world frame.
  std::unique_ptr<MapJoiner> leaf = prototype_->NewEmpty(nodes_.empty() ? initial_pose_ : Pose2());
  if (absl::Status st = leaf->Join(rotated_back ? *rotated_back : widened); !st.ok()) return st;
  if (rotated_back) ++maps_widened_;
  if (TestsRotation()) previous_leaf_ = leaf->Clone();
  folded_.reset();
  nodes_.push_back({std::move(leaf), 0, std::nullopt});
  if (!options_.running) return absl::OkStatus();
  while (nodes_.size() >= 2 && nodes_[nodes_.size() - 2].level == nodes_.back().level) {
    Node right = std::move(nodes_.back());
    nodes_.pop_back();
    Node& left = nodes_.back();
    if (absl::Status st = left.map->JoinMap(*right.map); !st.ok()) {
      status_ = st;
      return st;
    }
    ++left.level;
    left.last_anchor_covariance.reset();
    ++tree_joins_;
  }
  return absl::OkStatus();
}

std::optional<LocalSubmap> TreeJoiner::RotatedAgainstPrevious(const LocalSubmap& submap) {
  if (previous_leaf_ == nullptr || !TestsRotation()) return std::nullopt;
  const absl::Time start = absl::Now();
  const MapJoiner& previous = *previous_leaf_;
  const association::SubmapAssociation a =
      previous.associator().Associate(submap, previous.num_anchors() - 1, previous.graph(),
                                      [&previous](const std::vector<int>& anchors, const std::vector<int>& landmarks) {
                                        return previous.JointCovariance(anchors, landmarks);
                                      });
  rotation_test_seconds_ += absl::ToDoubleSeconds(absl::Now() - start);
  rotation_spread_.Add(a.map_rotation_fit_rad, a.map_rotation_fit_variance_rad2, submap.rotation_spread_rad);
  return association::RotatedBack(submap, a);
}

bool TreeJoiner::TestsRotation() const {
  const association::SubmapAssociationOptions& o = prototype_->associator().options();
  return o.map_rotation_sigma_rad > 0 && o.joint_compatibility && !o.known_association;
}

absl::Status TreeJoiner::Finish() {
  if (finished_) return status_;
  finished_ = true;
  folded_.reset();
  if (!status_.ok()) return status_;
  if (nodes_.empty()) return absl::OkStatus();
  if (options_.running) {  // fold right to left: the small nodes first
    while (nodes_.size() > 1) {
      Node right = std::move(nodes_.back());
      nodes_.pop_back();
      if (absl::Status st = nodes_.back().map->JoinMap(*right.map); !st.ok()) return status_ = st;
      nodes_.back().last_anchor_covariance.reset();
      ++tree_joins_;
    }
  } else {
    while (nodes_.size() > 1) {  // level by level
      std::vector<Node> next;
      for (size_t i = 0; i + 1 < nodes_.size(); i += 2) {
        if (absl::Status st = nodes_[i].map->JoinMap(*nodes_[i + 1].map); !st.ok()) return status_ = st;
        nodes_[i].last_anchor_covariance.reset();
        ++tree_joins_;
        ++nodes_[i].level;
        next.push_back(std::move(nodes_[i]));
      }
      if (nodes_.size() % 2 == 1) next.push_back(std::move(nodes_.back()));
      nodes_ = std::move(next);
    }
  }
  status_ = nodes_.front().map->Finish();
  nodes_.front().last_anchor_covariance.reset();
  return status_;
}

const MapJoiner& TreeJoiner::Whole() const {
  if (nodes_.empty()) return *prototype_;
  if (nodes_.size() == 1) return *nodes_.front().map;
  if (folded_ == nullptr) {
    const absl::Time start = absl::Now();
    std::unique_ptr<MapJoiner> acc = nodes_.back().map->Clone();
    for (int i = static_cast<int>(nodes_.size()) - 2; i >= 0; --i) {
      std::unique_ptr<MapJoiner> left = nodes_[i].map->Clone();
      const absl::Status st = left->JoinMap(*acc);
      SUBSLAM_CHECK(st.ok()) << "folding the tree: " << st.message();
      acc = std::move(left);
    }
    folded_ = std::move(acc);
    fold_seconds_ += absl::ToDoubleSeconds(absl::Now() - start);
  }
  return *folded_;
}

void TreeJoiner::Chain(Pose2* pose, Eigen::Matrix3d* covariance) const {
  *pose = initial_pose_;
  if (covariance != nullptr) covariance->setZero();
  for (size_t i = 0; i < nodes_.size(); ++i) {
    const MapJoiner& node = *nodes_[i].map;
    const auto node_covariance = [&]() -> const Eigen::Matrix3d& {
      if (!nodes_[i].last_anchor_covariance) nodes_[i].last_anchor_covariance = node.LastAnchorCovariance();
      return *nodes_[i].last_anchor_covariance;
    };
    if (i == 0) {  // in the world frame already
      *pose = node.LastAnchor();
      if (covariance != nullptr) *covariance = node_covariance();
      continue;
    }
    *pose = covariance != nullptr
                ? ComposeWithCovariance(*pose, *covariance, node.LastAnchor(), node_covariance(), covariance)
                : Compose(*pose, node.LastAnchor());
  }
}

Pose2 TreeJoiner::LastAnchor() const {
  if (options_.online_anchor_from_whole_map && nodes_.size() > 1) return Whole().LastAnchor();
  Pose2 p;
  Chain(&p, nullptr);
  return p;
}

Eigen::Matrix3d TreeJoiner::LastAnchorCovariance() const {
  if (options_.online_anchor_from_whole_map && nodes_.size() > 1) return Whole().LastAnchorCovariance();
  Pose2 p;
  Eigen::Matrix3d c;
  Chain(&p, &c);
  return c;
}

std::map<std::string, double> TreeJoiner::stage_times() const {
  std::map<std::string, double> out;
  for (const Node& node : nodes_) {
    for (const auto& [stage, seconds] : node.map->stage_times()) out[stage] += seconds;
  }
  out["fold"] = fold_seconds_;
  out["leaf_rotation_test"] = rotation_test_seconds_;
  return out;
}

const JoinerCounters& TreeJoiner::counters() const {
  counters_ = JoinerCounters();
  for (const Node& node : nodes_) {
    counters_ += node.map->counters();
  }
  counters_.maps_widened += maps_widened_;
  return counters_;
}

}  // namespace subslam::backend
