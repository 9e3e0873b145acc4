// Runs one function in parallel, fork-join style, on oneTBB's scheduler: Run(body) calls
// body(t) once for every t in [0, threads()) and returns when every call has returned.
// The body shares out its work (e.g. by an atomic counter); t indexes per-thread scratch,
// and no two calls with the same t run at once. Calls may run one after another on one
// thread (when the others are busy elsewhere), so a body must not wait for another.
// Internal, not part of the API.
//
// The calls run in a task arena of threads() slots on TBB's shared workers, which sleep
// when there is no work instead of spinning — a filter beside other busy processes keeps
// its speed, and idle workers cost no CPU. Each index is offered to the thread that ran
// it the time before (best effort), so per-index data tends to stay in one core's cache.
// Run() must not be called concurrently or from inside a body.
#ifndef SUBSLAM_FRONTEND_INTERNAL_WORKER_POOL_H_
#define SUBSLAM_FRONTEND_INTERNAL_WORKER_POOL_H_

#include <oneapi/tbb/partitioner.h>
#include <oneapi/tbb/task_arena.h>

#include <functional>

namespace subslam::frontend {

class WorkerPool {
 public:
  // threads ≥ 1: at most this many calls run at once.
  explicit WorkerPool(int threads);
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return threads_; }
  // How many indices Run(body, active) calls: active if in [1, threads()], else threads().
  int Active(int active) const { return active > 0 && active < threads_ ? active : threads_; }
  // body(t) for t in [0, active) (0 or more than threads(): every t); with one active
  // index the body runs on the calling thread alone.
  void Run(const std::function<void(int t)>& body, int active = 0);

 private:
  int threads_;
  oneapi::tbb::task_arena arena_;
  oneapi::tbb::affinity_partitioner affinity_;
};

}  // namespace subslam::frontend

#endif  // SUBSLAM_FRONTEND_INTERNAL_WORKER_POOL_H_
