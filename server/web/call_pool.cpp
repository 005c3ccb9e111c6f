// CallPool's members (call_pool.hpp): a bounded queue of the unary routes' calls and the
// threads that make them.
#include "server/web/call_pool.hpp"

#include <utility>

#include "server/ops/worker_pool.hpp"

namespace geotraj::server::web_detail {

CallPool::CallPool(std::size_t threads, std::size_t queued) : capacity_(threads + queued) {
  for (std::size_t k = 0; k < threads; ++k) threads_.emplace_back([this] { work(); });
}

bool CallPool::submit(std::function<void()> job) {
  {
    const std::lock_guard lock(mutex_);
    if (stopping_ || running_ + jobs_.size() >= capacity_) return false;
    jobs_.push_back(std::move(job));
  }
  ready_.notify_one();
  return true;
}

void CallPool::shutdown() {
  std::deque<std::function<void()>> dropped;
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
    dropped.swap(jobs_);
  }
  ready_.notify_all();
  for (auto& t : threads_) t.join();
  threads_.clear();
}

void CallPool::work() {
  lower_priority(WorkerPool::kWorkerNice);  // below gRPC's threads, like the workers
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock lock(mutex_);
      ready_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
      if (stopping_) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
      ++running_;
    }
    job();
    const std::lock_guard lock(mutex_);
    --running_;
  }
}

}  // namespace geotraj::server::web_detail
