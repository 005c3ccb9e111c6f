// fuzz_robot_model_json: bytes as a robot model file (geotrajd --robot-model FILE), parsed by
// robot_model_from_json, the start-up parser, then checked (core::ValidRobot::check) as geotrajd
// does before the model enters its catalogue. A model both accept must
//  - have a finite tool pose and Jacobian at its home configuration and at the middle of
//    its joint ranges (a model whose kinematics overflow must be refused, not served);
//  - be accepted again after the round trip through its wire form (to_proto, then
//    robot_model_from_proto, as ListRobots and robot.model would carry it), unchanged.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include <google/protobuf/util/message_differencer.h>

#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"
#include "server/wire/convert.hpp"

namespace {

[[noreturn]] void fail(const std::string& why, std::string_view input) {
  std::fprintf(stderr, "\n==== geotraj fuzz check failed: %s\n==== robot model file: %.*s\n\n", why.c_str(),
               static_cast<int>(std::min<std::size_t>(input.size(), 4000)), input.data());
  std::abort();
}

void require_finite_kinematics(const geotraj::core::RobotModel& model, const geotraj::core::JointVector& q,
                               const char* where, std::string_view input) {
  Eigen::Isometry3d X_WT;
  geotraj::core::JointJacobian J;
  geotraj::core::forward_kinematics(model, q, X_WT, J);
  if (!X_WT.matrix().allFinite()) fail(std::string("the tool pose at ") + where + " is not finite", input);
  if (!J.allFinite()) fail(std::string("the Jacobian at ") + where + " is not finite", input);
  if (!geotraj::core::forward_kinematics(model, q).matrix().allFinite()) {
    fail(std::string("forward_kinematics(model, q) at ") + where + " is not finite", input);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  // As geotrajd reads a model file: read, then checked where it enters the catalogue.
  auto read = geotraj::server::robot_model_from_json(input);
  if (!read) {
    if (read.error().empty()) fail("refused without a reason", input);
    return 0;
  }
  auto checked = geotraj::core::ValidRobot::check(*read);
  if (!checked) {
    if (checked.error().empty()) fail("refused by the check without a reason", input);
    return 0;
  }
  const geotraj::core::RobotModel* model = &checked->model();
  const auto home = geotraj::core::home_configuration(*model);
  if (static_cast<std::size_t>(home.size()) != model->dof()) fail("home_configuration has the wrong size", input);
  require_finite_kinematics(*model, home, "home", input);
  geotraj::core::JointVector middle(home.size());
  for (Eigen::Index i = 0; i < middle.size(); ++i) {
    const auto& limits = model->limits[static_cast<std::size_t>(i)];
    middle[i] = 0.5 * limits.min_position + 0.5 * limits.max_position;
  }
  require_finite_kinematics(*model, middle, "the middle of the joint ranges", input);

  geotraj::v1::RobotModel wire;
  geotraj::server::to_proto(*model, wire);
  auto again = geotraj::server::robot_model_from_proto(wire, "");
  if (!again) fail("the model's own wire form is refused: " + again.error().front().field + " " +
                       again.error().front().description, input);
  geotraj::v1::RobotModel wire_again;
  geotraj::server::to_proto(*again, wire_again);
  if (!google::protobuf::util::MessageDifferencer::Equals(wire, wire_again)) {
    fail("the model changes in the round trip through its wire form:\n" + wire.ShortDebugString() + "\n" +
             wire_again.ShortDebugString(), input);
  }
  return 0;
}
