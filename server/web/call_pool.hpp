// CallPool, private to server/web: the threads of the blocking gRPC calls of the unary routes
// (its members: call_pool.cpp).
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace geotraj::server::web_detail {

// The threads that make the blocking gRPC calls of the unary routes, off the I/O threads,
// with a bounded queue: a call beyond it is refused (503) rather than queued without end.
class CallPool {
 public:
  CallPool(std::size_t threads, std::size_t queued);
  ~CallPool() { shutdown(); }
  CallPool(const CallPool&) = delete;
  CallPool& operator=(const CallPool&) = delete;

  // False when every thread is busy and the queue is full, or the pool is stopping: the
  // caller refuses the call. A job handed to an idle thread that has not yet taken it
  // counts as that thread's, not the queue's.
  bool submit(std::function<void()> job);

  // Lets the running jobs end, drops the queued ones, joins.
  void shutdown();

 private:
  void work();

  const std::size_t capacity_;  // threads + queued calls
  std::size_t running_ = 0;     // jobs a thread has taken and not finished
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::function<void()>> jobs_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace geotraj::server::web_detail
