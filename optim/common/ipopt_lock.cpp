#include "optim/common/ipopt_lock.hpp"

#include <algorithm>

namespace geotraj::optim::detail {

std::unique_lock<std::timed_mutex> lock_ipopt(std::chrono::steady_clock::time_point deadline,
                                              const std::stop_token& stop) {
  static std::timed_mutex ipopt;
  // Waits in short slices so that a cancelled call stops waiting within one slice.
  constexpr auto kSlice = std::chrono::milliseconds(10);
  std::unique_lock lock(ipopt, std::defer_lock);
  for (;;) {
    const auto now = std::chrono::steady_clock::now();
    if (lock.try_lock_until(std::min(deadline, now + kSlice))) return lock;
    if (stop.stop_requested() || std::chrono::steady_clock::now() >= deadline) return lock;
  }
}

}  // namespace geotraj::optim::detail
