// The operator's description of a path: key frames with geometric constraints (thesis
// Chapter 5, Table 7.8). Plain value types; `std::optional` mirrors proto3 `optional`, so a
// constraint that was not given (free) stays distinct from one given as zero.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace geotraj::core {

/// How curvature and torsion derivatives are expressed.
enum class DerivativeConvention {
  kPerArcLength,  ///< d/ds: kappa' and tau' in [1/m^2] (the API default).
  kPerParameter,  ///< d/du: per unit of the segment parameter u, as in the thesis's tables.
};

/// What a constraint that the operator did not give means (thesis 5.7, 7.2.8, 7.3.1).
enum class UnspecifiedConstraints {
  /// The default: every given constraint is met exactly; every derivative up to the 4th
  /// that the request leaves free is chosen to minimise the jerk energy
  /// sum_segments integral_0^1 |d3p/du3|^2 du over the whole path (one sparse linear
  /// solve, core/geometry/smoothest.hpp). Degree 9 segments, G4 across frames where nothing breaks.
  kSmoothest,
  /// The thesis's reading: orders 1-4 fixed at every frame, a parametric derivative that no
  /// constraint fixes is 0 (degree 9 segments, 5.7, B.2, 7.2.8).
  kThesisZeros,
  /// Only the given orders, each segment of the lowest degree that meets them (kept for
  /// comparison; 7.3.1's "future work").
  kLowestDegree,
};

/// How each axis of each segment is blended between its end constraints (thesis App. B).
enum class BlendMethod {
  kPolynomial,   ///< lowest-degree polynomial (App. B.2), held in Bernstein form.
  kTrapezoidal,  ///< generalized trapezoid of Tesar and Matthew (App. B, Eq. B.7).
};

/// How the tool turns on the segment that leaves a key frame (thesis Table 6.3). The tool
/// frame convention is Eq. (6.21): tool z along the frame's tangent T, tool y along N, tool
/// x = y x z = -B, i.e. R_WT = [-B N T].
enum class OrientationMode {
  kFixed,              ///< keep the orientation the segment starts with
  kFrameBased,         ///< turn (SLERP) to the next key frame's [-B N T]
  kCustom,             ///< turn (SLERP) to a given orientation
  kFrenet,             ///< follow the curve's Frenet frame [-B N T] (6.21)
  kParallelTransport,  ///< rotation-minimising frame about the tangent (7.3.2)
};

/// One key frame: position and Frenet frame in the world frame W, plus the geometric
/// constraints that hold there. Units: metres and radians.
struct KeyFrame {
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();  ///< position [m]
  Eigen::Vector3d T_W = Eigen::Vector3d::UnitX();  ///< unit tangent (required)
  std::optional<Eigen::Vector3d> N_W;              ///< unit normal, required where kappa > 0
  std::optional<Eigen::Vector3d> B_W;              ///< binormal, checked against T x N when given
  std::optional<double> kappa;                     ///< curvature [1/m], >= 0
  std::optional<double> kappa_d;                   ///< curvature derivative [1/m^2] or [1/m per u]
  std::optional<double> tau;                       ///< torsion [1/m], signed
  std::optional<double> tau_d;                     ///< torsion derivative [1/m^2] or [1/m per u]
  /// |dp/du| at the frame [m], > 0, on the approach side (and on the leaving side unless
  /// `leave_tangent_scale` is given). Not given: the chord length of the neighbouring
  /// segment on each side (see validate_path).
  std::optional<double> tangent_scale;
  /// |dp/du| on the leaving side [m], > 0; default `tangent_scale` when that is given, the
  /// leaving segment's chord otherwise. Where the sides differ and nothing breaks the curve
  /// (no cusp, inflection or stop), the smoothest reading keeps it G4 (see smoothest.hpp).
  std::optional<double> leave_tangent_scale;
  bool cusp = false;        ///< the tangent inverts on the leaving side (thesis 5.6.2)
  bool inflection = false;  ///< the normal inverts on the leaving side (thesis 5.6.1)
  bool stop = false;        ///< the motion rests here (used by motion planning)
  OrientationMode orientation_mode = OrientationMode::kFixed;  ///< for the leaving segment
  std::optional<Eigen::Quaterniond> orientation;  ///< R_WT target for kCustom (unit)
  /// kFrameBased, kCustom: the leaving segment's SLERP eased (quintic in the arc-length
  /// fraction; zero angular velocity and acceleration at both ends). See orientation.hpp.
  bool ease_orientation = false;
};

/// Trapezoid breakpoints of one segment (thesis App. B, Eqs. B.10, B.11, B.13), in the
/// segment's local parameter u in [0, 1]. `all` applies to every axis unless that axis has
/// its own list. Each list holds 2n + 2 non-decreasing values for an order-n trapezoid.
struct SegmentBreakpoints {
  std::uint32_t segment = 0;
  std::vector<double> all;
  std::vector<double> x, y, z;
};

/// The shape of one piece of a path written by its natural equations (thesis 2.4).
enum class PieceShape {
  kLine,      ///< kappa = tau = 0
  kArc,       ///< kappa = 1 / radius, tau = 0: turns towards the current normal
  kHelix,     ///< kappa, tau from radius and pitch (4.18-4.19)
  kClothoid,  ///< kappa linear in s from where the piece starts to end_curvature, tau = 0
  kProfile,   ///< kappa(s), tau(s) polynomials in s
  kTo,        ///< a blend from the previous piece's end to the key frame `to`
};

/// One piece: it continues from where the previous one (or PathSpec::start) ends, with the
/// same position, tangent and normal. Lengths [m], curvatures [1/m], coefficients of s^i
/// [1/m^(i+1)]; s is the arc length from the piece's start.
struct PathPiece {
  PieceShape shape = PieceShape::kLine;
  double length_m = 0.0;           ///< > 0; not used by kTo
  double radius = 0.0;             ///< kArc, kHelix [m], > 0
  double pitch = 0.0;              ///< kHelix: rise per turn along the axis [m], signed (+: right-handed)
  double end_curvature = 0.0;      ///< kClothoid [1/m], signed (< 0: towards -N)
  std::vector<double> curvature;   ///< kProfile: kappa(s) = sum curvature[i] s^i, signed
  std::vector<double> torsion;     ///< kProfile: tau(s) = sum torsion[i] s^i
  KeyFrame to;                     ///< kTo
};

/// Everything that defines the geometry of a path: key frames blended (`frames`), or a
/// start frame and pieces (`start`, `pieces`).
struct PathSpec {
  std::vector<KeyFrame> frames;  ///< at least 2 (a path of pieces: none; see build_path)
  DerivativeConvention convention = DerivativeConvention::kPerArcLength;
  UnspecifiedConstraints unspecified = UnspecifiedConstraints::kSmoothest;
  BlendMethod blend = BlendMethod::kPolynomial;
  std::vector<SegmentBreakpoints> breakpoints;  ///< trapezoid only; default uniform (B.10)
  bool closed = false;  ///< a last segment returns from the last frame to the first
  /// Curvature above which a bend is reported (PathWarningCode::kTightBend) [1/m]; > 0.
  std::optional<double> max_curvature;
  /// A path of pieces: where it starts (position, tangent, normal; the orientation mode of
  /// the pieces up to the first `to` frame, and for kFixed optionally the tool orientation).
  std::optional<KeyFrame> start;
  std::vector<PathPiece> pieces;
  /// Where curvature or torsion jumps between pieces, a transition joins them within this
  /// distance [m] of the programmed pieces; absent or 0: the motion rests there.
  std::optional<double> transition_tolerance;
};

/// Number of segments of a path with `frame_count` frames.
constexpr std::size_t segment_count(std::size_t frame_count, bool closed) {
  return frame_count < 2 ? 0 : (closed ? frame_count : frame_count - 1);
}

/// The chord |p_(i+1) - p_i| [m] of segment i (from frame i to the next, the first after the
/// last on a closed path). Precondition: i < segment_count.
inline double segment_chord(const PathSpec& spec, std::size_t i) {
  const std::size_t n = spec.frames.size();
  return (spec.frames[(i + 1) % n].p_W - spec.frames[i].p_W).norm();
}

}  // namespace geotraj::core
