// Numbers in messages: one formatter for every error, warning and report that geotraj writes
// in words, so a value reads the same wherever it appears.
//  - number(x): the shortest text that reads back as exactly x (std::to_chars), for values
//    a user gave ("must be > 0, got 0.1", never 0.10000000000000001 or 0.1000);
//  - number(x, digits): `digits` significant digits (%g style), for measured values whose
//    last digits are noise ("peak curvature 40.27 1/m").
// -0 reads as 0; NaN and the infinities as proto JSON spells them (NaN, Infinity, -Infinity).
#pragma once

#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <string>

namespace geotraj::core {

inline std::string number(double x, int digits = 0) {
  if (std::isnan(x)) return "NaN";
  if (std::isinf(x)) return x > 0 ? "Infinity" : "-Infinity";
  x += 0.0;  // -0 -> +0
  std::array<char, 64> buffer{};
  if (digits <= 0) {
    const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), x);
    return std::string(buffer.data(), result.ptr);
  }
  const int n = std::snprintf(buffer.data(), buffer.size(), "%.*g", digits, x);
  return std::string(buffer.data(), static_cast<std::size_t>(n > 0 ? n : 0));
}

}  // namespace geotraj::core
