#include "subslam/frontend/submap_policy.h"

#include <gtest/gtest.h>

#include <cmath>

namespace subslam::frontend {
namespace {

SubmapPolicy Policy(SubmapPolicyOptions o) { return SubmapPolicy(o, 0.1, 0.01); }

SubmapStatus Quiet(double elapsed) {
  SubmapStatus s;
  s.elapsed_s = elapsed;
  s.pose_covariance = 1e-6 * Eigen::Matrix3d::Identity();
  return s;
}

TEST(SubmapPolicy, EachCriterionClosesTheMap) {
  SubmapPolicyOptions o;
  o.max_duration_s = 10;
  o.max_features = 20;
  o.max_pose_sigma_ratio = 3;
  o.min_ess_ratio = 0.1;
  o.min_lineage_diversity = 0.3;
  o.density_min_features = 5;
  o.density_min_visible = 4;
  const SubmapPolicy p = Policy(o);
  EXPECT_EQ(p.Decide(Quiet(5)).reason, CloseReason::kKeepOpen);
  EXPECT_EQ(p.Decide(Quiet(10)).reason, CloseReason::kElapsedTime);
  SubmapStatus s = Quiet(5);
  s.pose_covariance(0, 0) = 0.31 * 0.31;  // σ_x = 3.1 σ_r
  EXPECT_EQ(p.Decide(s).reason, CloseReason::kPoseUncertainty);
  s = Quiet(5);
  s.ess_ratio = 0.05;
  EXPECT_EQ(p.Decide(s).reason, CloseReason::kDiversity);
  s = Quiet(5);
  s.lineage_diversity = 0.2;
  EXPECT_EQ(p.Decide(s).reason, CloseReason::kDiversity);
  s = Quiet(5);
  s.confirmed_features = 20;
  EXPECT_EQ(p.Decide(s).reason, CloseReason::kFeatureCount);
  s = Quiet(5);
  s.confirmed_features = 6;
  s.visible_features = 3;
  EXPECT_EQ(p.Decide(s).reason, CloseReason::kKeepOpen);
  s.visible_features = 4;
  EXPECT_EQ(p.Decide(s).reason, CloseReason::kLandmarkDensity);
}

TEST(SubmapPolicy, MinimumDurationAndDisabled) {
  SubmapPolicyOptions o;
  o.min_duration_s = 2;
  o.max_features = 1;
  SubmapStatus s = Quiet(1);
  s.confirmed_features = 5;
  EXPECT_EQ(Policy(o).Decide(s).reason, CloseReason::kKeepOpen);
  s.elapsed_s = 2;
  EXPECT_EQ(Policy(o).Decide(s).reason, CloseReason::kFeatureCount);
  o.enabled = false;
  EXPECT_EQ(Policy(o).Decide(s).reason, CloseReason::kKeepOpen);
}

TEST(SubmapPolicy, DelaysWhileAmbiguousUpToTheLimit) {
  SubmapPolicyOptions o;
  o.max_duration_s = 10;
  o.delay_while_ambiguous = true;
  o.ambiguity_threshold = 0.2;
  o.max_delay_s = 3;
  SubmapStatus s = Quiet(10);
  s.disagreement = 0.4;
  const SubmapDecision first = Policy(o).Decide(s);
  EXPECT_EQ(first.reason, CloseReason::kKeepOpen);
  EXPECT_TRUE(first.delayed);
  s.delayed_for_s = 3;
  EXPECT_EQ(Policy(o).Decide(s).reason, CloseReason::kElapsedTime);
  s.delayed_for_s = 0;
  s.disagreement = 0.1;
  EXPECT_EQ(Policy(o).Decide(s).reason, CloseReason::kElapsedTime);
}

TEST(SubmapPolicyOptions, ValidationRejectsNonsense) {
  SubmapPolicyOptions o;
  EXPECT_TRUE(o.Validate().ok());
  o.min_ess_ratio = 2;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.max_duration_s = -1;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.density_min_visible = 0;
  EXPECT_FALSE(o.Validate().ok());
  for (const double bad : {-1.0, static_cast<double>(NAN), static_cast<double>(INFINITY)}) {
    o = {};
    o.max_feature_sigma_ratio = bad;
    EXPECT_FALSE(o.Validate().ok()) << bad;
  }
}

}  // namespace
}  // namespace subslam::frontend
