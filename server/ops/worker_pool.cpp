#include "server/ops/worker_pool.hpp"

#include <algorithm>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

namespace geotraj::server {

// Linux gives each thread its own nice value; a thread may always lower its own priority.
void lower_priority(int nice) {
  if (nice <= 0) return;  // as the process
  const auto tid = static_cast<id_t>(::syscall(SYS_gettid));
  (void)::setpriority(PRIO_PROCESS, tid, nice);
}

WorkerPool::WorkerPool(int threads, int urgent_threads, int nice) {
  const int n = std::max(threads, 1);
  const int u = std::max(urgent_threads, 0);
  threads_.reserve(static_cast<std::size_t>(n + u));
  for (int i = 0; i < n; ++i) threads_.emplace_back(&WorkerPool::run, this, false, nice);
  for (int i = 0; i < u; ++i) threads_.emplace_back(&WorkerPool::run, this, true, nice);
}

WorkerPool::~WorkerPool() {
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (auto& t : threads_) t.join();
}

void WorkerPool::submit(std::function<void()> task, Priority priority) {
  {
    const std::lock_guard lock(mutex_);
    (priority == Priority::kUrgent ? urgent_ : normal_).push_back(std::move(task));
  }
  wake_.notify_all();  // one of each kind may be waiting: let the right one take it
}

std::size_t WorkerPool::queued() const {
  const std::lock_guard lock(mutex_);
  return urgent_.size() + normal_.size();
}

int WorkerPool::busy() const {
  const std::lock_guard lock(mutex_);
  return busy_;
}

void WorkerPool::run(bool urgent_only, int nice) {
  lower_priority(nice);
  std::unique_lock lock(mutex_);
  const auto has_work = [this, urgent_only] { return !urgent_.empty() || (!urgent_only && !normal_.empty()); };
  for (;;) {
    wake_.wait(lock, [&] { return stopping_ || has_work(); });
    if (!has_work()) return;  // stopping, and nothing left for this worker
    auto& queue = urgent_.empty() ? normal_ : urgent_;
    std::function<void()> task = std::move(queue.front());
    queue.pop_front();
    ++busy_;
    lock.unlock();
    task();
    task = nullptr;  // its captures go before the next wait
    lock.lock();
    --busy_;
  }
}

}  // namespace geotraj::server
