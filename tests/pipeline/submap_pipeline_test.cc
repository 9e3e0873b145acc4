// The submap pipeline with the EIF back-end, end to end on simulated data.
#include <gtest/gtest.h>

#include <algorithm>
#include <boost/math/distributions/binomial.hpp>
#include <cmath>
#include <fstream>
#include <optional>

#include "simulated_dataset.h"
#include "subslam/eval/nees.h"
#include "subslam/eval/trajectory_errors.h"
#include "subslam/io/steps.h"
#include "subslam/io/submaps_jsonl.h"
#include "subslam/models/gating.h"
#include "subslam/pipeline/join_pipeline.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/pipeline/submap_slam.h"
#include "subslam/sim/simulator.h"

namespace subslam::pipeline {
namespace {

// The EKF local maps of a run (no back-end).
std::vector<LocalSubmap> EkfLocalMaps(const io::Dataset& d) {
  RunOptions run;
  run.frontend = Frontend::kEkfLocal;
  absl::StatusOr<RunResult> r = RunPipeline(d, run);
  EXPECT_TRUE(r.ok()) << r.status();
  return r.ok() ? r->local_maps : std::vector<LocalSubmap>{};
}

// Joining closes the loop: the final trajectory passes the 10σ test and is more accurate
// than the same local maps chained without a back-end; the joined map has no spurious
// landmark; the online trajectory is the one a navigation stack had (also not failed).
TEST(SubmapPipeline, EkfLocalMapsJoinedByEifBeatChaining) {
  for (uint64_t seed : {1, 2}) {
    RunOptions options;
    options.frontend = Frontend::kEkfLocal;
    options.backend.kind = Backend::kNone;
    absl::StatusOr<RunResult> chained = RunPipeline(Simulate(seed), options);
    ASSERT_TRUE(chained.ok()) << chained.status();
    options.backend.kind = Backend::kEif;
    options.backend.eif.relinearize_at_end = true;
    absl::StatusOr<RunResult> joined = RunPipeline(Simulate(seed), options);
    ASSERT_TRUE(joined.ok()) << joined.status();
    EXPECT_FALSE(joined->errors->failed) << seed;
    EXPECT_FALSE(joined->errors_online->failed) << seed;
    EXPECT_LT(joined->errors->rms_position_m, chained->errors->rms_position_m) << seed;
    EXPECT_EQ(joined->map_errors->spurious, 0) << seed;
    EXPECT_LT(joined->map_errors->duplicates, chained->map_errors->duplicates) << seed;  // merged
    EXPECT_EQ(joined->final_trajectory.size(), joined->online.size());
  }
}

// Background joins (BackendOptions::background): the final trajectory and the map are
// those of the synchronous run, to the bit; the online pose is one join behind — the
// same while maps 0 and 1 are built (map 0's join changes nothing before map 1 closes),
// different later — and the same from run to run whatever the RBPF's thread count (it
// gives the join a core while one runs).
TEST(SubmapPipeline, BackgroundJoinsGiveTheSynchronousEstimatesWithTheOnlinePoseOneJoinBehind) {
  const io::Dataset d = Simulate(3, "hybrid-120m", 40.0);
  RunOptions options;
  options.frontend = Frontend::kRbpf;
  options.backend.kind = Backend::kEif;
  options.fastslam.num_threads = 2;
  options.backend.background = false;
  absl::StatusOr<RunResult> synchronous = RunPipeline(d, options);
  ASSERT_TRUE(synchronous.ok()) << synchronous.status();
  options.backend.background = true;  // the tool's default
  absl::StatusOr<RunResult> background = RunPipeline(d, options);
  ASSERT_TRUE(background.ok()) << background.status();
  options.fastslam.num_threads = 1;
  absl::StatusOr<RunResult> one_thread = RunPipeline(d, options);
  ASSERT_TRUE(one_thread.ok()) << one_thread.status();
  ASSERT_GE(synchronous->local_maps.size(), 5u);

  ASSERT_EQ(background->final_trajectory.size(), synchronous->final_trajectory.size());
  for (size_t k = 0; k < synchronous->final_trajectory.size(); ++k) {
    ASSERT_EQ(background->final_trajectory[k].pose.vector(), synchronous->final_trajectory[k].pose.vector()) << k;
    ASSERT_EQ(background->final_trajectory[k].covariance, synchronous->final_trajectory[k].covariance) << k;
  }
  ASSERT_EQ(background->landmarks.size(), synchronous->landmarks.size());
  for (size_t j = 0; j < synchronous->landmarks.size(); ++j) {
    ASSERT_EQ(background->landmarks[j].position, synchronous->landmarks[j].position) << j;
  }
  // Online: the same until map 1 closes (map 0's join only solves for the anchor it
  // initialised, to rounding), then one join behind.
  const double map1_end = synchronous->local_maps[1].t_end;
  size_t differing = 0;
  for (size_t k = 0; k < synchronous->online.size(); ++k) {
    const double difference =
        (background->online[k].pose.vector() - synchronous->online[k].pose.vector()).cwiseAbs().maxCoeff();
    if (synchronous->online[k].t < map1_end) {
      ASSERT_LT(difference, 1e-9) << "step " << k << " at " << synchronous->online[k].t << " s";
    }
    differing += difference > 1e-6 ? 1 : 0;
    ASSERT_EQ(one_thread->online[k].pose.vector(), background->online[k].pose.vector()) << k;
  }
  EXPECT_GT(differing, synchronous->online.size() / 4);
  EXPECT_FALSE(background->errors_online->failed);
  // Only a background run leaves the joins a core (how many scans depends on timing;
  // FastSlam.ThreadLimitChangesNothingButTheThreadsUsed tests the limit itself).
  EXPECT_EQ(synchronous->report["estimator_counters"]["scans_with_fewer_threads"].get<double>(), 0.0);
}

// Background joins through every other back-end (EKF local maps): the final trajectory
// and the map are the synchronous run's, to the bit — Ceres solving on its schedule in
// the joining thread, the tree joiners folding their nodes there.
TEST(SubmapPipeline, BackgroundJoinsGiveEveryBackendsSynchronousEstimates) {
  const io::Dataset d = Simulate(2, "hybrid-120m", 60.0);
  for (const Backend kind : {Backend::kCeres, Backend::kEkf, Backend::kTreeEkf, Backend::kTreeEif}) {
    RunOptions options;
    options.frontend = Frontend::kEkfLocal;
    options.backend.kind = kind;
    options.backend.ceres_every = 3;
    options.backend.background = false;
    absl::StatusOr<RunResult> synchronous = RunPipeline(d, options);
    ASSERT_TRUE(synchronous.ok()) << ToString(kind) << ": " << synchronous.status();
    options.backend.background = true;
    absl::StatusOr<RunResult> background = RunPipeline(d, options);
    ASSERT_TRUE(background.ok()) << ToString(kind) << ": " << background.status();
    ASSERT_GE(synchronous->local_maps.size(), 6u) << ToString(kind);
    if (kind == Backend::kCeres) {
      EXPECT_EQ(background->report["estimator_counters"]["ceres_solves"].get<double>(),
                static_cast<double>(synchronous->local_maps.size() / 3 + 1));
    }
    ASSERT_EQ(background->final_trajectory.size(), synchronous->final_trajectory.size()) << ToString(kind);
    for (size_t k = 0; k < synchronous->final_trajectory.size(); ++k) {
      ASSERT_EQ(background->final_trajectory[k].pose.vector(), synchronous->final_trajectory[k].pose.vector())
          << ToString(kind) << " step " << k;
      ASSERT_EQ(background->final_trajectory[k].covariance, synchronous->final_trajectory[k].covariance)
          << ToString(kind) << " step " << k;
    }
    ASSERT_EQ(background->landmarks.size(), synchronous->landmarks.size()) << ToString(kind);
    for (size_t j = 0; j < synchronous->landmarks.size(); ++j) {
      ASSERT_EQ(background->landmarks[j].position, synchronous->landmarks[j].position) << ToString(kind);
    }
    // Online one join behind (so the joins did run in the background), still a sound
    // estimate.
    ASSERT_EQ(background->online.size(), synchronous->online.size()) << ToString(kind);
    size_t differing = 0;
    for (size_t k = 0; k < synchronous->online.size(); ++k) {
      differing +=
          (background->online[k].pose.vector() - synchronous->online[k].pose.vector()).cwiseAbs().maxCoeff() > 1e-6;
    }
    EXPECT_GT(differing, synchronous->online.size() / 4) << ToString(kind);
    EXPECT_FALSE(background->errors_online->failed) << ToString(kind);
  }
}

// The online pose one join behind, exactly: right after the update that closes map k,
// the pose is the joiner's last anchor before that update (map k's start anchor as
// joined so far) composed with map k's end pose (the new map's local pose is the
// identity). A SubmapSlam destroyed while a join runs finishes it first.
TEST(SubmapSlam, BackgroundOnlinePoseIsTheLastJoinedAnchorThroughTheClosedMapsEndPose) {
  const io::Dataset d = Simulate(4, "hybrid-120m", 30.0);
  const auto make = [&d] {
    frontend::FastSlamOptions fastslam;
    fastslam.num_threads = 2;
    const double t0 = d.controls.empty() ? 0.0 : d.controls.front().t;
    auto mapper = std::make_unique<frontend::RbpfLocalMapper>(d.motion.MakeModel(), d.sensor.range_bearing, fastslam,
                                                              frontend::SubmapPolicyOptions{}, t0);
    BackendOptions backend;
    backend.kind = Backend::kEif;
    backend.background = true;
    return std::make_unique<SubmapSlam>(std::move(mapper), d.initial_pose, backend);
  };
  std::unique_ptr<SubmapSlam> slam = make(), abandoned = make();
  int closes = 0;
  for (const io::Step& step : io::BuildSteps(d)) {
    slam->Predict(step.control, step.dt);
    if (abandoned) abandoned->Predict(step.control, step.dt);
    if (step.scan_index < 0) continue;
    const Scan& scan = d.scans[step.scan_index];
    const Pose2 last_joined = slam->joiner()->LastAnchor();  // waits for the pending join
    const size_t maps = slam->local_maps().size();
    EXPECT_TRUE(slam->Update(scan).ok());
    if (abandoned) {
      const size_t abandoned_maps = abandoned->local_maps().size();
      EXPECT_TRUE(abandoned->Update(scan).ok());
      if (abandoned->local_maps().size() > abandoned_maps && abandoned_maps >= 2) abandoned.reset();  // mid-join
    }
    if (slam->local_maps().size() == maps) continue;
    ASSERT_EQ(slam->local_maps().size(), maps + 1);
    const Pose2 expected = Compose(last_joined, slam->local_maps().back().submap.end_pose());
    const Eigen::Vector3d difference = slam->pose().vector() - expected.vector();
    EXPECT_LT(difference.head<2>().norm(), 1e-9) << "map " << maps;
    EXPECT_LT(std::abs(WrapAngle(difference[2])), 1e-12) << "map " << maps;
    ++closes;
  }
  EXPECT_EQ(abandoned, nullptr);
  EXPECT_GE(closes, 5);
  ASSERT_TRUE(slam->Finish().ok());
  EXPECT_EQ(slam->joiner()->num_anchors(), static_cast<int>(slam->local_maps().size()) + 1);
}

// --backend ceres: the EIF's association, then one Ceres solve of the whole graph; the
// final trajectory is at least as good as the EIF's without its Gauss-Newton at the end,
// and the same as with it (the default: both are the optimum, to the EIF's tolerance).
TEST(SubmapPipeline, CeresSolveAfterTheEif) {
  RunOptions options;
  options.frontend = Frontend::kEkfLocal;
  options.backend.kind = Backend::kEif;
  absl::StatusOr<RunResult> converged = RunPipeline(Simulate(1), options);
  ASSERT_TRUE(converged.ok()) << converged.status();
  options.backend.eif.relinearize_at_end = false;
  absl::StatusOr<RunResult> eif = RunPipeline(Simulate(1), options);
  ASSERT_TRUE(eif.ok()) << eif.status();
  options.backend.kind = Backend::kCeres;
  options.backend.eif.relinearize_at_end = true;  // the default, which the Ceres back-end skips
  absl::StatusOr<RunResult> ceres = RunPipeline(Simulate(1), options);
  ASSERT_TRUE(ceres.ok()) << ceres.status();
  // Its EIF relinearised only as the one without Gauss-Newton at the end did.
  EXPECT_EQ(ceres->report["estimator_counters"]["join_relinearizations"].get<double>(),
            eif->report["estimator_counters"]["join_relinearizations"].get<double>());
  EXPECT_GT(ceres->report["estimator_counters"]["ceres_iterations"].get<double>(), 0);
  EXPECT_LE(ceres->report["estimator_counters"]["ceres_final_cost"].get<double>(),
            ceres->report["estimator_counters"]["ceres_initial_cost"].get<double>());
  // (A revision of the association at the end solves the EIF again, to convergence.)
  EXPECT_LE(ceres->errors->rms_position_m, eif->errors->rms_position_m * (1.0 + 1e-4));
  EXPECT_NEAR(converged->errors->rms_position_m, ceres->errors->rms_position_m, 1e-3);
  EXPECT_GT(converged->report["estimator_counters"]["join_relinearizations"].get<double>(),
            eif->report["estimator_counters"]["join_relinearizations"].get<double>());
  EXPECT_FALSE(ceres->errors->failed);
  // With the ISEIF-style schedule: a solve every 10 joins and at the end, same minimum.
  options.backend.ceres_every = 10;
  absl::StatusOr<RunResult> every = RunPipeline(Simulate(1), options);
  ASSERT_TRUE(every.ok()) << every.status();
  const int maps = static_cast<int>(every->local_maps.size());
  EXPECT_EQ(every->report["estimator_counters"]["ceres_solves"].get<double>(), maps / 10 + 1);
  EXPECT_NEAR(every->errors->rms_position_m, ceres->errors->rms_position_m, 1e-6);
}

// The back-end alone on the recorded local maps: known association and JCBB agree with
// the truth ids (no two true landmarks merged), and the loop is closed.
TEST(SubmapPipeline, JoinOnRecordedSubmaps) {
  const io::Dataset d = Simulate(3);
  const std::vector<LocalSubmap> maps = EkfLocalMaps(d);
  ASSERT_FALSE(maps.empty());
  JoinOptions options;
  options.initial_pose = d.initial_pose;
  options.truth_poses = d.truth_poses;
  options.truth_landmarks = d.truth_landmarks;
  options.out_dir = ::testing::TempDir() + "/subslam_join";
  for (const bool known : {true, false}) {
    options.backend.eif.association.known_association = known;
    absl::StatusOr<JoinResult> j = RunJoin(maps, options);
    ASSERT_TRUE(j.ok()) << j.status();
    EXPECT_EQ(j->association.wrong, 0) << "known " << known;
    EXPECT_GT(j->association.loop_merged, 0) << "known " << known;
    if (known) {
      EXPECT_EQ(j->association.missed, 0);
      EXPECT_EQ(j->association.loop_missed, 0);
    }
    EXPECT_EQ(static_cast<int>(j->anchors.size()), j->local_maps + 1);
  }
  // And from the file a run writes.
  const std::string path = ::testing::TempDir() + "/subslam_join_input.jsonl";
  ASSERT_TRUE(io::WriteSubmapsJsonl(path, maps).ok());
  absl::StatusOr<std::vector<LocalSubmap>> back = io::ReadSubmapsJsonl(path);
  ASSERT_TRUE(back.ok());
  EXPECT_TRUE(RunJoin(*back, options).ok());
}

// Each join's summary: one per local map, in order, its counters' changes adding up to the
// joiner's totals before Finish (which adds only its own relinearisations and revisions),
// and joins.csv holds them.
TEST(SubmapPipeline, JoinSummariesAddUpToTheCounters) {
  const io::Dataset d = Simulate(3);
  const std::vector<LocalSubmap> maps = EkfLocalMaps(d);
  ASSERT_FALSE(maps.empty());
  JoinOptions options;
  options.initial_pose = d.initial_pose;
  options.out_dir = ::testing::TempDir() + "/subslam_join_summaries";
  absl::StatusOr<JoinResult> j = RunJoin(maps, options);
  ASSERT_TRUE(j.ok()) << j.status();
  ASSERT_EQ(j->joins.size(), maps.size());
  long new_landmarks = 0, associated = 0;
  for (size_t k = 0; k < maps.size(); ++k) {
    EXPECT_EQ(j->joins[k].map_id, maps[k].id);
    EXPECT_TRUE(j->joins[k].status.ok());
    EXPECT_EQ(j->joins[k].counts.joins, 1);
    EXPECT_EQ(j->joins[k].counts.associated + j->joins[k].counts.new_landmarks, maps[k].num_landmarks());
    new_landmarks += j->joins[k].counts.new_landmarks;
    associated += j->joins[k].counts.associated;
  }
  EXPECT_EQ(new_landmarks, j->report["counts"]["new_landmarks"].get<long>());
  EXPECT_EQ(associated, j->report["counts"]["associated_features"].get<long>());
  std::ifstream csv(options.out_dir + "/joins.csv");
  std::string line;
  int rows = 0;
  ASSERT_TRUE(std::getline(csv, line));
  EXPECT_EQ(line.rfind("map_id,seconds,maps,associated_features,new_landmarks", 0), 0u) << line;
  while (std::getline(csv, line)) ++rows;
  EXPECT_EQ(rows, static_cast<int>(maps.size()));
}

// The online anchors of a join (each as the join that made it left it): the last equals
// the final one (to rounding) when nothing is relinearised after it, the earlier ones were moved by
// later joins, and the report scores them against the truth.
TEST(SubmapPipeline, JoinRecordsEachAnchorAsItsJoinLeftIt) {
  const io::Dataset d = Simulate(3);
  const std::vector<LocalSubmap> maps = EkfLocalMaps(d);
  ASSERT_GE(maps.size(), 3u);
  JoinOptions options;
  options.initial_pose = d.initial_pose;
  options.truth_poses = d.truth_poses;
  options.backend.eif = options.backend.eif.SingleLinearization();
  absl::StatusOr<JoinResult> j = RunJoin(maps, options);
  ASSERT_TRUE(j.ok()) << j.status();
  ASSERT_EQ(j->anchors_online.size(), j->anchors.size());
  // (the end's exact solve in place of the last join's partial recovery: the same to rounding)
  EXPECT_LE((j->anchors_online.back().pose.vector() - j->anchors.back().pose.vector()).norm(),
            1e-9 * j->anchors.back().pose.vector().norm());
  // (its marginal recovered another way: the same to rounding)
  EXPECT_LE((j->anchors_online.back().covariance - j->anchors.back().covariance).norm(),
            1e-9 * j->anchors.back().covariance.norm());
  size_t moved = 0;
  for (size_t k = 0; k < j->anchors.size(); ++k) {
    EXPECT_EQ(j->anchors_online[k].t, j->anchors[k].t) << k;
    moved += (j->anchors_online[k].pose.vector() - j->anchors[k].pose.vector()).norm() > 1e-6;
  }
  EXPECT_GT(moved, j->anchors.size() / 2);  // the loop closure moved them
  EXPECT_TRUE(j->report["metrics"].contains("anchors_online"));
  EXPECT_EQ(j->report["metrics"]["anchors_online"]["steps"], j->report["metrics"]["anchors"]["steps"]);
}

// Every back-end on the same recorded local maps, with the same (JCBB) association
// options: none merges two true landmarks, each closes the loop, and the anchors pass the
// 10σ test; run online, the EKF and tree back-ends' trajectories do too.
TEST(SubmapPipeline, EveryBackendJoinsTheSameLocalMaps) {
  const io::Dataset d = Simulate(3);
  const std::vector<LocalSubmap> maps = EkfLocalMaps(d);
  ASSERT_FALSE(maps.empty());
  for (const Backend kind : {Backend::kEif, Backend::kCeres, Backend::kEkf, Backend::kTreeEkf, Backend::kTreeEif}) {
    JoinOptions options;
    options.initial_pose = d.initial_pose;
    options.truth_poses = d.truth_poses;
    options.backend.kind = kind;
    absl::StatusOr<JoinResult> j = RunJoin(maps, options);
    ASSERT_TRUE(j.ok()) << ToString(kind) << ": " << j.status();
    EXPECT_EQ(j->association.wrong, 0) << ToString(kind);
    EXPECT_GT(j->association.loop_merged, 0) << ToString(kind);
    EXPECT_EQ(static_cast<int>(j->anchors.size()), j->local_maps + 1) << ToString(kind);
    const eval::TrajectoryErrors e = eval::ComputeTrajectoryErrors(j->anchors, d.truth_poses);
    EXPECT_FALSE(e.failed) << ToString(kind);
    EXPECT_EQ(j->report["configuration"]["backend"], ToString(kind));
  }
  for (const Backend kind : {Backend::kEkf, Backend::kTreeEkf, Backend::kTreeEif}) {
    RunOptions options;
    options.frontend = Frontend::kEkfLocal;
    options.backend.kind = kind;
    absl::StatusOr<RunResult> r = RunPipeline(d, options);
    ASSERT_TRUE(r.ok()) << ToString(kind) << ": " << r.status();
    EXPECT_FALSE(r->errors->failed) << ToString(kind);
    EXPECT_FALSE(r->errors_online->failed) << ToString(kind);
    EXPECT_EQ(r->map_errors->spurious, 0) << ToString(kind);
  }
}

// Every back-end revises its association: with a join gate so strict that most
// re-observations become new landmarks, the merges take the copies back — the same local
// maps end with about the landmarks a default join finds, and no wrong merge.
TEST(SubmapPipeline, EveryBackendMergesTheCopiesOfAStrictJoinGate) {
  const io::Dataset d = Simulate(3);
  const std::vector<LocalSubmap> maps = EkfLocalMaps(d);
  JoinOptions reference_options;
  reference_options.initial_pose = d.initial_pose;
  absl::StatusOr<JoinResult> reference = RunJoin(maps, reference_options);
  ASSERT_TRUE(reference.ok()) << reference.status();
  const int landmarks = reference->report["counts"]["landmarks"].get<int>();
  for (const Backend kind : {Backend::kEif, Backend::kCeres, Backend::kEkf, Backend::kTreeEkf, Backend::kTreeEif}) {
    JoinOptions options;
    options.initial_pose = d.initial_pose;
    options.backend.kind = kind;
    options.backend.eif.association.gate_probability = 0.05;
    options.backend.ekf.association.gate_probability = 0.05;
    absl::StatusOr<JoinResult> j = RunJoin(maps, options);
    ASSERT_TRUE(j.ok()) << ToString(kind) << ": " << j.status();
    EXPECT_GT(j->report["counts"]["landmarks_merged"].get<int>(), landmarks / 2) << ToString(kind);
    EXPECT_LE(j->report["counts"]["landmarks"].get<int>(), landmarks * 11 / 10) << ToString(kind);
    EXPECT_EQ(j->association.wrong, 0) << ToString(kind);
  }
}

// The joined anchors are not over-confident: with known association and relinearisation,
// each anchor's NEES against the true pose at its time is below χ²₃(0.95) as often as a
// consistent estimate's would be — the count over runs is compared with
// Binomial(n, 0.95)'s 0.1% quantile. (They are conservative: mean NEES ≈ 1.4-2.3 on these
// EKF local maps; single-map EKF-SLAM on the same scenario is too, at 1.87.)
TEST(SubmapPipeline, JoinedAnchorsAreNotOverconfident) {
  int n = 0, inside = 0;
  for (uint64_t seed : {1, 2, 3}) {
    const io::Dataset d = Simulate(seed);
    JoinOptions options;
    options.initial_pose = d.initial_pose;
    options.backend.eif.association.known_association = true;
    options.backend.eif.relinearize_at_end = true;
    absl::StatusOr<JoinResult> j = RunJoin(EkfLocalMaps(d), options);
    ASSERT_TRUE(j.ok()) << j.status();
    for (size_t k = 1; k < j->anchors.size(); ++k) {
      const PoseEstimate& a = j->anchors[k];
      const std::optional<double> nees =
          eval::PoseNees(eval::InterpolatePose(d.truth_poses, a.t), a.pose, a.covariance);
      ASSERT_TRUE(nees.has_value());
      ++n;
      inside += *nees <= models::ChiSquareQuantile(0.95, 3) ? 1 : 0;
    }
  }
  ASSERT_GT(n, 100);
  const int bound = static_cast<int>(boost::math::quantile(boost::math::binomial(n, 0.95), 0.001));
  EXPECT_GE(inside, bound) << inside << " / " << n;
}

// The whole pipeline closes combined-2km's loop with unknown association in the front-end
// and the back-end, at the defaults. The EIF relinearises during the run (whenever a
// factor's linear model is off by more than its noise); without that (single
// linearisation) this seed's loop closes wrongly and ends at 257 m, worse than chaining
// the local maps (172 m). With it the final pose is many times closer to the truth than the chained
// local maps, consistent with its covariance, and the trajectory passes the 10σ test.
TEST(SubmapPipeline, Combined2kmUnknownAssociationClosesTheLoop) {
  const io::Dataset d = Simulate(3, "combined-2km");
  RunOptions options;
  options.frontend = Frontend::kRbpf;
  options.backend.kind = Backend::kNone;
  absl::StatusOr<RunResult> chained = RunPipeline(d, options);
  ASSERT_TRUE(chained.ok()) << chained.status();
  options.backend.kind = Backend::kEif;
  absl::StatusOr<RunResult> joined = RunPipeline(d, options);
  ASSERT_TRUE(joined.ok()) << joined.status();
  EXPECT_FALSE(joined->errors->failed);
  EXPECT_LT(joined->errors->final_position_error_m, chained->errors->final_position_error_m / 5);
  ASSERT_FALSE(joined->errors->nees.empty());
  EXPECT_LE(joined->errors->nees.back(), models::ChiSquareQuantile(0.999, 3))
      << "final error " << joined->errors->final_position_error_m << " m, chained "
      << chained->errors->final_position_error_m << " m";
}

// Combined SLAM §7's experiment: combined-2km (a 4 km loop, σ 0.5 m / 5°) with known
// association in the front-end and the back-end, RBPF local maps joined by the EIF and
// relinearised at the end. The loop closes: the final pose is far closer to the truth
// than the same local maps chained without a back-end, and consistent with its
// covariance (last step's NEES below χ²₃(0.999)); the whole trajectory passes the 10σ
// test; no local-map feature mixes two true landmarks, and no true landmark is mapped twice.
TEST(SubmapPipeline, Combined2kmKnownAssociationClosesTheLoop) {
  const io::Dataset d = Simulate(1, "combined-2km");
  RunOptions options;
  options.frontend = Frontend::kRbpf;
  options.fastslam.landmarks.known_association = true;
  options.backend.kind = Backend::kNone;
  absl::StatusOr<RunResult> chained = RunPipeline(d, options);
  ASSERT_TRUE(chained.ok()) << chained.status();
  options.backend.kind = Backend::kEif;
  options.backend.eif.association.known_association = true;
  options.backend.eif.relinearize_at_end = true;
  absl::StatusOr<RunResult> joined = RunPipeline(d, options);
  ASSERT_TRUE(joined.ok()) << joined.status();
  EXPECT_EQ(joined->impure_features, 0);
  // Each true landmark is one global landmark (evaluated by label, not by distance).
  ASSERT_TRUE(joined->labelled_map_errors.has_value());
  EXPECT_GT(joined->labelled_map_errors->true_landmarks, 300);
  EXPECT_EQ(joined->labelled_map_errors->duplicates, 0);
  // The run's association against the true ids, from its labelled local maps: every
  // re-observation joined to its landmark, nothing merged wrongly.
  ASSERT_TRUE(joined->association.has_value());
  EXPECT_EQ(joined->association->correct, joined->labelled_map_errors->true_landmarks);
  EXPECT_EQ(joined->association->missed, 0);
  EXPECT_EQ(joined->association->wrong, 0);
  EXPECT_EQ(joined->association->recent_missed + joined->association->loop_missed, 0);
  EXPECT_GT(joined->association->loop_merged, 0);
  EXPECT_FALSE(chained->association.has_value());  // nothing joined
  EXPECT_FALSE(joined->errors->failed);
  EXPECT_LT(joined->errors->final_position_error_m, chained->errors->final_position_error_m);
  ASSERT_FALSE(joined->errors->nees.empty());
  EXPECT_LE(joined->errors->nees.back(), models::ChiSquareQuantile(0.999, 3))
      << "final error " << joined->errors->final_position_error_m << " m, chained "
      << chained->errors->final_position_error_m << " m";
}

// In a room revisited all the time (the camera robot, true ids), the running tree's
// online pose chained over its nodes drifts between their joins; taken from the folded
// whole map it is the sequential EIF's (within 5 %), and well below the chain's.
TEST(SubmapPipeline, TheTreesOnlinePoseFromTheFoldedMapIsTheSequentialJoinersInARoom) {
  const io::Dataset d = SimulateCameraRobot(1, /*moving_objects=*/0, /*odometry_scale=*/1.0);
  const auto online_rms = [&](Backend kind, bool fold) {
    RunOptions options;
    options.frontend = Frontend::kRbpf;
    options.ekf.landmarks.known_association = options.fastslam.landmarks.known_association = true;
    options.backend.kind = kind;
    options.backend.tree.online_anchor_from_whole_map = fold;
    absl::StatusOr<RunResult> r = RunPipeline(d, options);
    EXPECT_TRUE(r.ok()) << r.status();
    return r->errors_online->rms_position_m;
  };
  const double sequential = online_rms(Backend::kEif, false);
  const double chained = online_rms(Backend::kTreeEif, false);
  const double folded = online_rms(Backend::kTreeEif, true);
  EXPECT_LT(folded, 1.05 * sequential) << "sequential " << sequential;
  EXPECT_LT(folded, 0.5 * chained) << "chained " << chained;
}

// Back-end names round-trip; a bad name, a bad option or a join without a back-end or
// without local maps is an error, not a crash.
TEST(BackendOptions, RejectsBadInput) {
  for (Backend b : {Backend::kNone, Backend::kEif, Backend::kCeres, Backend::kEkf, Backend::kTreeEkf, Backend::kTreeEif,
                    Backend::kTreeCeres}) {
    absl::StatusOr<Backend> parsed = BackendFromString(ToString(b));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, b);
  }
  const absl::StatusOr<Backend> bogus = BackendFromString("bogus");
  ASSERT_FALSE(bogus.ok());
  EXPECT_NE(bogus.status().message().find("tree-eif"), std::string::npos);
  BackendOptions o;
  o.ceres_every = -1;
  EXPECT_FALSE(o.Validate().ok());
  o.ceres_every = 0;
  o.ekf.association.recent_maps = -1;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.eif.relinearize_tolerance = 0.0;  // --relinearize_tolerance
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.eif.relinearize_step_chi2 = -1e-3;  // --relinearize_step_chi2
  EXPECT_FALSE(o.Validate().ok());
  o.eif.relinearize_step_chi2 = NAN;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.eif.association.loop_confirmation_maps = -1;  // --join_loop_confirmation_maps
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.eif.association.loop_confirmation_min_sigma_radius_m = NAN;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.eif.max_relinearizations = 0;  // --max_relinearizations
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.eif.divergence_rises = -1;  // --relinearize_max_rises
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.eif.relinearize_heading_change = -0.1;  // --relinearize_heading_change
  EXPECT_FALSE(o.Validate().ok());
  o.eif.relinearize_heading_change = NAN;
  EXPECT_FALSE(o.Validate().ok());
  o = {};
  o.eif.relinearize_linearization_chi2 = -1.0;  // --relinearize_linearization_chi2
  EXPECT_FALSE(o.Validate().ok());
  o.eif.relinearize_linearization_chi2 = NAN;
  EXPECT_FALSE(o.Validate().ok());

  const io::Dataset d = Simulate(1);
  JoinOptions join;
  join.initial_pose = d.initial_pose;
  EXPECT_FALSE(RunJoin({}, join).ok());  // no local maps
  join.backend.kind = Backend::kNone;
  EXPECT_FALSE(RunJoin(EkfLocalMaps(d), join).ok());
}

}  // namespace
}  // namespace subslam::pipeline
