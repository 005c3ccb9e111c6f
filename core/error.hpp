// Two tiers of errors (docs/architecture.md):
//  - user input: every violation collected as a value, naming the field the user sent;
//  - programmer bugs: GEOTRAJ_CHECK, always on, stops the process. Never used on request data.
//
// Field paths: one convention. A path names a field in proto JSON names (`tangentScale`,
// `durationS`, never snake_case) from the root of the value the function was given:
//  - a function given one user value (validate_path, build_path, validate_robot) names
//    fields inside it (`frames[2].torsion`);
//  - a function given several (a path and a motion, a path and optimiser options) names
//    each from the PlanRequest's root (`path.frames[2].torsion`, `motion.durationS`,
//    `optimize.tangentScales.minScale`), as the request spells them.
// The planner, the only layer that knows where each value sits in a request, prefixes the
// first kind once (core::prefixed), so that every path that leaves it is absolute from the
// request's root; a request that nests requests (a sequence) prefixes again at its level.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#include <tl/expected.hpp>

namespace geotraj::core {

/// Which kind of wrong a violation is, carried with it so that no caller tells them apart by
/// field names: a field the user must change (kInvalid), or a well-formed request that the
/// limits or the geometry cannot carry out (kUnattainable: no positive speed follows the path
/// somewhere, the IK fails along it, the minimum-time motion is too long to sample).
enum class ViolationKind { kInvalid, kUnattainable };

/// One thing wrong with a request: where (`field`, a path in proto JSON names) and what.
struct FieldViolation {
  std::string field;
  std::string description;
  ViolationKind kind = ViolationKind::kInvalid;
};

using Violations = std::vector<FieldViolation>;

/// A value or the complete list of what is wrong with the input that should have made it.
template <class T>
using Expected = tl::expected<T, Violations>;

/// A violation of the kUnattainable kind.
inline FieldViolation unattainable(std::string field, std::string description) {
  return {std::move(field), std::move(description), ViolationKind::kUnattainable};
}

/// Whether every violation is kUnattainable (and there is one): the request is well-formed,
/// what it asks cannot be done.
inline bool all_unattainable(const Violations& v) {
  if (v.empty()) return false;
  for (const auto& fv : v) {
    if (fv.kind != ViolationKind::kUnattainable) return false;
  }
  return true;
}

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
