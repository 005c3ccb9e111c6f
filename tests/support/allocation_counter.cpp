#include "allocation_counter.hpp"

#include <atomic>
#include <cstdlib>
#include <new>

// GCC 12 takes the replaced pair for a mismatch when it inlines std::allocator: a false
// positive.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

namespace {
std::atomic<long> g_allocations{0};
}

void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

long geotraj::testing::allocation_count() { return g_allocations.load(std::memory_order_relaxed); }
