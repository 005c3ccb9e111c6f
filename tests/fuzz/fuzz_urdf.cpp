// fuzz_urdf: bytes as a URDF document (RobotSpec.urdf from a client, `geotrajd --robot-model
// arm.urdf`), read by planner::robot_from_urdf with the options (UrdfOptions: baseLink,
// tipLink, the request's jointLimits) the fuzzer may also
// choose. No server: the reader is called directly.
//
// Input: when the first byte is 0x00-0x07 (C0 controls that no XML document may contain, so
// a URDF file used as a seed as it is never starts with one) it is a selector, and what it
// selects follows in this order:
//   bit 2: an options byte (bit 0 unused);
//          bits 1-2, how many jointLimits entries (0-3) follow the links;
//   bit 0: the baseLink;  bit 1: the tipLink;
//   then each jointLimits entry: its joint name, then three bytes, maxVelocity, maxAcceleration
//   and maxJerk, each absent when 0, else byte / 4 (finite and > 0, as the caller checks);
// each name being the bytes up to the next '\n' (consumed) or kMaxName bytes, whichever comes
// first; the rest is the document. Any other first byte: the whole input is the document with
// the default options (the root, the default leaf).
//
// A model it accepts must
//  - pass core::validate_robot, with 1 to core::kMaxJoints joints and one limit per joint;
//  - have every limit, joint origin, axis, the flange and home finite, home one per joint;
//  - have a finite tool pose and Jacobian at its home configuration and at the middle of its
//    joint ranges.
// A document it refuses must come with at least one violation, each with a field among
// "urdf", "baseLink" and "tipLink" and a non-empty description. Every name of a model and
// every description is well-formed UTF-8 (a character reference may not smuggle in what the
// document's own UTF-8 check refuses).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"
#include "planner/robots.hpp"
#include "tests/support/utf8.hpp"

namespace {

using geotraj::test::well_formed_utf8;

/// The longest name (baseLink, tipLink, a jointLimits joint) the selector reads [bytes].
constexpr std::size_t kMaxName = 64;

struct Input {
  geotraj::planner::UrdfOptions options;
  std::string_view urdf;
};

std::string_view take_name(std::string_view& rest) {
  const std::size_t newline = rest.substr(0, kMaxName).find('\n');
  const std::size_t length = newline == std::string_view::npos ? std::min(rest.size(), kMaxName) : newline;
  const std::string_view name = rest.substr(0, length);
  rest.remove_prefix(std::min(rest.size(), newline == std::string_view::npos ? length : length + 1));
  return name;
}

std::optional<double> take_limit(std::string_view& rest) {
  if (rest.empty()) return std::nullopt;
  const auto b = static_cast<unsigned char>(rest.front());
  rest.remove_prefix(1);
  if (b == 0) return std::nullopt;
  return b / 4.0;
}

Input split(const std::uint8_t* data, std::size_t size) {
  Input in;
  std::string_view rest(reinterpret_cast<const char*>(data), size);
  if (rest.empty() || static_cast<unsigned char>(rest.front()) > 0x07) {
    in.urdf = rest;
    return in;
  }
  const auto selector = static_cast<unsigned char>(rest.front());
  rest.remove_prefix(1);
  unsigned char options = 0;
  if ((selector & 4u) != 0 && !rest.empty()) {
    options = static_cast<unsigned char>(rest.front());
    rest.remove_prefix(1);
  }
  if ((selector & 1u) != 0) in.options.base_link = std::string(take_name(rest));
  if ((selector & 2u) != 0) in.options.tip_link = std::string(take_name(rest));
  for (unsigned k = 0; k < ((options >> 1) & 3u); ++k) {
    geotraj::planner::NamedLimits limits;
    limits.joint = std::string(take_name(rest));
    limits.max_velocity = take_limit(rest);
    limits.max_acceleration = take_limit(rest);
    limits.max_jerk = take_limit(rest);
    in.options.limits.push_back(std::move(limits));
  }
  in.urdf = rest;
  return in;
}

std::string number(const std::optional<double>& x) { return x ? std::to_string(*x) : std::string("-"); }

std::string printable(std::string_view s, std::size_t limit) {
  std::string out;
  for (const char c : s.substr(0, std::min(s.size(), limit))) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '\n' || c == '\t' || (u >= 0x20 && u < 0x7f)) {
      out += c;
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", u);
      out += hex;
    }
  }
  if (s.size() > limit) out += "\n[... " + std::to_string(s.size() - limit) + " more bytes]";
  return out;
}

[[noreturn]] void fail(const std::string& why, const Input& in) {
  std::string limits;
  for (const auto& l : in.options.limits) {
    limits += " {joint '" + printable(l.joint, kMaxName) + "' velocity " + number(l.max_velocity) + " acceleration " +
              number(l.max_acceleration) + " jerk " + number(l.max_jerk) + "}";
  }
  std::fprintf(stderr,
               "\n==== geotraj fuzz check failed: %s\n==== baseLink: '%s'\n==== tipLink: '%s'\n"
               "==== jointLimits:%s\n==== urdf (%zu bytes):\n%s\n\n",
               why.c_str(), printable(in.options.base_link, kMaxName).c_str(),
               printable(in.options.tip_link, kMaxName).c_str(),
               limits.c_str(), in.urdf.size(), printable(in.urdf, 4000).c_str());
  std::abort();
}

bool finite(double x) { return std::isfinite(x); }

void check_refusal(const geotraj::core::Violations& violations, const Input& in) {
  if (violations.empty()) fail("refused without a violation", in);
  for (const auto& v : violations) {
    if (v.field != "urdf" && v.field != "baseLink" && v.field != "tipLink") {
      fail("a violation names the field '" + v.field + "', not urdf, baseLink or tipLink (" + v.description + ")",
           in);
    }
    if (v.description.empty()) fail("a violation of '" + v.field + "' has no description", in);
    if (!well_formed_utf8(v.description)) fail("a violation of '" + v.field + "' is not UTF-8: " + printable(v.description, 400), in);
  }
}

void require_finite_kinematics(const geotraj::core::RobotModel& model, const geotraj::core::JointVector& q,
                               const char* where, const Input& in) {
  if (!geotraj::core::forward_kinematics(model, q).matrix().allFinite()) {
    fail(std::string("forward_kinematics(model, q) at ") + where + " is not finite", in);
  }
  Eigen::Isometry3d X_WT;
  geotraj::core::JointJacobian J;
  geotraj::core::forward_kinematics(model, q, X_WT, J);
  if (!X_WT.matrix().allFinite()) fail(std::string("the tool pose at ") + where + " is not finite", in);
  if (!J.allFinite()) fail(std::string("the Jacobian at ") + where + " is not finite", in);
}

void check_model(const geotraj::core::RobotModel& model, const Input& in) {
  using geotraj::core::kMaxJoints;
  if (const auto violations = geotraj::core::validate_robot(model); !violations.empty()) {
    fail("the model fails validate_robot: " + violations.front().field + " " + violations.front().description +
             " (" + std::to_string(violations.size()) + " in all)",
         in);
  }
  const std::size_t n = model.dof();
  if (n < 1 || n > kMaxJoints) {
    fail("the model has " + std::to_string(n) + " joints, not 1 to " + std::to_string(kMaxJoints), in);
  }
  if (!well_formed_utf8(model.name) || !well_formed_utf8(model.description)) fail("the model's name or description is not UTF-8", in);
  for (const auto& joint : model.joints) {
    if (!well_formed_utf8(joint.name)) fail("a joint name is not UTF-8: " + printable(joint.name, 200), in);
  }
  if (model.limits.size() != n) fail("the model has " + std::to_string(model.limits.size()) + " limits", in);
  if (model.home.size() != n) fail("the model's home has " + std::to_string(model.home.size()) + " values", in);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& joint = model.joints[i];
    const auto& l = model.limits[i];
    const std::string at = "joint " + std::to_string(i) + " ('" + joint.name + "')";
    if (joint.name.empty()) fail(at + " has no name", in);
    if (!joint.origin.matrix().allFinite()) fail(at + ": the origin is not finite", in);
    if (!joint.axis.allFinite()) fail(at + ": the axis is not finite", in);
    if (!finite(l.min_position) || !finite(l.max_position) || !finite(l.max_velocity) ||
        !finite(l.max_acceleration) || (l.max_jerk && !finite(*l.max_jerk))) {
      fail(at + ": a limit is not finite", in);
    }
    if (!finite(model.home[i])) fail(at + ": home is not finite", in);
  }
  if (!model.flange.matrix().allFinite()) fail("the flange is not finite", in);

  const geotraj::core::JointVector home = geotraj::core::home_configuration(model);
  if (static_cast<std::size_t>(home.size()) != n) fail("home_configuration has the wrong size", in);
  require_finite_kinematics(model, home, "home", in);
  geotraj::core::JointVector middle(home.size());
  for (Eigen::Index i = 0; i < middle.size(); ++i) {
    const auto& l = model.limits[static_cast<std::size_t>(i)];
    middle[i] = 0.5 * l.min_position + 0.5 * l.max_position;
  }
  require_finite_kinematics(model, middle, "the middle of the joint ranges", in);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const Input in = split(data, size);
  const auto model = geotraj::planner::robot_from_urdf(in.urdf, in.options);
  if (model) {
    check_model(*model, in);
  } else {
    check_refusal(model.error(), in);
  }
  return 0;
}
