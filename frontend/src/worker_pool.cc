#include "subslam/frontend/internal/worker_pool.h"

#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/partitioner.h>

#include <algorithm>
#include <thread>
#include <vector>

#include "subslam/core/check.h"

#if defined(__SANITIZE_THREAD__)
#define SUBSLAM_THREAD_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define SUBSLAM_THREAD_SANITIZER 1
#endif
#endif

namespace subslam::frontend {

WorkerPool::WorkerPool(int threads) : threads_(threads), arena_(std::max(threads, 1)) {
  SUBSLAM_CHECK(threads >= 1) << "a worker pool needs at least one thread";
}

void WorkerPool::Run(const std::function<void(int)>& body, int active) {
  active = Active(active);
  if (active == 1) {
    body(0);
    return;
  }
#if defined(SUBSLAM_THREAD_SANITIZER)
  // Under ThreadSanitizer: one plain thread per index. libtbb is not instrumented, so TSan
  // cannot see its scheduler hand the bodies their data and would report every handoff;
  // with threads it sees the fork and the join, and reports the races of the bodies.
  std::vector<std::thread> threads;
  for (int t = 1; t < active; ++t) threads.emplace_back(body, t);
  body(0);
  for (std::thread& thread : threads) thread.join();
#else
  // Each index offered to the thread that ran it in the previous Run() (oneTBB's
  // affinity_partitioner, best effort; no thread is pinned), so that a body that gives
  // index t the same data every run tends to find it in that thread's cache.
  arena_.execute([&] {
    oneapi::tbb::parallel_for(
        0, active, 1, [&](int t) { body(t); }, affinity_);
  });
#endif
}

}  // namespace subslam::frontend
