// Which sanitizer a test is built under: GCC defines __SANITIZE_ADDRESS__, clang answers
// __has_feature(address_sanitizer) (its __SANITIZE_ADDRESS__ came only in clang 17), and the
// same of the thread sanitizer.
#pragma once

namespace geotraj::testing {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kAddressSanitizer = true;
#else
inline constexpr bool kAddressSanitizer = false;
#endif
#else
inline constexpr bool kAddressSanitizer = false;
#endif

#if defined(__SANITIZE_THREAD__)
inline constexpr bool kThreadSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
inline constexpr bool kThreadSanitizer = true;
#else
inline constexpr bool kThreadSanitizer = false;
#endif
#else
inline constexpr bool kThreadSanitizer = false;
#endif

/// Under a sanitizer the code runs 10-20 times slower (ASan and UBSan with Eigen's
/// assertions on, or TSan): tests that repeat the same calls repeat them fewer times.
inline constexpr bool kSanitized = kAddressSanitizer || kThreadSanitizer;

}  // namespace geotraj::testing
