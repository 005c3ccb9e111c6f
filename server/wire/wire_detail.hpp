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

// One path, move or line (a request's, or a sequence step's); `robot`, when given, is the
// request's robot already resolved (a sequence resolves it once for all its steps).
core::Expected<planner::Request> single_from_proto(const v1::PlanRequest& request, const RobotCatalog& catalog,
                                                   const ServiceLimits& limits, RequestUse use,
                                                   const planner::StopAt& stop_at,
                                                   std::shared_ptr<const planner::Robot> robot);

// PlanRequest.sequence: each step converted as a request of its own (the request's robot,
// motion unless the step gives one, optimize for paths), every violation named from the root.
core::Expected<planner::Request> sequence_from_proto(const v1::PlanRequest& request, const RobotCatalog& catalog,
                                                     const ServiceLimits& limits, RequestUse use,
                                                     const planner::StopAt& stop_at);

}  // namespace geotraj::server::wire_detail
