// The flag bindings shared by the tool and the benches: every flag reaches the options it
// names, in every front-end or back-end that uses it.
#include <gtest/gtest.h>

#include "absl/flags/declare.h"
#include "absl/flags/flag.h"
#include "absl/flags/reflection.h"
#include "backend_flags.h"
#include "frontend_flags.h"

ABSL_DECLARE_FLAG(std::string, association);
ABSL_DECLARE_FLAG(double, gate);
ABSL_DECLARE_FLAG(double, existence_alpha);
ABSL_DECLARE_FLAG(int, particles);
ABSL_DECLARE_FLAG(std::string, seif_pose_covariance);
ABSL_DECLARE_FLAG(double, submap_max_duration);
ABSL_DECLARE_FLAG(std::string, backend);
ABSL_DECLARE_FLAG(bool, single_linearization);
ABSL_DECLARE_FLAG(bool, join_merge);
ABSL_DECLARE_FLAG(bool, join_confirm_thin_loops);
ABSL_DECLARE_FLAG(double, join_map_rotation_sigma);
ABSL_DECLARE_FLAG(double, join_map_rotation_level);
ABSL_DECLARE_FLAG(double, join_map_rotation_spread_level);
ABSL_DECLARE_FLAG(std::string, ceres_method);
ABSL_DECLARE_FLAG(double, eif_recovery_threshold);
ABSL_DECLARE_FLAG(std::string, ekf_fusion);
ABSL_DECLARE_FLAG(int, ceres_every);

namespace subslam::cli {
namespace {

TEST(FrontendFlags, ReachEveryFrontEndsOptions) {
  absl::FlagSaver restore;
  absl::SetFlag(&FLAGS_association, "jcbb");
  absl::SetFlag(&FLAGS_gate, 0.95);
  absl::SetFlag(&FLAGS_existence_alpha, 0.7);
  absl::SetFlag(&FLAGS_known_association, true);
  absl::SetFlag(&FLAGS_particles, 37);
  absl::SetFlag(&FLAGS_seif_pose_covariance, "exact");
  absl::SetFlag(&FLAGS_submap_max_duration, 4.0);
  pipeline::RunOptions o;
  ASSERT_TRUE(SetFrontendOptionsFromFlags(&o).ok());
  EXPECT_EQ(o.ekf.association, association::AssociationMethod::kJointCompatibility);
  EXPECT_EQ(o.seif.association, association::AssociationMethod::kJointCompatibility);
  for (const frontend::LandmarkOptions* l : {&o.ekf.landmarks, &o.fastslam.landmarks, &o.seif.landmarks}) {
    EXPECT_EQ(l->gate_probability, 0.95);
    EXPECT_EQ(l->existence.detection_probability, 0.7);
    EXPECT_TRUE(l->known_association);
  }
  EXPECT_EQ(o.fastslam.num_particles, 37);
  EXPECT_EQ(o.seif.pose_covariance, frontend::CovarianceRecovery::kExact);
  EXPECT_EQ(o.policy.max_duration_s, 4.0);
}

TEST(FrontendFlags, AnUnknownNameIsAnError) {
  absl::FlagSaver restore;
  absl::SetFlag(&FLAGS_association, "greedy");
  pipeline::RunOptions o;
  const absl::Status st = SetFrontendOptionsFromFlags(&o);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("greedy"), std::string_view::npos);
}

TEST(BackendFlags, ReachTheBackEndsOptions) {
  absl::FlagSaver restore;
  absl::SetFlag(&FLAGS_backend, "ceres");
  absl::SetFlag(&FLAGS_known_association, true);
  absl::SetFlag(&FLAGS_single_linearization, true);
  absl::SetFlag(&FLAGS_join_merge, false);
  absl::SetFlag(&FLAGS_join_confirm_thin_loops, false);
  absl::SetFlag(&FLAGS_join_map_rotation_sigma, 0.2);
  absl::SetFlag(&FLAGS_join_map_rotation_level, 0.95);
  absl::SetFlag(&FLAGS_join_map_rotation_spread_level, 0.99);
  absl::SetFlag(&FLAGS_ceres_method, "dogleg");
  absl::SetFlag(&FLAGS_ceres_every, 5);
  absl::SetFlag(&FLAGS_eif_recovery_threshold, 1e-6);
  absl::StatusOr<pipeline::BackendOptions> o = BackendOptionsFromFlags();
  ASSERT_TRUE(o.ok()) << o.status();
  EXPECT_EQ(o->kind, pipeline::Backend::kCeres);
  EXPECT_TRUE(o->eif.association.known_association);
  EXPECT_TRUE(o->ekf.association.known_association);
  EXPECT_EQ(o->eif.relinearize_at_end, false);  // the single linearisation
  EXPECT_FALSE(o->eif.revision.merge);
  EXPECT_FALSE(o->ekf.revision.merge);
  EXPECT_FALSE(o->eif.association.confirm_thin_loops);
  EXPECT_EQ(o->eif.association.map_rotation_sigma_rad, 0.2);
  EXPECT_EQ(o->ekf.association.map_rotation_sigma_rad, 0.2);
  EXPECT_EQ(o->eif.association.map_rotation_probability, 0.95);
  EXPECT_EQ(o->ekf.association.map_rotation_probability, 0.95);
  EXPECT_EQ(o->eif.association.map_rotation_spread_probability, 0.99);
  EXPECT_EQ(o->ekf.association.map_rotation_spread_probability, 0.99);
  EXPECT_EQ(o->ceres.method, backend::CeresMethod::kDogleg);
  EXPECT_EQ(o->ceres_every, 5);
  EXPECT_EQ(o->eif.recovery_change_threshold, 1e-6);
}

TEST(BackendFlags, ARotationSpreadLevelOutsideItsRangeIsAnErrorThatNamesIt) {
  for (double bad : {1.0, -0.5}) {
    absl::FlagSaver restore;
    absl::SetFlag(&FLAGS_join_map_rotation_spread_level, bad);
    const absl::StatusOr<pipeline::BackendOptions> o = BackendOptionsFromFlags();
    ASSERT_FALSE(o.ok()) << bad;
    EXPECT_NE(o.status().message().find("map_rotation_spread_probability"), std::string_view::npos) << o.status();
  }
}

TEST(BackendFlags, AnUnknownNameIsAnErrorThatNamesIt) {
  for (const auto& [flag, bad] : {std::pair{&FLAGS_backend, "gtsam"}, std::pair{&FLAGS_ceres_method, "bfgs"},
                                  std::pair{&FLAGS_ekf_fusion, "average"}}) {
    absl::FlagSaver restore;
    absl::SetFlag(flag, bad);
    const absl::StatusOr<pipeline::BackendOptions> o = BackendOptionsFromFlags();
    ASSERT_FALSE(o.ok()) << bad;
    EXPECT_NE(o.status().message().find(bad), std::string_view::npos) << o.status();
  }
}

}  // namespace
}  // namespace subslam::cli
