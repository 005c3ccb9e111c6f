// Happens-before edges that ThreadSanitizer cannot see. A reactor's state is written on one
// thread (a worker, or a gRPC thread) before it starts a write, an alarm or its finish, and
// read on the gRPC thread that runs the completion: gRPC orders the two inside its core
// library, which Debian does not build with TSan. Releasing before the hand-off and
// acquiring in the callback tells TSan what gRPC guarantees. No code in other builds.
#pragma once

#if defined(__SANITIZE_THREAD__)
#define GEOTRAJ_TSAN_BUILD 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define GEOTRAJ_TSAN_BUILD 1
#endif
#endif

#ifdef GEOTRAJ_TSAN_BUILD
extern "C" void __tsan_acquire(void* address);
extern "C" void __tsan_release(void* address);
#endif

namespace geotraj::server {

/// Before handing `object` to gRPC (StartWrite, Finish, Alarm::Set) on this thread.
inline void handoff_release([[maybe_unused]] const void* object) {
#ifdef GEOTRAJ_TSAN_BUILD
  __tsan_release(const_cast<void*>(object));
#endif
}

/// First thing in a callback that gRPC runs for `object` (OnWriteDone, OnDone, an alarm).
inline void handoff_acquire([[maybe_unused]] const void* object) {
#ifdef GEOTRAJ_TSAN_BUILD
  __tsan_acquire(const_cast<void*>(object));
#endif
}

}  // namespace geotraj::server
