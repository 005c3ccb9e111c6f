// Corner blending: a chain of straight lines and paths whose corners are replaced, each
// within a distance tolerance, by a short curvature-continuous segment built by the same
// geometry engine (Chapter 5), so that the whole chain is ONE path, followed without a rest.
//
// Peers (MoveIt Pilz, KDL's path composites, LinuxCNC's G64) round a corner with a circular
// arc: G1 only, the curvature jumps from 0 to 1/r where the arc starts, so the centripetal
// acceleration (and the joints' acceleration) jumps there too. Here each corner becomes a
// segment of the blended path between two frames cut on the neighbouring pieces:
//  - on a line, the cut frame is at distance l from the corner along the line, with the
//    line's tangent and zero curvature, marked as an inflection (thesis 5.6.1: the two
//    sides are independent), so the straight part stays exactly straight (every derivative
//    perpendicular to it is 0 at both its ends, and its free ones minimise a jerk energy
//    that is then 0) and the blend meets it with the same tangent and curvature 0:
//    G2 (tangent and curvature continuous; kappa' jumps from 0 to the blend's);
//  - on a path, the path's own end frame, with every constraint it gives: the blend meets
//    the path G4 there under the smoothest reading (smoothest.hpp), or as the path's reading
//    ties its frames. Two paths are not blended with each other (their frames can be one path).
// The blend segment's deviation from the route it replaces (the two pieces of line either
// side of the corner, or the piece of line between the cut and a path's end) is measured on
// the built curve (the largest distance of 400 points per blend to that route), and l is the
// largest that keeps it within the tolerance, at most 45 % of each line it cuts (so a line
// keeps a straight part between two blends). Between two lines the blend is a scaled copy of
// the one for l = 1 (its frames are independent of the rest and scale with l), so
// l = tolerance / deviation(1); next to a path l is found by bisection, then every blend is
// measured again on the whole chain and l shrunk where the path's coupling moved it.
//
// The tool's orientation through the chain: each line turns the tool from its start to its
// goal orientation on its straight part by an eased SLERP (orientation.hpp: zero angular
// velocity and acceleration at its ends), and every blend holds the orientation of the
// corner, so angular velocity and acceleration are continuous through the blends; a path
// keeps its frames' modes (its last frame's leaving segment, the blend, holds its end
// orientation). Units: SI, frame W.
#pragma once

#include <cstddef>
#include <string>
#include <variant>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/geometry/key_frame.hpp"
#include "core/geometry/path.hpp"

namespace geotraj::core {

/// A straight line of a chain: the tool origin from p0 to p1 [m], its orientation from q0
/// to q1 (unit).
struct BlendLine {
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero();
  Eigen::Vector3d p1 = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q0 = Eigen::Quaterniond::Identity();
  Eigen::Quaterniond q1 = Eigen::Quaterniond::Identity();
};

/// One piece of a chain: a line or an open polynomial path.
using BlendPiece = std::variant<BlendLine, PathSpec>;

/// Largest corner [rad] that is blended: a line that turns back more sharply has no room
/// for a blend within a tolerance (the blend would be a hairpin).
inline constexpr double kMaxBlendedCorner = 170.0 * 3.14159265358979323846 / 180.0;

/// Largest turn [rad] of a junction that is not a corner: pieces whose tangents agree within
/// it meet tangent-continuously. Their blend rounds no corner: between collinear lines it is
/// straight (and reports do not list it); between a line and a path it makes the curvature
/// continuous (reported as such, not as a turn).
inline constexpr double kSmoothJunction = 1e-6;

/// One blended corner, between piece `after` and piece `after + 1`.
struct CornerBlend {
  std::size_t after = 0;
  std::size_t segment = 0;   ///< the blend's segment in the chain's path
  double tolerance = 0.0;    ///< [m]
  double deviation = 0.0;    ///< largest distance from the route it replaces [m], <= tolerance
  double cut_before = 0.0;   ///< length of the line before the corner it replaces [m] (0 at a path)
  double cut_after = 0.0;    ///< length of the line after the corner it replaces [m] (0 at a path)
  double corner = 0.0;       ///< the angle between the tangents either side of the corner [rad]
};

/// A chain as one path.
struct BlendedChain {
  PathSpec spec;  ///< built by build_path; its orientation by plan_orientation from the first line's q0
  /// Per segment of `spec`: the piece it belongs to (a blend: the piece before its corner).
  std::vector<std::size_t> segment_piece;
  std::vector<CornerBlend> corners;  ///< one per junction, in order
};

/// Blends the corners of `pieces` (at least 2, each starting where the previous ends),
/// corner j (between pieces j and j + 1) within tolerances[j] > 0 [m]. `names[k]` is how
/// errors name piece k (a field path, e.g. `sequence[2]`): `<name>.blendTolerance` for a
/// corner that cannot be blended (two paths, a line turning back more than
/// kMaxBlendedCorner, a line without length), `<name>.path` for a path that is closed,
/// trapezoid-blended or read differently from the others, `<name>.path.frames[i]...` for
/// the path's own errors.
Expected<BlendedChain> blend_chain(const std::vector<BlendPiece>& pieces, const std::vector<double>& tolerances,
                                   const std::vector<std::string>& names);

/// Largest distance [m] of `path`'s segment `segment` (sampled at `samples` + 1 points
/// uniform in u) from the polyline `route` (at least 2 points).
double deviation_from(const Path& path, std::size_t segment, const std::vector<Eigen::Vector3d>& route,
                      int samples = 400);

}  // namespace geotraj::core
