// Which sanitizer a test is built under: GCC defines __SANITIZE_ADDRESS__, clang answers
// __has_feature(address_sanitizer) (its __SANITIZE_ADDRESS__ came only in clang 17).
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

}  // namespace geotraj::testing
