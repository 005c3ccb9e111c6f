// MoveIt's joint_limits.yaml read with yaml-cpp. See joint_limits_yaml.hpp.
#include "planner/joint_limits_yaml.hpp"

#include <algorithm>
#include <exception>
#include <optional>
#include <utility>

#include <yaml-cpp/yaml.h>

#include "core/format.hpp"

namespace geotraj::planner {

namespace {

// Flow collections ([...], {...}) nested deeper than this are refused before the parse: a
// joint_limits.yaml nests two levels of block mappings (yaml-cpp's own guard stops at 2000
// levels of either kind).
constexpr int kMaxFlowDepth = 64;

bool flow_too_deep(std::string_view text) {
  int depth = 0;
  for (const char c : text) {
    if (c == '[' || c == '{') {
      if (++depth > kMaxFlowDepth) return true;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return false;
}

// "line 4, joint_limits.panda_joint1.max_velocity" (the parser's lines are from 0).
std::string where(const YAML::Node& node, const std::string& path) {
  const YAML::Mark mark = node.Mark();
  return (mark.line >= 0 ? "line " + std::to_string(mark.line + 1) + ", " : std::string()) + path;
}

// The kinds of limit a joint may give: its flag, its value's key, the unit and the field of
// NamedLimits it sets.
struct Kind {
  const char* flag;
  const char* key;
  const char* unit;
  std::optional<double> NamedLimits::*to;
};
constexpr Kind kKinds[] = {
    {"has_velocity_limits", "max_velocity", "rad/s or m/s", &NamedLimits::max_velocity},
    {"has_acceleration_limits", "max_acceleration", "rad/s^2 or m/s^2", &NamedLimits::max_acceleration},
    {"has_jerk_limits", "max_jerk", "rad/s^3 or m/s^3", &NamedLimits::max_jerk},
    {"has_effort_limits", "max_effort", "N m or N", &NamedLimits::max_torque},
};

}  // namespace

core::Expected<std::vector<NamedLimits>> joint_limits_from_yaml(std::string_view text, const std::string& field) {
  core::Violations out;
  const auto refuse = [&](std::string why) {
    out.push_back({field, std::move(why)});
    return tl::unexpected(std::move(out));
  };
  if (text.size() > kMaxJointLimitsYamlBytes)
    return refuse("is " + std::to_string(text.size()) + " bytes, more than a joint_limits.yaml may be (" +
                  std::to_string(kMaxJointLimitsYamlBytes) + ")");
  if (flow_too_deep(text))
    return refuse("nests [ ] or { } more than " + std::to_string(kMaxFlowDepth) + " deep: not a joint_limits.yaml");
  YAML::Node root;
  try {
    root = YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    return refuse("is not YAML: line " + std::to_string(e.mark.line + 1) + ", column " +
                  std::to_string(e.mark.column + 1) + ": " + e.msg);
  } catch (const std::exception& e) {
    return refuse(std::string("is not YAML: ") + e.what());
  }
  try {
    const YAML::Node joints = root.IsMap() ? root["joint_limits"] : YAML::Node();
    if (!joints || !joints.IsMap())
      return refuse("has no `joint_limits` mapping (MoveIt's joint_limits.yaml: joint_limits: JOINT: "
                    "has_velocity_limits, max_velocity, ...)");
    std::vector<NamedLimits> limits;
    for (const auto& entry : joints) {
      const std::string name = entry.first.IsScalar() ? entry.first.Scalar() : std::string();
      const std::string path = "joint_limits." + name;
      if (name.empty()) {
        out.push_back({field, where(entry.first, "joint_limits") + ": a joint's name must be a string"});
        continue;
      }
      if (std::any_of(limits.begin(), limits.end(), [&](const NamedLimits& l) { return l.joint == name; })) {
        out.push_back({field, where(entry.first, path) + ": the joint is named twice"});
        continue;
      }
      const YAML::Node& joint = entry.second;
      if (!joint.IsMap()) {
        out.push_back({field, where(joint, path) + ": must be a mapping of has_..._limits and max_... keys"});
        continue;
      }
      NamedLimits l{name, std::nullopt, std::nullopt, std::nullopt};
      for (const Kind& kind : kKinds) {
        const YAML::Node flag = joint[kind.flag];
        bool on = false;
        if (flag && !(flag.IsScalar() && YAML::convert<bool>::decode(flag, on))) {
          out.push_back({field, where(flag, path + "." + kind.flag) + ": must be true or false"});
          continue;
        }
        const YAML::Node value = joint[kind.key];
        if (!on) continue;  // MoveIt's rule: no flag, no limit
        if (!value) {
          out.push_back({field, where(flag, path + "." + kind.flag) + ": is true but " + kind.key + " is missing"});
          continue;
        }
        double x = 0.0;
        if (!(value.IsScalar() && YAML::convert<double>::decode(value, x))) {
          out.push_back({field, where(value, path + "." + kind.key) + ": must be a number"});
          continue;
        }
        if (auto bad = core::joint_limit_violation(field, x, kind.unit)) {
          out.push_back({field, where(value, path + "." + kind.key) + ": " + bad->description});
          continue;
        }
        l.*kind.to = x;
      }
      limits.push_back(std::move(l));
    }
    if (!out.empty()) return tl::unexpected(std::move(out));
    return limits;
  } catch (const std::exception& e) {  // yaml-cpp's conversions of a malformed node
    return refuse(std::string("cannot be read: ") + e.what());
  }
}

}  // namespace geotraj::planner
