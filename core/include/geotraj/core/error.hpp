// Two tiers of errors (docs/architecture.md):
//  - user input: every violation collected as a value, naming the field path the user sent
//    (`frames[2].torsion`, relative to the validated value; the server prefixes `path.`);
//  - programmer bugs: GEOTRAJ_CHECK, always on, stops the process. Never used on request data.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <tl/expected.hpp>

namespace geotraj::core {

/// One thing wrong with a request: where (`field`, a path in proto JSON names) and what.
struct FieldViolation {
  std::string field;
  std::string description;
};

using Violations = std::vector<FieldViolation>;

/// A value or the complete list of what is wrong with the input that should have made it.
template <class T>
using Expected = tl::expected<T, Violations>;

/// Prefixes every violation's field path with `prefix` (e.g. "path.").
inline Violations prefixed(Violations v, const std::string& prefix) {
  for (auto& fv : v) fv.field = prefix + fv.field;
  return v;
}

[[noreturn]] inline void check_failed(const char* expr, const char* file, int line) {
  std::fprintf(stderr, "geotraj: internal check failed: %s at %s:%d\n", expr, file, line);
  std::abort();
}

}  // namespace geotraj::core

/// Always-armed programmer check (a bug in geotraj, never bad user input).
#define GEOTRAJ_CHECK(cond) \
  ((cond) ? static_cast<void>(0) : ::geotraj::core::check_failed(#cond, __FILE__, __LINE__))
