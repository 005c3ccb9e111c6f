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
/// A ForwardKinematicsRequest as given (planner::admit checks the robot and the joints).
planner::ForwardInput forward_input_from_proto(const v1::ForwardKinematicsRequest& request);

/// An InverseKinematicsRequest as given, with the violations of what cannot be read: `target`
/// (a unit quaternion), `restarts`, `maxSolutions`, `positionTolerance`, `orientationTolerance`
/// (their ranges in the proto). planner::admit checks the robot and the target.
planner::InverseInput inverse_input_from_proto(const v1::InverseKinematicsRequest& request);

void to_proto(const planner::Forward& forward, v1::ForwardKinematicsResponse& out);
void to_proto(const planner::Inverse& inverse, v1::InverseKinematicsResponse& out);

}  // namespace geotraj::server
