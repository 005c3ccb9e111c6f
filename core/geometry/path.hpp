// A path: one segment per pair of consecutive frames. Key frames blended, each axis
// independently (thesis 5.7, App. B), or pieces given by their natural equations (2.4,
// core/geometry/pieces.hpp), whose joins are frames too. The path parameter u runs over
// [0, M] for M segments: segment i covers u in [i, i + 1] with local parameter u - i (as in
// thesis Eq. B.13).
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "core/error.hpp"
#include "core/geometry/bezier.hpp"
#include "core/geometry/constraints.hpp"
#include "core/geometry/key_frame.hpp"
#include "core/geometry/natural.hpp"
#include "core/geometry/trapezoid.hpp"

namespace geotraj::core {

/// The three axes of a trapezoid-blended segment.
struct TrapezoidSegment {
  std::array<TrapezoidAxis, 3> axes;
};

/// The part [s0, s1] of a curve given by its natural equations, local u in [0, 1] at
/// s = s0 + u (s1 - s0): |dp/du| = s1 - s0 everywhere, so arc length is linear in u, and
/// d^k p/du^k = (s1 - s0)^k d^k p/ds^k. The curve is shared (immutable) by the copies.
struct NaturalSegment {
  std::shared_ptr<const NaturalCurve> curve;
  double s0 = 0.0;  ///< [m]
  double s1 = 0.0;  ///< [m], > s0
  double length() const { return s1 - s0; }
};

/// A closed set of segment kinds: a value, not a class hierarchy.
using Segment = std::variant<BezierSegment, TrapezoidSegment, NaturalSegment>;

/// What a segment is: a blend between key frames, a piece by its natural equations (all of
/// it, or what transitions leave), or a transition between two pieces.
enum class SegmentKind { kBlend, kPiece, kTransition };
struct SegmentOrigin {
  SegmentKind kind = SegmentKind::kBlend;
  std::size_t piece = 0;  ///< a path of pieces: the piece drawn (a transition: the one entered)
};

/// An immutable blended path with its converted frame constraints.
struct Path {
  PathSpec spec;                          ///< the validated, normalised request
  std::vector<FrameConstraints> frames;   ///< Chapter 5 conversion, per frame and side
  std::vector<Segment> segments;          ///< segment i: frame i (leave) -> frame i+1 (approach)
  std::vector<double> segment_lengths;    ///< arc length of each segment [m]
  std::vector<double> cumulative_lengths; ///< s at the start of each segment, plus the total [m]
  std::vector<double> p_uu_noise;         ///< rounding level of d2p/du2 on each segment [m]
  /// A path of pieces: the request field of each frame (`start`, `pieces[2].to`, and
  /// `pieces[1]` for where piece 1 ends or a transition enters it), and the frame whose
  /// orientation mode each frame's leaving segment takes (`start` or a `to` frame). Both
  /// empty for key frames (`frames[k]`, each its own).
  std::vector<std::string> frame_fields;
  std::vector<std::size_t> mode_frames;
  /// A path of pieces: what each segment is; empty for key frames (all blends).
  std::vector<SegmentOrigin> origins;

  std::size_t segment_count() const { return segments.size(); }
  double u_max() const { return static_cast<double>(segments.size()); }
  double length() const { return cumulative_lengths.back(); }
};

/// Validates, converts and blends. Also computes the segment arc lengths.
/// Errors name fields relative to the PathSpec (`frames[1].torsion`, `breakpoints[0].x`).
/// A spec with `start` or `pieces` is built by build_piece_path (pieces.hpp).
Expected<Path> build_path(const PathSpec& spec);

/// The request field of frame k (`frames[3]`, `start`, `pieces[2].to`), and of its `name`
/// (`frames[3].orientationMode`).
std::string frame_name(const Path& path, std::size_t k);
std::string frame_field(const Path& path, std::size_t k, const char* name);
/// The request field of the orientation mode that frame k's leaving segment follows.
std::string mode_field(const Path& path, std::size_t k);

/// Arc length [m] from local u0 to u1 (u0 <= u1) of a natural segment: exact.
inline double natural_arc(const NaturalSegment& seg, double u0, double u1) { return (u1 - u0) * seg.length(); }

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
