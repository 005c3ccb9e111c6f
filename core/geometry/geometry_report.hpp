// The geometry of a blended path between its key frames: what an operator would not see
// from the frames alone (thesis 2.2.3: curvature and torsion along the curve; 5.6.2: a
// cusp is where dp/du vanishes). Per segment the extreme curvature, torsion and |dp/du|,
// the tangent's total turning, and warnings for what the operator did not ask for.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "core/geometry/path.hpp"

namespace geotraj::core {

/// An extreme value on a segment and where it is: global u in [0, M], arc length s [m].
struct Extremum {
  double value = 0.0;
  double u = 0.0;
  double s = 0.0;
};

/// The geometry of one segment, measured on the curve.
struct SegmentGeometry {
  Extremum peak_curvature;  ///< largest kappa [1/m]
  Extremum peak_torsion;    ///< tau [1/m] of the largest |tau| where the normal is defined
  Extremum min_speed;       ///< smallest |dp/du| [m per unit u]
  double turning = 0.0;     ///< total turning of the unit tangent, integral of kappa ds [rad]
};

enum class PathWarningCode {
  kNearCusp,   ///< |dp/du| nearly vanishes inside the segment (value: that |dp/du| [m])
  kTightBend,  ///< curvature above PathSpec.max_curvature (value: the peak kappa [1/m])
  kTurnsBack,  ///< the tangent turns more than a half-turn beyond its ends' angle (value [rad])
};

struct PathWarning {
  PathWarningCode code = PathWarningCode::kNearCusp;
  std::size_t segment = 0;
  double u = 0.0;  ///< global path parameter of the finding
  double s = 0.0;  ///< arc length there [m]
  double value = 0.0;
  std::string message;
};

struct GeometryReport {
  std::vector<SegmentGeometry> segments;
  std::vector<PathWarning> warnings;
};

/// Near cusp: the smallest |dp/du| inside a segment below this fraction of the segment's
/// mean |dp/du| (its arc length, since u spans 1). The curve then turns on a radius far
/// below the segment's size: a kink the operator did not ask for.
inline constexpr double kNearCuspFraction = 0.1;

/// Turns back: total turning of the tangent above the angle between the segment's end
/// tangents by more than this [rad] (a loop, or a doubling back at a near-cusp).
inline constexpr double kTurnsBackExcess = 3.14159265358979323846;

/// Samples 16 to 64 points per segment (at most `max_points` in all, more where a path has
/// fewer than 256 segments), then refines each extreme where the slope of its quantity
/// (kappa_u 5.15, tau_u 5.21, d|dp/du|/du) changes sign next to the best sample, by regula
/// falsi (Illinois); the curvature also next to the smallest |dp/du|, where a kink narrower
/// than the sampling peaks. s comes from the two-point Hermite rule on |dp/du| between
/// samples, anchored to the segment's arc length (about 1e-7 m).
GeometryReport geometry_report(const Path& path, std::size_t max_points = 16384);

}  // namespace geotraj::core
