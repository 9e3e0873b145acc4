#include "subslam/frontend/internal/worker_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <vector>

namespace subslam::frontend {
namespace {

// Every run calls the body once per index and returns only after all of them: over many
// back-to-back runs and after pauses (the scheduler's workers asleep).
TEST(WorkerPool, RunsEachThreadIndexOncePerRun) {
  for (int threads : {1, 2, 3}) {
    WorkerPool pool(threads);
    ASSERT_EQ(pool.threads(), threads);
    std::vector<std::atomic<int>> calls(threads);
    for (int run = 0; run < 1000; ++run) {
      pool.Run([&](int t) { calls[t].fetch_add(1, std::memory_order_relaxed); });
      for (int t = 0; t < threads; ++t) ASSERT_EQ(calls[t].load(), run + 1) << "thread " << t;
      if (run % 250 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }
}

// A body shares work through an atomic counter, and no two calls with one index overlap.
TEST(WorkerPool, SharesWorkThroughACounter) {
  WorkerPool pool(3);
  std::vector<int> owner(1000, -1);
  std::atomic<int> next{0};
  std::vector<std::atomic<int>> inside(3);
  std::atomic<bool> overlap{false};
  pool.Run([&](int t) {
    if (inside[t].fetch_add(1) != 0) overlap = true;
    for (int i = next.fetch_add(1); i < 1000; i = next.fetch_add(1)) owner[i] = t;
    inside[t].fetch_sub(1);
  });
  EXPECT_FALSE(overlap);
  for (int i = 0; i < 1000; ++i) EXPECT_GE(owner[i], 0) << i;
}

// Run(body, active) calls the body for the first `active` indices only (0 or more than
// threads(): all), so a caller can leave cores to other threads between runs.
TEST(WorkerPool, RunsOnlyTheActiveThreadIndices) {
  WorkerPool pool(3);
  for (int run = 0; run < 300; ++run) {
    const int active = run % 5;  // 0 (all), 1, 2, 3, 4 (all)
    std::vector<std::atomic<int>> calls(3);
    pool.Run([&](int t) { calls[t].fetch_add(1, std::memory_order_relaxed); }, active);
    const int expected = active == 0 || active > 3 ? 3 : active;
    ASSERT_EQ(pool.Active(active), expected) << "run " << run;
    for (int t = 0; t < 3; ++t) ASSERT_EQ(calls[t].load(), t < expected ? 1 : 0) << "run " << run << ", thread " << t;
  }
}

}  // namespace
}  // namespace subslam::frontend
