// A path written by its natural equations (thesis 2.4, Eqs. 2.34-2.35; 4.4.1): a start
// frame and pieces, each continuing from where the previous one ends (position, tangent,
// normal; the clothoid also from its curvature). Frames and units as in natural.hpp: W,
// metres, curvatures [1/m], s the arc length from a piece's start.
//
// Pieces and their natural equations (kappa(s), tau(s); kappa signed: < 0 bends towards -N):
//   line      0, 0
//   arc       1/r, 0                     (turns towards the current normal)
//   helix     r/(r^2 + l^2), l/(r^2 + l^2), l = pitch / 2 pi   (4.18-4.19)
//   clothoid  k0 + (k1 - k0) s / L, 0    (k0: the curvature where the piece starts)
//   profile   the given polynomials
//   to        a blend (Bezier, Chapter 5) from the previous piece's end to a key frame
//
// Each natural piece is one NaturalSegment of a NaturalCurve: exact (closed form) where kappa
// and tau are constant, within 1e-9 m elsewhere; arc length is its parameter. The frames of
// the built path are the joins: frame 0 is `start`, then the end of every segment.
//
// Joins. Where the curvature (or, on a bent curve, the torsion) jumps from one piece to the
// next, the tool's acceleration would jump: with `transition_tolerance` > 0 a transition
// replaces the join, a degree-9 Bezier that meets both pieces to the fourth derivative (G4:
// kappa, tau, kappa', tau' continuous) where it leaves one and enters the other, as long as
// it stays within the tolerance of the programmed pieces (the largest such length, at most
// a third of either piece, by bisection on the distance measured at 64 points and checked at
// 512); without it the join is a rest (`stop`). Outside the transitions the pieces are
// exact. A `to` blend starts with the full state (kappa, tau, kappa', tau') the previous
// piece ends with (G4); the key frame it ends at, when a natural piece follows, takes the
// curvature, torsion and derivatives it does not give from that piece's start (G4 again),
// and where what it gives differs from them, the motion rests there.
//
// Orientation: `start.orientation_mode` governs the pieces up to the first `to` frame, each
// `to` frame's mode the pieces after it (kCustom: only the first, kFixed after). kFixed
// holds the tool as the robot starts (or `start.orientation`), on curved starts too.
#pragma once

#include <cstddef>
#include <vector>

#include "core/error.hpp"
#include "core/geometry/path.hpp"

namespace geotraj::core {

/// The most pieces one path may have.
inline constexpr std::size_t kMaxPieces = 10'000;
/// The most integration steps (NaturalCurve::steps) the pieces of one path may take in all:
/// about 20 MB of frames and 0.1 s of integration.
inline constexpr std::size_t kMaxPathNaturalSteps = 200'000;
/// The largest share of a piece's length that a transition at one of its ends may take.
inline constexpr double kTransitionShare = 1.0 / 3.0;
/// The most transitions one path may have (each costs some 0.3 ms to size).
inline constexpr std::size_t kMaxTransitions = 1000;
/// The shortest transition [m] (its half-length and its chord); where the tolerance or the
/// pieces allow none as long, the join is a rest.
inline constexpr double kMinTransition = 1e-9;
/// The largest transition tolerance [m].
inline constexpr double kMaxTransitionTolerance = 1.0;

/// A natural piece's kappa(s) and tau(s), polynomial coefficients in s.
struct PieceProfile {
  std::vector<double> kappa, tau;
};

/// kappa(s), tau(s) of a piece other than kTo, given the curvature it starts with (the
/// clothoid's k0; the others ignore it).
PieceProfile piece_profile(const PathPiece& piece, double start_curvature);

/// Builds a path of `start` and `pieces` (see the header). Errors name the request's fields
/// (`pieces[2].radius`, `pieces[3].to.normal`, `start.normal`, `transitionTolerance`).
Expected<Path> build_piece_path(const PathSpec& spec);

}  // namespace geotraj::core
