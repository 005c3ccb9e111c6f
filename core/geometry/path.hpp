// A blended path: one segment per pair of consecutive key frames, each axis blended
// independently (thesis 5.7, App. B). The path parameter u runs over [0, M] for M segments:
// segment i covers u in [i, i + 1] with local parameter u - i (as in thesis Eq. B.13).
#pragma once

#include <cstddef>
#include <utility>
#include <variant>
#include <vector>

#include "core/error.hpp"
#include "core/geometry/bezier.hpp"
#include "core/geometry/constraints.hpp"
#include "core/geometry/key_frame.hpp"
#include "core/geometry/trapezoid.hpp"

namespace geotraj::core {

/// The three axes of a trapezoid-blended segment.
struct TrapezoidSegment {
  std::array<TrapezoidAxis, 3> axes;
};

/// A closed set of blends: a value, not a class hierarchy.
using Segment = std::variant<BezierSegment, TrapezoidSegment>;

/// An immutable blended path with its converted frame constraints.
struct Path {
  PathSpec spec;                          ///< the validated, normalised request
  std::vector<FrameConstraints> frames;   ///< Chapter 5 conversion, per frame and side
  std::vector<Segment> segments;          ///< segment i: frame i (leave) -> frame i+1 (approach)
  std::vector<double> segment_lengths;    ///< arc length of each segment [m]
  std::vector<double> cumulative_lengths; ///< s at the start of each segment, plus the total [m]
  std::vector<double> p_uu_noise;         ///< rounding level of d2p/du2 on each segment [m]

  std::size_t segment_count() const { return segments.size(); }
  double u_max() const { return static_cast<double>(segments.size()); }
  double length() const { return cumulative_lengths.back(); }
};

/// Validates, converts and blends. Also computes the segment arc lengths.
/// Errors name fields relative to the PathSpec (`frames[1].torsion`, `breakpoints[0].x`).
Expected<Path> build_path(const PathSpec& spec);

/// Global path parameter u -> (segment index, local u in [0, 1]); u is clamped to [0, M].
/// An integer u = i < M belongs to segment i (its start); u = M to the last segment's end.
std::pair<std::size_t, double> locate(const Path& path, double u);

/// jet[0..max_order] of one segment at local parameter u.
void evaluate(const Segment& segment, double u_local, int max_order, Jet& jet);

/// jet[0..max_order] of the path at global u (see locate).
Jet evaluate(const Path& path, double u, int max_order = kMaxJetOrder);

/// Rounding level [m] of d2p/du2 evaluated on `segment`: a few hundred ulps of the
/// magnitudes that the evaluation sums (control points for Bezier, ramp heights and start
/// state for the trapezoid). Below it, a computed d2p/du2 carries no direction.
double segment_noise(const Segment& segment);

/// Order of the trapezoid between end orders n0 and n1: max(n0, n1) + 1.
constexpr int trapezoid_order(int n0, int n1) { return (n0 > n1 ? n0 : n1) + 1; }

}  // namespace geotraj::core
