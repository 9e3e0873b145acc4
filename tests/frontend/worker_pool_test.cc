#include "subslam/frontend/internal/worker_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <vector>

namespace subslam::frontend {
namespace {

// Every run calls the body once per thread index, the caller's included, and returns only
// after all of them: over many back-to-back runs (workers spinning) and after pauses
// longer than the spin (workers asleep).
TEST(WorkerPool, RunsEachThreadIndexOncePerRun) {
  for (int threads : {1, 2, 3}) {
    for (auto spin : {std::chrono::microseconds(0), std::chrono::microseconds(500)}) {
      WorkerPool pool(threads, spin);
      ASSERT_EQ(pool.threads(), threads);
      std::vector<std::atomic<int>> calls(threads);
      for (int run = 0; run < 1000; ++run) {
        pool.Run([&](int t) { calls[t].fetch_add(1, std::memory_order_relaxed); });
        for (int t = 0; t < threads; ++t) ASSERT_EQ(calls[t].load(), run + 1) << "thread " << t;
        if (run % 250 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
    }
  }
}

// The caller's thread runs index 0; a body can share work through an atomic counter.
TEST(WorkerPool, SharesWorkThroughACounter) {
  WorkerPool pool(3);
  std::vector<int> owner(1000, -1);
  std::atomic<int> next{0};
  const std::thread::id caller = std::this_thread::get_id();
  bool zero_on_caller = false;
  pool.Run([&](int t) {
    if (t == 0) zero_on_caller = std::this_thread::get_id() == caller;
    for (int i = next.fetch_add(1); i < 1000; i = next.fetch_add(1)) owner[i] = t;
  });
  EXPECT_TRUE(zero_on_caller);
  for (int i = 0; i < 1000; ++i) EXPECT_GE(owner[i], 0) << i;
}

// Run(body, active) calls the body for the first `active` thread indices only (0 or more
// than threads(): all), so a caller can leave cores to other threads between runs.
TEST(WorkerPool, RunsOnlyTheActiveThreadIndices) {
  WorkerPool pool(3);
  for (int run = 0; run < 300; ++run) {
    const int active = run % 5;  // 0 (all), 1, 2, 3, 4 (all)
    std::vector<std::atomic<int>> calls(3);
    pool.Run([&](int t) { calls[t].fetch_add(1, std::memory_order_relaxed); }, active);
    const int expected = active == 0 || active > 3 ? 3 : active;
    for (int t = 0; t < 3; ++t) ASSERT_EQ(calls[t].load(), t < expected ? 1 : 0) << "run " << run << ", thread " << t;
  }
}

}  // namespace
}  // namespace subslam::frontend
