// The kinematics calls on the wire: ComputeForwardKinematics and ComputeInverseKinematics
// requests as the planner's values (every violation of a request together, field paths in
// proto JSON names), and the planner's answers as responses.
#pragma once

#include "core/error.hpp"
#include "geotraj/v1/geotraj.pb.h"
#include "planner/kinematics.hpp"
#include "planner/robots.hpp"
#include "server/wire/convert.hpp"

namespace geotraj::server {

/// InverseKinematicsRequest's bounds and defaults.
inline constexpr std::uint32_t kDefaultIkRestarts = 255;
inline constexpr std::uint32_t kMaxIkRestarts = 100'000;
inline constexpr std::uint32_t kDefaultIkSolutions = 16;
inline constexpr std::uint32_t kMaxIkSolutions = 1000;
/// The largest |coordinate| of an IK target [m], as for a key frame (core::PathLimits).
inline constexpr double kMaxTargetCoordinate = 1e6;

/// A ForwardKinematicsRequest converted, or every violation: `robot` (required; as in a
/// PlanRequest; a URDF parsed within `stop_at`), `joints` (one per joint, finite, magnitude
/// at most 1e6).
core::Expected<planner::ForwardRequest> forward_request_from_proto(const v1::ForwardKinematicsRequest& request,
                                                                   const RobotCatalog& catalog,
                                                                   const planner::StopAt& stop_at = {});

/// An InverseKinematicsRequest converted, or every violation: `robot`, `target` (required;
/// a position within 1e6 m of the origin, a unit quaternion), `restarts`, `maxSolutions`, `positionTolerance`,
/// `orientationTolerance` (their ranges in the proto).
core::Expected<planner::InverseRequest> inverse_request_from_proto(const v1::InverseKinematicsRequest& request,
                                                                   const RobotCatalog& catalog,
                                                                   const planner::StopAt& stop_at = {});

void to_proto(const planner::Forward& forward, v1::ForwardKinematicsResponse& out);
void to_proto(const planner::Inverse& inverse, v1::InverseKinematicsResponse& out);

}  // namespace geotraj::server
