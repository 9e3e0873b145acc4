// What a navigation stack that links the library can count on, whatever the tool does:
// no thread of the library's own unless asked for, and a scan it filled badly refused
// with an error instead of used.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <memory>

#include "absl/strings/match.h"
#include "simulated_dataset.h"
#include "subslam/io/steps.h"
#include "subslam/pipeline/run_pipeline.h"
#include "subslam/pipeline/submap_slam.h"

namespace subslam::pipeline {
namespace {

// The threads of this process (Linux: its tasks).
int ThreadsOfThisProcess() {
  int n = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator("/proc/self/task")) ++n;
  return n;
}

// A library caller's SubmapSlam at the default options starts no thread of its own: the
// RBPF updates its particles on the calling thread and each closed map is joined inside
// the Update() that closed it; asked for background joins, it starts one joining thread.
TEST(LibraryContract, NoThreadUnlessAsked) {
  const io::Dataset d = Simulate(2, "hybrid-120m", 20.0);
  RunOptions options;
  options.frontend = Frontend::kRbpf;
  ASSERT_EQ(options.backend.kind, Backend::kEif);
  for (bool background : {false, true}) {
    options.backend.background = background;
    const int before = ThreadsOfThisProcess();
    absl::StatusOr<std::unique_ptr<frontend::OnlineEstimator>> slam = MakeOnlineEstimator(d, options);
    ASSERT_TRUE(slam.ok()) << slam.status();
    for (const io::Step& step : io::BuildSteps(d)) {
      (*slam)->Predict(step.control, step.dt);
      if (step.scan_index >= 0) EXPECT_TRUE((*slam)->Update(d.scans[step.scan_index]).ok());
    }
    auto* chain = dynamic_cast<SubmapSlam*>(slam->get());
    ASSERT_NE(chain, nullptr);
    EXPECT_GE(chain->local_maps().size(), 2u);
    EXPECT_EQ(ThreadsOfThisProcess(), before + (background ? 1 : 0)) << "background " << background;
    EXPECT_TRUE(chain->Finish().ok());
  }
}

// A scan a caller filled badly (a NaN range, a bearing at infinity, a zero range) is refused
// by every estimator with an error naming the detection, and changes nothing: the pose,
// its covariance and the map stay as they were, and the next good scan is taken.
TEST(LibraryContract, AMalformedScanIsRefusedAndChangesNothing) {
  const io::Dataset d = Simulate(4, "hybrid-120m", 15.0);
  for (Frontend frontend : {Frontend::kOdometry, Frontend::kEkfSlam, Frontend::kFastSlam, Frontend::kRbpf,
                            Frontend::kEkfLocal, Frontend::kSeif}) {
    RunOptions options;
    options.frontend = frontend;
    absl::StatusOr<std::unique_ptr<frontend::OnlineEstimator>> made = MakeOnlineEstimator(d, options);
    ASSERT_TRUE(made.ok()) << made.status();
    frontend::OnlineEstimator& estimator = **made;
    const Scan* last_good = nullptr;
    for (const io::Step& step : io::BuildSteps(d)) {
      estimator.Predict(step.control, step.dt);
      if (step.scan_index < 0) continue;
      last_good = &d.scans[step.scan_index];
      ASSERT_TRUE(estimator.Update(*last_good).ok()) << ToString(frontend);
    }
    ASSERT_NE(last_good, nullptr);
    const Pose2 pose = estimator.pose();
    const Eigen::Matrix3d covariance = estimator.pose_covariance();
    const size_t landmarks = estimator.Map().size();
    for (const Detection& bad :
         {Detection{.range_m = NAN, .bearing_rad = 0.1}, Detection{.range_m = 5.0, .bearing_rad = INFINITY},
          Detection{.range_m = 0.0, .bearing_rad = 0.1}}) {
      Scan scan = *last_good;
      scan.detections.insert(scan.detections.begin() + std::min<size_t>(1, scan.detections.size()), bad);
      const absl::Status refused = estimator.Update(scan);
      EXPECT_EQ(refused.code(), absl::StatusCode::kInvalidArgument) << ToString(frontend);
      EXPECT_TRUE(absl::StrContains(refused.message(), "detection")) << refused;
      EXPECT_EQ(estimator.pose().vector(), pose.vector()) << ToString(frontend);
      EXPECT_EQ(estimator.pose_covariance(), covariance) << ToString(frontend);
      EXPECT_EQ(estimator.Map().size(), landmarks) << ToString(frontend);
    }
    EXPECT_TRUE(estimator.Update(*last_good).ok()) << ToString(frontend);
  }
}

}  // namespace
}  // namespace subslam::pipeline
