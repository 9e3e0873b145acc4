// What a navigation stack that links the library can count on, whatever the tool does:
// no thread of the library's own unless asked for.
#include <gtest/gtest.h>

#include <filesystem>
#include <memory>

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
      if (step.scan_index >= 0) (*slam)->Update(d.scans[step.scan_index]);
    }
    auto* chain = dynamic_cast<SubmapSlam*>(slam->get());
    ASSERT_NE(chain, nullptr);
    EXPECT_GE(chain->local_maps().size(), 2u);
    EXPECT_EQ(ThreadsOfThisProcess(), before + (background ? 1 : 0)) << "background " << background;
    EXPECT_TRUE(chain->Finish().ok());
  }
}

}  // namespace
}  // namespace subslam::pipeline
