// The threads that do the service's long work (plans, optimisations, analyses, the planning
// of a stream), off gRPC's own threads: those keep answering health checks, accepting calls
// and pacing real-time streams however many long calls are in flight.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace geotraj::server {

/// Lowers the calling thread's CPU priority to `nice` (nothing when `nice` <= 0).
void lower_priority(int nice);

/// A fixed set of threads taking tasks in order, the urgent queue first. The queue is not
/// bounded here: the callers admit work against their caps (Call, runtime.hpp) before they
/// submit it, so the queue holds at most the calls admitted. The workers run at a lower CPU
/// priority (nice +10) than the rest of the process, so that a machine full of plans still
/// schedules gRPC's threads (health, stream writes) at once.
class WorkerPool {
 public:
  /// The workers' CPU priority (nice): below the rest of the process.
  static constexpr int kWorkerNice = 10;

  /// Starts `threads` workers (at least one) for any task, and `urgent_threads` more that
  /// take urgent tasks only, so that an urgent task (the planning of a stream) never waits
  /// behind normal ones (long unary plans); each at the CPU priority `nice` (the live
  /// calls' pacing threads take 0, the priority of gRPC's threads).
  explicit WorkerPool(int threads, int urgent_threads = 1, int nice = kWorkerNice);
  /// Runs what is queued, then joins the workers.
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  enum class Priority { kNormal, kUrgent };
  /// Queues `task`; a worker runs it. Tasks must not throw (an escaping exception ends the
  /// process, as on any thread).
  void submit(std::function<void()> task, Priority priority = Priority::kNormal);

  int threads() const { return static_cast<int>(threads_.size()); }  ///< both kinds
  /// Tasks waiting for a worker.
  std::size_t queued() const;
  /// Tasks running now.
  int busy() const;

 private:
  void run(bool urgent_only, int nice);

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> urgent_;
  std::deque<std::function<void()>> normal_;
  int busy_ = 0;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace geotraj::server
