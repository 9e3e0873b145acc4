#include "subslam/frontend/data_association.h"

#include <gtest/gtest.h>

namespace subslam::frontend {
namespace {

AssociationCandidate C(int landmark, double nu0, double nu1) {
  // Unit innovation covariance: d² = ‖ν‖².
  return {landmark, nu0 * nu0 + nu1 * nu1, Eigen::Vector2d(nu0, nu1)};
}

TEST(NearestNeighbour, OneToOneInIncreasingDistance) {
  AssociationProblem p;
  p.candidates = {{C(0, 0.5, 0), C(1, 1.0, 0)}, {C(0, 0.1, 0)}};
  const AssociationResult r = NearestNeighbour(p);
  // Detection 1 is closer to landmark 0, so detection 0 falls back to landmark 1.
  EXPECT_EQ(r.landmark_of_detection, (std::vector<int>{1, 0}));
  EXPECT_EQ(r.pairings, 2);
}

TEST(JointCompatibility, RejectsJointlyIncompatiblePairings) {
  // Two landmarks whose predicted measurements are strongly correlated (a shared pose
  // error): individually both pairings pass, but their innovations point in opposite
  // directions, which the joint covariance makes implausible.
  AssociationProblem p;
  p.candidates = {{C(0, 2.0, 0)}, {C(1, -2.0, 0)}};
  p.covariance_block = [](int, int a, int, int b) -> Eigen::Matrix2d {
    return Eigen::Matrix2d::Identity() * (a == b ? 1.0 : 0.95);
  };
  const AssociationResult nn = NearestNeighbour(p);
  EXPECT_EQ(nn.pairings, 2);
  const AssociationResult jc = JointCompatibility(p, 0.99, 1000);
  EXPECT_EQ(jc.pairings, 1);
  EXPECT_FALSE(jc.truncated);
  // With independent landmarks, both pairings are jointly compatible.
  p.covariance_block = [](int, int a, int, int b) -> Eigen::Matrix2d {
    return Eigen::Matrix2d::Identity() * (a == b ? 1.0 : 0.0);
  };
  const AssociationResult both = JointCompatibility(p, 0.99, 1000);
  EXPECT_EQ(both.pairings, 2);
  EXPECT_NEAR(both.joint_d2, 8.0, 1e-12);
}

TEST(JointCompatibility, PrefersConsistentShiftedHypothesis) {
  // Detections shifted consistently by the same pose error: JCBB pairs them with the
  // landmarks that agree on the shift rather than the individually nearest ones.
  AssociationProblem p;
  p.candidates = {{C(1, 0.2, 0), C(0, 1.5, 0)}, {C(1, 1.5, 0), C(2, -2.8, 0)}};
  p.covariance_block = [](int, int a, int, int b) -> Eigen::Matrix2d {
    return Eigen::Matrix2d::Identity() * (a == b ? 1.0 : 0.9);
  };
  EXPECT_EQ(NearestNeighbour(p).landmark_of_detection, (std::vector<int>{1, 2}));
  const AssociationResult r = JointCompatibility(p, 0.99, 1000);
  EXPECT_EQ(r.pairings, 2);
  EXPECT_EQ(r.landmark_of_detection, (std::vector<int>{0, 1}));
}

// Detections without candidates do not spend the search budget: among 500 detections of
// which 3 have candidates, a 20-node budget still finds the full hypothesis (every node
// of the old search visited each detection, 500 nodes per hypothesis).
TEST(JointCompatibility, DetectionsWithoutCandidatesCostNothing) {
  AssociationProblem p;
  p.candidates.resize(500);
  p.candidates[10] = {C(0, 0.3, 0)};
  p.candidates[250] = {C(1, 0, 0.2), C(2, 0.5, 0.5)};
  p.candidates[499] = {C(3, 0.1, 0.1)};
  p.covariance_block = [](int, int a, int, int b) -> Eigen::Matrix2d {
    return Eigen::Matrix2d::Identity() * (a == b ? 1.0 : 0.0);
  };
  const AssociationResult r = JointCompatibility(p, 0.99, 20);
  EXPECT_FALSE(r.truncated);
  EXPECT_EQ(r.pairings, 3);
  EXPECT_EQ(r.landmark_of_detection[10], 0);
  EXPECT_EQ(r.landmark_of_detection[250], 1);
  EXPECT_EQ(r.landmark_of_detection[499], 3);
  EXPECT_EQ(r.landmark_of_detection[0], -1);
}

}  // namespace
}  // namespace subslam::frontend
