// Complete validation of a PathSpec that came from a user. Collects every violation.
#pragma once

#include <string>

#include "core/error.hpp"
#include "core/geometry/key_frame.hpp"

namespace geotraj::core {

/// Tolerances of the key-frame checks, dimensionless.
struct FrameTolerances {
  /// A tangent or normal whose length is within this of 1 is normalised (the thesis prints
  /// 0.707 for 1/sqrt(2)); others are rejected.
  double unit_length = 1e-3;
  /// |T . N| up to this is accepted, then N is made exactly perpendicular to T.
  double perpendicular = 1e-3;
  /// |B - T x N| up to this is accepted for a given binormal.
  double binormal = 1e-3;
};

/// Hard limits on the size of a path, to bound the work of one request.
struct PathLimits {
  std::size_t max_frames = 100000;
  /// Largest |coordinate| of a key frame [m] and largest tangent scale [m]: far beyond any
  /// workcell, and small enough that no product in the conversion or blend overflows.
  double max_coordinate = 1e6;
  double max_tangent_scale = 1e6;
  /// Smallest tangent scale [m]: below it the tangent of the blended curve is lost in rounding.
  double min_tangent_scale = 1e-9;
  /// Largest |curvature|, |torsion| and |derivative| [1/m, 1/m^2 or per u]: a radius of
  /// 1e-12 m; larger values only overflow the conversion.
  double max_abs_geometry = 1e12;
};

/// Checks `spec` completely and returns a normalised copy: unit T and N, N exactly
/// perpendicular to T. Field paths are relative to the PathSpec (`frames[2].torsion`).
/// Rules: finite numbers; |T| and |N| within `unit_length` of 1; T . N within
/// `perpendicular`; B (when given) within `binormal` of T x N; kappa >= 0; a normal where
/// kappa > 0; kappa', tau and tau' only with kappa > 0 (thesis footnote 5); tau' only with
/// tau given; tangent scale > 0; cusp and inflection only at frames with both sides on an
/// open path; inflection only with a curvature; breakpoints only for the trapezoid, for an
/// existing segment, ordered and inside [0, 1] (their count is checked when the path is
/// built, since it depends on the orders that the frames fix).
Expected<PathSpec> validate_path(const PathSpec& spec, const FrameTolerances& tol = {},
                                 const PathLimits& limits = {});

/// Checks one key frame outside a list (a path's `start`) by the rules of validate_path,
/// fields under `at`, and normalises it in place; `arriving` and `leaving`: whether segments
/// arrive at and leave it (cusps, inflections and leaving scales need them).
Violations validate_key_frame(const std::string& at, KeyFrame& frame, bool arriving, bool leaving,
                              UnspecifiedConstraints reading, const FrameTolerances& tol = {},
                              const PathLimits& limits = {});

}  // namespace geotraj::core
