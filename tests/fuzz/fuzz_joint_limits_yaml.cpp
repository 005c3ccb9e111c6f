// fuzz_joint_limits_yaml: bytes as MoveIt's joint_limits.yaml (RobotSpec.jointLimitsYaml from
// a client, `geotrajd --joint-limits FILE`), read by planner::joint_limits_from_yaml. No
// server: the reader is called directly.
//
// What it reads must be limits a request could give: one entry per joint, each named, each
// name once, every value finite and within [core::kMinJointLimit, core::kMaxJointLimit]; a
// file it refuses must come with at least one violation, each of the field given, with a
// non-empty description. Merging the limits over themselves changes nothing.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "core/robot/robot.hpp"
#include "planner/joint_limits_yaml.hpp"

namespace {

[[noreturn]] void fail(const std::string& why) {
  std::fprintf(stderr, "fuzz_joint_limits_yaml: %s\n", why.c_str());
  std::abort();
}

void check_value(const std::optional<double>& v, const std::string& what) {
  if (v && !geotraj::core::within_joint_limit_range(*v)) fail(what + " outside the range of limits");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const auto read = geotraj::planner::joint_limits_from_yaml(text, "robot.jointLimitsYaml");
  if (!read) {
    if (read.error().empty()) fail("refused without a violation");
    for (const auto& v : read.error()) {
      if (v.field != "robot.jointLimitsYaml") fail("a violation of another field: " + v.field);
      if (v.description.empty()) fail("a violation without a description");
    }
    return 0;
  }
  std::set<std::string> names;
  for (const auto& l : *read) {
    if (l.joint.empty()) fail("a joint without a name");
    if (!names.insert(l.joint).second) fail("joint '" + l.joint + "' read twice");
    check_value(l.max_velocity, l.joint + " max_velocity");
    check_value(l.max_acceleration, l.joint + " max_acceleration");
    check_value(l.max_jerk, l.joint + " max_jerk");
    check_value(l.max_torque, l.joint + " max_effort");
  }
  // Whatever the reader accepts makes a valid model of the joints it names.
  geotraj::core::RobotModel panda = *geotraj::planner::find_builtin_robot("panda");
  std::vector<geotraj::planner::NamedLimits> renamed = *read;
  for (auto& l : renamed) l.joint = "panda_joint" + std::to_string(1 + std::hash<std::string>{}(l.joint) % 7);
  geotraj::planner::apply_named_limits(renamed, panda);
  if (const auto bad = geotraj::core::validate_robot(panda); !bad.empty())
    fail("the limits read make an invalid model: " + bad.front().field + " " + bad.front().description);
  return 0;
}
