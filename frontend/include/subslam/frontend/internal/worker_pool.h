// A fixed set of threads that run one function in parallel, fork-join style: Run(body)
// calls body(t) once for every t in [0, threads()) — t = 0 on the calling thread, the
// others on persistent workers — and returns when every call has returned. The body
// shares out its work (e.g. by an atomic counter); t indexes per-thread scratch.
// Internal, not part of the API.
//
// Runs come every few hundred microseconds in a filter (one per scan), where a sleeping
// worker's wake-up costs as much as the work: a worker therefore spins for up to
// `spin` after a run (and the caller for the workers' completion) before it sleeps on a
// condition variable. Run() must not be called concurrently or from inside a body.
#ifndef SUBSLAM_FRONTEND_INTERNAL_WORKER_POOL_H_
#define SUBSLAM_FRONTEND_INTERNAL_WORKER_POOL_H_

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace subslam::frontend {

class WorkerPool {
 public:
  // threads ≥ 1: the calling thread plus threads − 1 workers.
  explicit WorkerPool(int threads, std::chrono::microseconds spin = std::chrono::microseconds(500));
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }
  // body(t) for t in [0, active) (0 or more than threads(): every thread); with one
  // active thread the workers are not woken, and a worker that sits a run out sleeps
  // until the next instead of spinning (its core is meant for another thread).
  void Run(const std::function<void(int t)>& body, int active = 0);

 private:
  void Work(int t);
  // Spins until done() or `spin_` has passed; true if done() came true.
  template <typename Done>
  bool SpinUntil(Done done) const;

  std::vector<std::thread> workers_;
  std::chrono::microseconds spin_;
  std::mutex mutex_;
  std::condition_variable start_, finished_;
  const std::function<void(int)>* body_ = nullptr;  // written before generation_ moves
  int active_ = 0;                                   // likewise
  std::atomic<long> generation_{0};                 // changed under mutex_
  std::atomic<int> pending_{0};                     // workers still in the current run
  bool stop_ = false;                               // guarded by mutex_
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_INTERNAL_WORKER_POOL_H_
