// Failures reported, not hidden: each kind report.json's "health" counts is provoked here
// and checked in the report, the summary and (for a run that cannot go on) the partial
// outputs.
#include <gtest/gtest.h>

#include <boost/math/distributions/binomial.hpp>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>

#include "absl/strings/match.h"
#include "simulated_dataset.h"
#include "subslam/backend/eif_joiner.h"
#include "subslam/frontend/ekf_local_mapper.h"
#include "subslam/io/steps.h"
#include "subslam/models/unicycle_model.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/pipeline/submap_slam.h"
#include "subslam/sim/simulator.h"

namespace subslam::pipeline {
namespace {

namespace fs = std::filesystem;

int CountLines(const fs::path& path) {
  std::ifstream in(path);
  int n = 0;
  for (std::string line; std::getline(in, line);) ++n;
  return n;
}

nlohmann::json ReadJson(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

TEST(RunHealth, InputRulesAreAppliedAndCounted) {
  io::Dataset d = Simulate(1, "hybrid-120m", 60.0);
  const int k = static_cast<int>(d.controls.size()) / 2;
  d.controls[k].u[0] += 50.0 * (d.motion.noise.sigma_u0 + d.motion.noise.scale_u0 * std::abs(d.controls[k].u[0]));
  RunOptions options;
  options.frontend = Frontend::kEkfSlam;
  absl::StatusOr<RunResult> r = RunPipeline(d, options);
  ASSERT_TRUE(r.ok()) << r.status();
  const nlohmann::json& h = r->report["health"];
  EXPECT_TRUE(h["completed"].get<bool>());
  EXPECT_EQ(h["inputs"]["control_spikes_replaced"].get<int>(), 1);
  EXPECT_EQ(h["inputs"]["time_gaps"].get<int>(), 0);
  EXPECT_NE(SummaryTable(*r).find("inputs: spikes / gaps / repeated t 1 / 0"), std::string::npos) << SummaryTable(*r);
  // The repaired run equals the clean one.
  io::Dataset clean = Simulate(1, "hybrid-120m", 60.0);
  absl::StatusOr<RunResult> c = RunPipeline(clean, options);
  ASSERT_TRUE(c.ok());
  EXPECT_LT((c->online.back().pose.translation() - r->online.back().pose.translation()).norm(), 0.05);
}

// The windowed normalised innovation test: a consistent EKF-SLAM fails few windows (each
// window fails with probability below 0.001; windows overlap, so the count is compared
// with the binomial bound as if each window were a fresh trial, which only widens it by
// the overlap); told its bearings are 10× more precise than they are, it fails window
// after window.
TEST(RunHealth, InnovationTestPassesAConsistentFilterAndFlagsADivergingOne) {
  io::Dataset d = Simulate(1, "hybrid-120m", 200.0);
  RunOptions options;
  options.frontend = Frontend::kEkfSlam;
  options.ekf.landmarks.known_association = true;  // no gate: the test's χ² holds exactly
  absl::StatusOr<RunResult> good = RunPipeline(d, options);
  ASSERT_TRUE(good.ok()) << good.status();
  const nlohmann::json& g = good->report["health"]["divergence"];
  const double tested = g["windows_tested"].get<double>();
  ASSERT_GT(tested, 1000);
  const boost::math::binomial_distribution<double> null(tested / options.ekf.innovation_test.window_scans, 0.001);
  EXPECT_LE(g["windows_failed"].get<double>(),
            options.ekf.innovation_test.window_scans * boost::math::quantile(boost::math::complement(null, 0.001)));

  options.noise.sigma_bearing = d.sensor.range_bearing.sigma_bearing_rad / 10.0;
  options.noise.sigma_range = d.sensor.range_bearing.sigma_range_m / 10.0;
  absl::StatusOr<RunResult> bad = RunPipeline(d, options);
  ASSERT_TRUE(bad.ok()) << bad.status();
  const nlohmann::json& b = bad->report["health"]["divergence"];
  EXPECT_GT(b["windows_failed"].get<double>(), 0.5 * b["windows_tested"].get<double>());
  EXPECT_GE(b["episodes"].get<double>(), 1);
  EXPECT_NE(SummaryTable(*bad).find("innovation test: windows failed"), std::string::npos);
}

// The local maps against the map: the camera robot (no moving objects, 300 s) driving and
// turning at 0.8× what its odometry reports, not calibrated, makes local maps that
// disagree with the map where they are paired, window after window, and the run is
// flagged as diverged; the same robot with true odometry is not.
TEST(RunHealth, LocalMapsAgainstTheMapFlagAnUncalibratedOdometryScale) {
  const auto run = [](double odometry_scale) {
    const io::Dataset d = SimulateCameraRobot(2, /*moving_objects=*/0, odometry_scale);
    RunOptions options;
    options.frontend = Frontend::kRbpf;
    options.backend.kind = Backend::kEif;
    absl::StatusOr<RunResult> r = RunPipeline(d, options);
    EXPECT_TRUE(r.ok()) << r.status();
    return *std::move(r);
  };
  const RunResult calibrated = run(1.0);
  const nlohmann::json& g = calibrated.report["health"]["local_maps_against_the_map"];
  EXPECT_FALSE(g["diverged"].get<bool>()) << g.dump();
  EXPECT_GT(g["dof"].get<double>(), 50);
  const RunResult biased = run(0.8);
  const nlohmann::json& b = biased.report["health"]["local_maps_against_the_map"];
  EXPECT_TRUE(b["diverged"].get<bool>()) << b.dump();
  EXPECT_NE(SummaryTable(biased).find("local maps against the map         DIVERGED"), std::string::npos)
      << SummaryTable(biased);
}

// The map against its own scans: on a world without clutter every landmark of a good run
// is confirmed, and the detection curve reads near the simulator's certain detection; on
// the camera robot, whose moving robots leave features where nothing stands, some are not,
// and --drop_unconfirmed_landmarks takes exactly those out of the map (and the report says
// how many).
TEST(RunHealth, TheMapIsConfirmedAgainstItsOwnScans) {
  const io::Dataset clean = Simulate(1, "hybrid-120m", 60.0);
  RunOptions options;
  options.frontend = Frontend::kRbpf;
  options.backend.kind = Backend::kEif;
  absl::StatusOr<RunResult> good = RunPipeline(clean, options);
  ASSERT_TRUE(good.ok()) << good.status();
  const nlohmann::json& g = good->report["health"]["map_confirmation"];
  EXPECT_EQ(g["confirmed"].get<int>(), static_cast<int>(good->landmarks.size())) << g.dump();
  ASSERT_FALSE(g["detection_probability_by_range"].empty());
  EXPECT_GT(g["detection_probability_by_range"][0]["probability"].get<double>(), 0.9);
  EXPECT_NE(SummaryTable(*good).find("map confirmed by the scans"), std::string::npos);

  const io::Dataset movers = SimulateCameraRobot(2);
  absl::StatusOr<RunResult> kept = RunPipeline(movers, options);
  ASSERT_TRUE(kept.ok()) << kept.status();
  const backend::LandmarkPersistence& c = *kept->map_confirmation;
  ASSERT_LT(c.num_confirmed, static_cast<int>(kept->landmarks.size()));
  options.map_confirmation.drop_unconfirmed = true;
  absl::StatusOr<RunResult> dropped = RunPipeline(movers, options);
  ASSERT_TRUE(dropped.ok()) << dropped.status();
  EXPECT_EQ(dropped->landmarks.size(), static_cast<size_t>(c.num_confirmed));
  EXPECT_EQ(dropped->unconfirmed_dropped, static_cast<int>(kept->landmarks.size()) - c.num_confirmed);
  EXPECT_EQ(dropped->report["health"]["map_confirmation"]["unconfirmed_dropped"].get<int>(),
            dropped->unconfirmed_dropped);
  for (size_t i = 0, k = 0; i < kept->landmarks.size(); ++i) {
    if (!c.confirmed[i]) continue;
    EXPECT_EQ(dropped->landmarks[k].position, kept->landmarks[i].position) << i;
    ++k;
  }
}

// Particle depletion: with an over-confident sensor model a few particles take the
// weight at every scan (ESS collapses, lineages die out); the particle filter's counters
// say so, and a well-matched model shows far less.
TEST(RunHealth, ParticleDepletionIsCounted) {
  io::Dataset d = Simulate(1, "hybrid-120m", 60.0);
  RunOptions options;
  options.frontend = Frontend::kFastSlam;
  options.fastslam.num_particles = 50;
  absl::StatusOr<RunResult> good = RunPipeline(d, options);
  ASSERT_TRUE(good.ok()) << good.status();
  options.noise.sigma_bearing = d.sensor.range_bearing.sigma_bearing_rad / 20.0;
  options.noise.sigma_range = d.sensor.range_bearing.sigma_range_m / 20.0;
  absl::StatusOr<RunResult> bad = RunPipeline(d, options);
  ASSERT_TRUE(bad.ok()) << bad.status();
  const nlohmann::json& g = good->report["health"]["particles"];
  const nlohmann::json& b = bad->report["health"]["particles"];
  EXPECT_GT(b["depleted_updates"].get<double>(), 10 * std::max(1.0, g["depleted_updates"].get<double>()));
  EXPECT_LT(b["min_ess_ratio"].get<double>(), g["min_ess_ratio"].get<double>());
  EXPECT_GE(b["lineage_collapses"].get<double>(), 1);
  EXPECT_EQ(b["weight_collapses"].get<double>(), 0);
  EXPECT_NE(SummaryTable(*bad).find("particles: min ESS / depleted"), std::string::npos);
}

// A run that cannot go on: from the middle of the run the speed is 1e300 m/s (a step,
// not a spike, so the input rules keep it), the covariance overflows, and the run stops
// with the outputs written up to the last good step and the report saying so.
TEST(RunHealth, ANonFiniteEstimateStopsTheRunWithPartialOutputs) {
  io::Dataset d = Simulate(1, "hybrid-120m", 30.0);
  const size_t half = d.controls.size() / 2;
  for (size_t k = half; k < d.controls.size(); ++k) d.controls[k].u[0] = 1e300;
  const fs::path out = fs::path(::testing::TempDir()) / "subslam_run_health_stop";
  fs::remove_all(out);
  for (Frontend frontend : {Frontend::kEkfSlam, Frontend::kRbpf}) {
    RunOptions options;
    options.frontend = frontend;
    options.backend.kind = Backend::kEif;
    options.out_dir = out.string();
    absl::StatusOr<RunResult> r = RunPipeline(d, options);
    ASSERT_TRUE(r.ok()) << r.status();
    ASSERT_TRUE(r->stop.has_value()) << ToString(frontend);
    EXPECT_EQ(r->stop->cause, RunStop::Cause::kNonFiniteEstimate);
    EXPECT_NEAR(r->stop->t, d.controls[half].t, 0.5) << ToString(frontend);
    EXPECT_EQ(static_cast<int>(r->online.size()), r->stop->step);
    for (const PoseEstimate& p : r->online) ASSERT_TRUE(p.pose.vector().allFinite() && p.covariance.allFinite());
    for (const LandmarkEstimate& l : r->landmarks) ASSERT_TRUE(l.position.allFinite());
    EXPECT_GT(r->landmarks.size(), 0u);
    const nlohmann::json report = ReadJson(out / "report.json");
    EXPECT_FALSE(report["health"]["completed"].get<bool>());
    EXPECT_EQ(report["health"]["stopped"]["cause"], "non_finite_estimate");
    EXPECT_EQ(report["health"]["stopped"]["step"].get<int>(), r->stop->step);
    EXPECT_EQ(CountLines(out / "trajectory_online.csv"), 1 + r->stop->step);  // a header line
    EXPECT_GT(CountLines(out / "landmarks.csv"), 1);
    EXPECT_NE(SummaryTable(*r).find("STOPPED"), std::string::npos);
  }
}

// A joiner that fails its third join (or, with `fail_at_finish`, its Finish()), as a
// numerical failure would.
class FailingJoiner final : public backend::MapJoiner {
 public:
  explicit FailingJoiner(const Pose2& start, bool fail_at_finish = false)
      : inner_(start, backend::EifJoinerOptions{}), fail_at_finish_(fail_at_finish) {}
  std::string Name() const override { return "failing"; }
  absl::Status Finish() override {
    if (fail_at_finish_) return absl::InternalError("CHOLMOD: the matrix is not positive definite (provoked)");
    return inner_.Finish();
  }
  const SubmapGraph& graph() const override { return inner_.graph(); }
  Eigen::MatrixXd JointCovariance(const std::vector<int>& a, const std::vector<int>& l) const override {
    return inner_.JointCovariance(a, l);
  }
  const std::vector<int>& last_association() const override { return inner_.last_association(); }
  std::map<std::string, double> stage_times() const override { return inner_.stage_times(); }
  const backend::JoinerCounters& counters() const override { return inner_.counters(); }
  const association::SubmapAssociator& associator() const override { return inner_.associator(); }

 protected:
  absl::Status JoinLocalMap(const LocalSubmap& s) override {
    if (++joins_ == 3 && !fail_at_finish_) return absl::InternalError("factorisation failed (provoked)");
    return inner_.Join(s);
  }

 private:
  backend::EifJoiner inner_;
  bool fail_at_finish_ = false;
  int joins_ = 0;
};

// An EKF local mapper (5 s maps) chained by a FailingJoiner, driven over the whole data set;
// `on_step` sees the chain after each step.
std::unique_ptr<SubmapSlam> DriveWithFailingJoiner(const io::Dataset& d, bool fail_at_finish, bool background,
                                                   const std::function<void(const SubmapSlam&)>& on_step) {
  frontend::SubmapPolicyOptions policy;
  policy.max_duration_s = 5.0;
  auto mapper = std::make_unique<frontend::EkfLocalMapper>(d.motion.MakeModel(), d.sensor.range_bearing,
                                                           frontend::EkfSlamOptions{}, policy, 0.0, 0.5);
  auto slam = std::make_unique<SubmapSlam>(std::move(mapper), d.initial_pose,
                                           std::make_unique<FailingJoiner>(d.initial_pose, fail_at_finish), background);
  for (const io::Step& step : io::BuildSteps(d)) {
    slam->Predict(step.control, step.dt);
    if (step.scan_index >= 0) {
      // Update reports the failed join once it is known (at once when joining in it).
      const absl::Status updated = slam->Update(d.scans[step.scan_index]);
      if (!updated.ok()) EXPECT_TRUE(slam->join_failed()) << updated;
      if (!background) EXPECT_EQ(updated.ok(), !slam->join_failed());
      if (!updated.ok()) EXPECT_TRUE(absl::StrContains(updated.message(), "local map")) << updated;
    }
    slam->RecordStep(step.t);
    on_step(*slam);
  }
  return slam;
}

// A failed join stops the joining: nothing more is joined, the online pose goes on, the
// final trajectory ends with the last local map that has a start anchor, and Finish()
// names the map and the error — in the background and synchronously alike.
TEST(RunHealth, AFailedJoinStopsJoiningAndKeepsWhatWasJoined) {
  const io::Dataset d = Simulate(1, "hybrid-120m", 60.0);
  for (bool background : {false, true}) {
    bool failed_seen = false;
    const std::unique_ptr<SubmapSlam> chain =
        DriveWithFailingJoiner(d, /*fail_at_finish=*/false, background,
                               [&](const SubmapSlam& s) { failed_seen = failed_seen || s.join_failed(); });
    SubmapSlam& slam = *chain;
    const absl::Status st = slam.Finish();
    EXPECT_TRUE(slam.join_failed());
    EXPECT_FALSE(slam.export_failed());
    EXPECT_TRUE(failed_seen || background);  // a background failure may land after the last step
    ASSERT_FALSE(st.ok());
    EXPECT_NE(st.message().find("local map 2"), std::string::npos) << st;
    EXPECT_NE(st.message().find("provoked"), std::string::npos) << st;
    EXPECT_EQ(slam.joiner()->num_anchors(), 3);  // maps 0 and 1 joined
    EXPECT_EQ(slam.joins().size(), 2u);
    const Trajectory final_trajectory = slam.FinalTrajectory();
    ASSERT_FALSE(final_trajectory.empty());
    EXPECT_LE(final_trajectory.back().t, slam.local_maps()[2].submap.t_end + 1e-9);
    EXPECT_GT(final_trajectory.back().t, slam.local_maps()[1].submap.t_end);
    EXPECT_TRUE(slam.pose().vector().allFinite());
  }
}

// The joiner's own last work (Gauss-Newton, the final revision passes) failing is a failed
// join too: its estimate is not used (the run's final trajectory is then the online one).
TEST(RunHealth, AFailureAtTheJoinersFinishIsAFailedJoin) {
  const io::Dataset d = Simulate(1, "hybrid-120m", 30.0);
  for (bool background : {false, true}) {
    const std::unique_ptr<SubmapSlam> chain = DriveWithFailingJoiner(
        d, /*fail_at_finish=*/true, background, [](const SubmapSlam& s) { EXPECT_FALSE(s.join_failed()); });
    SubmapSlam& slam = *chain;
    const absl::Status st = slam.Finish();
    ASSERT_FALSE(st.ok());
    EXPECT_TRUE(slam.join_failed());
    EXPECT_NE(st.message().find("finishing the joins"), std::string::npos) << st;
    EXPECT_NE(st.message().find("provoked"), std::string::npos) << st;
    EXPECT_GE(slam.joins().size(), 5u);  // every map was joined before
  }
}

}  // namespace
}  // namespace subslam::pipeline
