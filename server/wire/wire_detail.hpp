// What the wire's conversion files share (server/wire/*.cpp); not part of the wire's
// interface (convert.hpp).
#pragma once

#include <memory>
#include <set>
#include <string>

#include <Eigen/Core>

#include "core/error.hpp"
#include "geotraj/v1/geotraj.pb.h"
#include "planner/planner.hpp"
#include "planner/request_input.hpp"
#include "server/wire/convert.hpp"

namespace geotraj::server::wire_detail {

inline Eigen::Vector3d to_core(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

inline void set(v1::Vec3* out, const Eigen::Vector3d& v) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

// The wire checks of one request, with the fields whose core checks would only repeat them.
struct WireCheck {
  core::Violations violations;
  std::set<std::string> suppressed;  ///< core field paths (relative to `path`) to drop

  void add(std::string field, std::string description) {
    violations.push_back({std::move(field), std::move(description)});
  }
};

// Records a violation when `value` is not a value of the enum (proto3 enums are open:
// unknown numbers survive parsing), naming the values that are.
void check_enum(WireCheck& check, const std::string& field, int value,
                const google::protobuf::EnumDescriptor* descriptor);

// A quaternion whose norm is within this of 1 is accepted as a rotation.
inline constexpr double kUnitQuaternionTolerance = 1e-3;

inline core::Violations joined(core::Violations a, const core::Violations& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// A path as given (PlanRequest.path, a step's, ConvertRequest.path): every field read, what
// could not be named from the path ("frames[2].tangent"), the core checks that makes noise.
// A path of more than `limits.max_frames` key frames is refused before any of it is read.
planner::PathInput path_input(const v1::PathSpec& path, const ServiceLimits& limits);

// PlanRequest.analysisPoints and samplesPerBatch within the server's limits.
void check_request_numbers(const v1::PlanRequest& request, const ServiceLimits& limits, WireCheck& check);

// PlanRequest.motion (or a sequence step's) as given; what cannot be read (unknown enum
// values) into `out` under `prefix` ("motion", "sequence[1].motion").
planner::MotionInput motion_input(const v1::MotionSpec& motion, const std::string& prefix, core::Violations& out);

// PlanRequest.jointMove and linearMove as given; poses that cannot be read into `out` under
// `prefix` ("" or "sequence[1].").
planner::JointMoveInput joint_move_input(const v1::JointMove& move, const std::string& prefix, core::Violations& out);
core::JointPathSpec joint_path_input(const v1::JointPath& path);
planner::LinearMoveInput linear_move_input(const v1::LinearMove& move);

// PlanRequest.optimize as given: the budget within the server's limit, the optimisers'
// options (optimize.cpp).
planner::OptimizeInput optimize_input(const v1::PlanRequest& request, const ServiceLimits& limits,
                                      core::Violations& out);

// PlanRequest.sequence's steps into `in` (sequence.cpp).
void sequence_input(const v1::PlanRequest& request, const ServiceLimits& limits, planner::RequestInput& in);

// PlanRequest.robot as the planner's RobotSpec (robot.cpp).
planner::RobotSpec robot_spec_from_proto(const v1::RobotSpec& spec, core::Violations& out);

}  // namespace geotraj::server::wire_detail
