#include "subslam/frontend/internal/worker_pool.h"

#include <algorithm>

#include "subslam/graph/check.h"

namespace subslam::frontend {

WorkerPool::WorkerPool(int threads, std::chrono::microseconds spin) : spin_(spin) {
  SUBSLAM_CHECK(threads >= 1) << "a worker pool needs at least one thread";
  workers_.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) workers_.emplace_back([this, t] { Work(t); });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
    generation_.fetch_add(1, std::memory_order_release);
  }
  start_.notify_all();
  for (std::thread& w : workers_) w.join();
}

template <typename Done>
bool WorkerPool::SpinUntil(Done done) const {
  const auto deadline = std::chrono::steady_clock::now() + spin_;
  while (!done()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
  }
  return true;
}

void WorkerPool::Run(const std::function<void(int)>& body, int active) {
  active = active > 0 ? std::min(active, threads()) : threads();
  if (active == 1) {
    body(0);
    return;
  }
  body_ = &body;
  active_ = active;
  pending_.store(static_cast<int>(workers_.size()), std::memory_order_relaxed);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    generation_.fetch_add(1, std::memory_order_release);  // publishes body_ and pending_
  }
  start_.notify_all();
  body(0);
  const auto all_done = [this] { return pending_.load(std::memory_order_acquire) == 0; };
  if (!SpinUntil(all_done)) {
    std::unique_lock<std::mutex> lock(mutex_);
    finished_.wait(lock, all_done);
  }
  body_ = nullptr;
}

void WorkerPool::Work(int t) {
  long seen = 0;
  bool spin = true;  // not after a run it sat out: its core is meant for another thread
  while (true) {
    const auto started = [&] { return generation_.load(std::memory_order_acquire) != seen; };
    if (!spin || !SpinUntil(started)) {
      std::unique_lock<std::mutex> lock(mutex_);
      start_.wait(lock, started);
    }
    seen = generation_.load(std::memory_order_acquire);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stop_) return;
    }
    spin = t < active_;
    if (spin) (*body_)(t);
    if (pending_.fetch_sub(1, std::memory_order_acq_rel) == 1) {
      std::lock_guard<std::mutex> lock(mutex_);  // the caller may be between test and wait
      finished_.notify_one();
    }
  }
}

}  // namespace subslam::frontend
