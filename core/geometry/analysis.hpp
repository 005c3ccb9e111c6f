// What a blended path actually is: the geometry measured on the curve at every key frame
// (the closed loop of the conversion) and profiles along the path for plots.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/differential_geometry.hpp"
#include "core/geometry/path.hpp"

namespace geotraj::core {

/// Geometry measured on the blended curve at one key frame, on each side that exists
/// (an open path has no approach side at its first frame, no leaving side at its last).
struct AchievedFrame {
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();
  std::optional<LocalGeometry> approach;  ///< end of the segment arriving here
  std::optional<LocalGeometry> leave;     ///< start of the segment leaving here
};

std::vector<AchievedFrame> achieved_geometry(const Path& path);

/// The largest deviation between what the request asked at its frames and what the curve
/// achieved: position [m], tangent and normal (angle [rad]), kappa, tau and the given
/// derivatives (in the request's convention) relative to max(1, |asked|). A tangent or
/// normal that the curve does not define there (rounding ate it) counts as pi.
struct ClosedLoopError {
  double max_error = 0.0;
  std::string worst_field;  ///< e.g. "frames[2].leave.torsion"
};
ClosedLoopError closed_loop_error(const Path& path, const std::vector<AchievedFrame>& achieved);

/// One point of a path profile.
struct ProfilePoint {
  double u = 0.0;          ///< global path parameter
  double s = 0.0;          ///< arc length from the start [m]
  std::size_t segment = 0;
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();
  LocalGeometry geometry;
};

/// `count` points spread uniformly in u over [0, M], both ends included (count >= 2).
std::vector<ProfilePoint> analyze(const Path& path, std::size_t count);

/// The same for long profiles that a caller may abandon: `stopped` is asked every
/// kAnalysisCheckInterval points, and nullopt comes back as soon as it answers true.
inline constexpr std::size_t kAnalysisCheckInterval = 4096;
std::optional<std::vector<ProfilePoint>> analyze(const Path& path, std::size_t count,
                                                 const std::function<bool()>& stopped);

}  // namespace geotraj::core
