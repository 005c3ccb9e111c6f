// A URDF document read into a core::RobotModel through urdfdom: its text checked
// (urdf_checks.cpp), the link tree, the chain from the base to the tip, the <geotraj> block.
// See robots.hpp.
#include "planner/robots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <console_bridge/console.h>
#include <tinyxml.h>
#include <urdf_parser/urdf_parser.h>

#include "core/format.hpp"
#include "planner/urdf_detail.hpp"

namespace geotraj::planner {
namespace {

using core::Violations;
using namespace urdf_detail;

// urdfdom reports what it refuses through console_bridge, a process-wide logger. One handler,
// installed once, keeps each thread's messages in that thread's buffer (no console output,
// no interleaving between concurrent parses).
class Capture final : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level < console_bridge::CONSOLE_BRIDGE_LOG_ERROR) return;  // warnings: not ours to print
    std::string& b = buffer();
    if (!b.empty()) b += "; ";
    b += text;
  }
  static std::string& buffer() {
    thread_local std::string b;
    return b;
  }
};

void install_capture() {
  static std::once_flag once;
  std::call_once(once, [] {
    static Capture capture;
    console_bridge::useOutputHandler(&capture);
  });
}

// Where an element sits, for messages: "line 12, joint 'elbow'".
std::string where(const TiXmlElement* e) {
  std::string out = "line " + std::to_string(e->Row()) + ", " + e->Value();
  if (const char* name = e->Attribute("name")) out += std::string(" '") + name + "'";
  return out;
}

// The first child of `root` of kind `tag` named `name`, or nullptr (for a message's line).
const TiXmlElement* find_named(const TiXmlElement* root, const char* tag, const std::string& name) {
  for (const TiXmlElement* e = root->FirstChildElement(tag); e != nullptr; e = e->NextSiblingElement(tag)) {
    if (const char* n = e->Attribute("name"); n != nullptr && name == n) return e;
  }
  return nullptr;
}

// "[name]" in a urdfdom message: the joint or link it is about, to point at its line.
std::string bracketed_name(const std::string& message) {
  const auto open = message.find('[');
  const auto close = open == std::string::npos ? std::string::npos : message.find(']', open);
  return close == std::string::npos ? std::string{} : message.substr(open + 1, close - open - 1);
}

// A number attribute of the <geotraj> block: absent (nullopt), or finite, or an error.
bool read_number(const TiXmlElement* e, const char* attribute, std::optional<double>& out, Violations& v) {
  const char* text = e->Attribute(attribute);
  if (text == nullptr) return true;
  char* end = nullptr;
  const double x = std::strtod(text, &end);
  while (end != nullptr && *end == ' ') ++end;
  if (end == text || end == nullptr || *end != '\0' || !std::isfinite(x)) {
    v.push_back({"urdf", where(e) + ": " + attribute + "=\"" + text + "\" is not a finite number"});
    return false;
  }
  out = x;
  return true;
}

Eigen::Isometry3d isometry(const urdf::Pose& pose) {
  double x = 0, y = 0, z = 0, w = 1;
  pose.rotation.getQuaternion(x, y, z, w);
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::Quaterniond(w, x, y, z).normalized().toRotationMatrix();
  X.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  return X;
}

std::string listed(const std::vector<std::string>& names) {
  constexpr std::size_t kShown = 12;
  std::string out;
  for (std::size_t i = 0; i < names.size() && i < kShown; ++i) out += (i ? ", '" : "'") + names[i] + "'";
  if (names.size() > kShown) out += ", ... (" + std::to_string(names.size()) + " in all)";
  return out;
}

std::string joint_kind(int type) {
  switch (type) {
    case urdf::Joint::FLOATING: return "floating";
    case urdf::Joint::PLANAR: return "planar";
    default: return "unknown";
  }
}

// The link tree, from the document itself before urdfdom builds it (urdfdom accepts a loop
// of links beside a root, and leaks it): every link the child of one joint at most, no loop.
void check_link_tree(const TiXmlElement* robot, Violations& v) {
  std::map<std::string, const TiXmlElement*> parent_joint;  // child link -> its joint
  for (const TiXmlElement* j = robot->FirstChildElement("joint"); j != nullptr; j = j->NextSiblingElement("joint")) {
    const TiXmlElement* child = j->FirstChildElement("child");
    const char* link = child ? child->Attribute("link") : nullptr;
    if (link == nullptr) continue;  // urdfdom names it
    const auto [it, fresh] = parent_joint.emplace(link, j);
    if (!fresh) {
      v.push_back({"urdf", where(j) + ": link '" + link + "' is already the child of " + where(it->second) +
                               ": a link has one parent joint"});
    }
  }
  if (!v.empty()) return;
  // Up from every link, each link visited once in all: meeting the walk's own trail is a loop.
  std::map<std::string, int> state;  // 1: on the current walk, 2: known to reach the root
  for (const auto& [link, joint] : parent_joint) {
    std::vector<std::string> trail;
    std::string at = link;
    for (;;) {
      int& st = state[at];
      if (st == 2) break;
      if (st == 1) {
        v.push_back({"urdf", where(parent_joint.at(at)) + ": the links form a loop through link '" + at +
                                 "' (a URDF is a tree: every chain of parents ends at the root)"});
        return;
      }
      st = 1;
      trail.push_back(at);
      const auto it = parent_joint.find(at);
      const TiXmlElement* parent = it == parent_joint.end() ? nullptr : it->second->FirstChildElement("parent");
      const char* up = parent ? parent->Attribute("link") : nullptr;
      if (up == nullptr) break;
      at = up;
    }
    for (const auto& l : trail) state[l] = 2;
  }
}

// The side block: per joint name, its element.
struct SideBlock {
  const TiXmlElement* element = nullptr;
  std::vector<const TiXmlElement*> joints;
};

}  // namespace

core::Expected<core::RobotModel> robot_from_urdf(std::string_view text, const UrdfOptions& options) {
  Violations v;
  std::string_view base_link = options.base_link, tip_link = options.tip_link;
  if (text.size() > kMaxUrdfBytes) {
    v.push_back({"urdf", "has " + std::to_string(text.size()) + " bytes; at most " + std::to_string(kMaxUrdfBytes)});
    return tl::unexpected(std::move(v));
  }
  // Between the stages below: the call's deadline or cancellation.
  const auto given_up = [] {
    return core::Violations{{"urdf", "was not read whole: the call's deadline passed or it was cancelled"}};
  };
  if (options.stop_at.reached()) return tl::unexpected(given_up());
  if (const std::size_t at = invalid_utf8(text); at != std::string_view::npos) {
    v.push_back({"urdf", "is not UTF-8: " + line_at(text, at) + ", byte " + std::to_string(at)});
    return tl::unexpected(std::move(v));
  }
  for (const auto& check : {forbidden_control, bad_reference, check_markup}) {
    if (options.stop_at.reached()) return tl::unexpected(given_up());
    if (const std::optional<Refusal> r = check(text)) {
      v.push_back({"urdf", (r->malformed ? "is not well-formed XML: " : "") + line_at(text, r->at) + ": " + r->what});
      return tl::unexpected(std::move(v));
    }
  }
  if (options.stop_at.reached()) return tl::unexpected(given_up());
  std::string xml(text);
  xml.append(4, '\0');  // whatever a parser reads past the end of a character is ours
  // The document first, for the line of whatever is wrong (urdfdom says what, not where).
  TiXmlDocument doc;
  doc.Parse(xml.c_str(), nullptr, TIXML_ENCODING_UTF8);
  if (doc.Error()) {
    v.push_back({"urdf", "is not well-formed XML: line " + std::to_string(doc.ErrorRow()) + ", column " +
                             std::to_string(doc.ErrorCol()) + ": " + doc.ErrorDesc()});
    return tl::unexpected(std::move(v));
  }
  const TiXmlElement* robot = doc.RootElement();
  if (robot == nullptr || std::string(robot->Value()) != "robot") {
    v.push_back({"urdf", robot == nullptr ? std::string("has no root element: a URDF document is one <robot>")
                                          : where(robot) + ": the root element must be <robot>"});
    return tl::unexpected(std::move(v));
  }

  if (options.stop_at.reached()) return tl::unexpected(given_up());
  check_link_tree(robot, v);
  if (!v.empty()) return tl::unexpected(std::move(v));
  if (options.stop_at.reached()) return tl::unexpected(given_up());

  install_capture();
  Capture::buffer().clear();
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(xml);
  if (options.stop_at.reached()) return tl::unexpected(given_up());
  if (!model) {
    std::string message = Capture::buffer();
    if (message.empty()) message = "urdfdom refused the document";
    const std::string name = bracketed_name(message);
    message = shown(message, 512);  // it may quote a whole attribute
    const TiXmlElement* at = name.empty() ? nullptr : find_named(robot, "joint", name);
    if (at == nullptr && !name.empty()) at = find_named(robot, "link", name);
    v.push_back({"urdf", (at ? where(at) + ": " : std::string()) + message});
    return tl::unexpected(std::move(v));
  }

  // The chain: base (default: the <geotraj> block's base_link, else the root) down to the tip
  // (default: the block's tip_link, else the leaf below the base reached through the most
  // moving joints, where only one is).
  const TiXmlElement* block = robot->FirstChildElement("geotraj");
  std::string block_base, block_tip;
  if (block != nullptr) {
    if (const char* b = block->Attribute("base_link"); b != nullptr && base_link.empty()) block_base = b;
    if (const char* t = block->Attribute("tip_link"); t != nullptr && tip_link.empty()) block_tip = t;
  }
  if (!block_base.empty()) base_link = block_base;
  if (!block_tip.empty()) tip_link = block_tip;
  urdf::LinkConstSharedPtr base = base_link.empty() ? model->getRoot() : model->getLink(std::string(base_link));
  std::vector<std::string> link_names;
  {
    std::vector<urdf::LinkSharedPtr> links;
    model->getLinks(links);
    for (const auto& l : links) link_names.push_back(l->name);
  }
  if (!base) {
    v.push_back({"baseLink", "names no link of the URDF ('" + quotable(base_link) + "'); its links: " +
                                 listed(link_names)});
    return tl::unexpected(std::move(v));
  }
  urdf::LinkConstSharedPtr tip;
  if (tip_link.empty()) {
    // The leaf reached through the most moving joints (a maker's tool0 beside a `base` frame,
    // a flange beside a sensor's mounting frames on a shorter branch), where it is the only one.
    std::vector<std::pair<std::string, std::size_t>> leaves;  // name, moving joints from the base
    std::vector<std::pair<urdf::LinkConstSharedPtr, std::size_t>> stack{{base, 0}};
    std::size_t most = 0;
    while (!stack.empty()) {  // a tree (check_link_tree): each link once
      const auto [l, moving] = stack.back();
      stack.pop_back();
      if (l->child_links.empty()) {
        leaves.emplace_back(l->name, moving);
        if (leaves.size() == 1 || moving > most) most = moving, tip = l;
      }
      for (const auto& c : l->child_links) {
        const bool moves = c->parent_joint && c->parent_joint->type != urdf::Joint::FIXED;
        stack.emplace_back(c, moving + (moves ? 1 : 0));
      }
    }
    std::vector<std::string> candidates;
    for (const auto& [name, moving] : leaves)
      if (moving == most) candidates.push_back(name);
    if (candidates.size() > 1) {
      std::sort(candidates.begin(), candidates.end());
      v.push_back({"tipLink", "is needed: the URDF branches below '" + base->name + "' into " +
                                  std::to_string(leaves.size()) + " leaf links, " + std::to_string(candidates.size()) +
                                  " of them through " + std::to_string(most) + " moving joints (" +
                                  listed(candidates) + "); name the one the tool is on"});
      return tl::unexpected(std::move(v));
    }
  } else {
    tip = model->getLink(std::string(tip_link));
    if (!tip) {
      v.push_back({"tipLink", "names no link of the URDF ('" + quotable(tip_link) + "'); its links: " +
                                  listed(link_names)});
      return tl::unexpected(std::move(v));
    }
  }
  std::vector<urdf::JointConstSharedPtr> path;  // tip to base
  for (urdf::LinkConstSharedPtr l = tip; l != base;) {
    if (!l->parent_joint || path.size() > link_names.size()) {
      v.push_back({"tipLink", "'" + tip->name + "' is not below the base link '" + base->name + "'"});
      return tl::unexpected(std::move(v));
    }
    path.push_back(l->parent_joint);
    l = model->getLink(l->parent_joint->parent_link_name);
  }
  std::reverse(path.begin(), path.end());
  const auto moving = std::count_if(path.begin(), path.end(), [](const auto& j) { return j->type != urdf::Joint::FIXED; });
  if (static_cast<std::size_t>(moving) > core::kMaxJoints) {  // before any work per joint
    v.push_back({"urdf", "the chain from '" + base->name + "' to '" + tip->name + "' has " + std::to_string(moving) +
                             " moving joints; at most " + std::to_string(core::kMaxJoints) + " are supported"});
    return tl::unexpected(std::move(v));
  }
  std::map<std::string, const TiXmlElement*> joint_elements;  // for the lines of messages
  for (const TiXmlElement* e = robot->FirstChildElement("joint"); e != nullptr; e = e->NextSiblingElement("joint")) {
    if (const char* n = e->Attribute("name")) joint_elements.emplace(n, e);
  }

  core::RobotModel m;
  m.name = model->getName();
  Eigen::Isometry3d pending = Eigen::Isometry3d::Identity();  // fixed joints since the last moving one
  std::vector<const TiXmlElement*> elements;                  // each moving joint's element
  // Mass properties: each moving joint's child link with the links fixed to it (their frames
  // in it: `pending`), in the joint's frame after its motion; links before the first moving
  // joint stand with the base, links off the chain (a hand's fingers) are not counted. A link
  // without <inertial> has none (URDF: zero mass).
  std::vector<core::Inertial> bodies;
  std::vector<std::string> body_links;  // each body's moving link, for messages
  bool any_inertial = false;
  const auto add_link = [&](const std::string& name, const Eigen::Isometry3d& X_body_link) {
    const urdf::LinkConstSharedPtr link = model->getLink(name);
    if (bodies.empty() || !link || !link->inertial) return;
    any_inertial = true;
    const urdf::Inertial& in = *link->inertial;
    core::Inertial body{in.mass, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero()};
    body.inertia << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
    bodies.back() = core::combined(bodies.back(), core::in_frame(body, X_body_link * isometry(in.origin)));
  };
  for (const auto& j : path) {
    const auto found = joint_elements.find(j->name);
    const TiXmlElement* e = found == joint_elements.end() ? nullptr : found->second;
    const std::string at = e ? where(e) : "joint '" + j->name + "'";
    const Eigen::Isometry3d origin = isometry(j->parent_to_joint_origin_transform);
    if (j->type == urdf::Joint::FIXED) {
      pending = pending * origin;
      add_link(j->child_link_name, pending);
      continue;
    }
    if (j->type != urdf::Joint::REVOLUTE && j->type != urdf::Joint::CONTINUOUS &&
        j->type != urdf::Joint::PRISMATIC) {
      v.push_back({"urdf", at + ": a " + joint_kind(j->type) +
                               " joint is not a joint of a serial arm (revolute, continuous, prismatic or fixed)"});
      continue;
    }
    if (j->mimic) {
      v.push_back({"urdf", at + ": mimics joint '" + j->mimic->joint_name +
                               "'; mimic joints are not supported on the chain (give the chain without it)"});
      continue;
    }
    core::Joint joint;
    joint.name = j->name;
    joint.type = j->type == urdf::Joint::PRISMATIC    ? core::JointType::kPrismatic
                 : j->type == urdf::Joint::CONTINUOUS ? core::JointType::kContinuous
                                                      : core::JointType::kRevolute;
    joint.origin = pending * origin;
    pending = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d axis(j->axis.x, j->axis.y, j->axis.z);
    if (!axis.allFinite() || axis.norm() < 1e-9) {
      v.push_back({"urdf", at + ": <axis xyz> must be a non-zero vector"});
      continue;
    }
    joint.axis = axis.normalized();
    core::JointLimits limits;
    if (!j->limits && joint.type != core::JointType::kContinuous) {
      v.push_back({"urdf", at + ": has no <limit> (lower, upper, velocity)"});
    } else if (!j->limits || !(std::isfinite(j->limits->velocity) && j->limits->velocity > 0.0)) {
      v.push_back({"urdf", at + ": <limit velocity> must be given, finite and > 0"});
    } else {
      limits.max_velocity = j->limits->velocity;
      if (joint.type != core::JointType::kContinuous) {
        limits.min_position = j->limits->lower;
        limits.max_position = j->limits->upper;
        if (!(std::isfinite(limits.min_position) && std::isfinite(limits.max_position) &&
              limits.min_position <= limits.max_position)) {
          v.push_back({"urdf", at + ": <limit lower=\"" + core::number(limits.min_position) + "\" upper=\"" +
                                   core::number(limits.max_position) + "\"> must be finite with lower <= upper"});
        }
      }
    }
    if (j->limits && j->limits->effort > 0.0) limits.max_torque = j->limits->effort;
    m.joints.push_back(std::move(joint));
    m.limits.push_back(limits);
    elements.push_back(e);
    bodies.push_back(core::Inertial{0.0, Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero()});
    body_links.push_back(j->child_link_name);
    add_link(j->child_link_name, Eigen::Isometry3d::Identity());
  }
  m.flange = pending;
  // Mass properties that no body has (CAD exports and placeholders often break the triangle
  // inequality) leave the model without dynamics rather than refuse its kinematics: its
  // description says why.
  std::string no_dynamics;
  if (any_inertial && bodies.size() == m.joints.size()) {
    Violations unphysical;
    for (std::size_t i = 0; i < bodies.size(); ++i)
      core::check_inertial("link '" + body_links[i] + "' <inertial>", bodies[i], unphysical);
    if (unphysical.empty()) {
      for (std::size_t i = 0; i < bodies.size(); ++i) m.joints[i].inertial = bodies[i];
    } else {
      no_dynamics = " (no dynamics: " + unphysical.front().field + " " + unphysical.front().description + ")";
    }
  }
  if (m.joints.empty() && v.empty()) {
    v.push_back({"urdf", "the chain from '" + base->name + "' to '" + tip->name + "' has no moving joint"});
  }

  // The <geotraj> block: accelerations, jerks, home, description.
  SideBlock side;
  side.element = block;
  if (side.element != nullptr) {
    if (const char* d = side.element->Attribute("description")) m.description = d;
    for (const TiXmlElement* e = side.element->FirstChildElement(); e != nullptr; e = e->NextSiblingElement()) {
      if (std::string(e->Value()) != "joint" || e->Attribute("name") == nullptr) {
        v.push_back({"urdf", where(e) + ": the <geotraj> block holds <joint name=\"..\" max_acceleration=\"..\" "
                                        "max_jerk=\"..\" home=\"..\"/> elements only"});
        continue;
      }
      const std::string name = e->Attribute("name");
      const auto it = std::find_if(m.joints.begin(), m.joints.end(), [&](const core::Joint& j) { return j.name == name; });
      if (it == m.joints.end()) {  // a joint off the chain is someone else's; no joint at all is a typo
        const urdf::JointConstSharedPtr j = model->getJoint(name);
        if (!j || j->type == urdf::Joint::FIXED) {
          v.push_back({"urdf", where(e) + ": the URDF has no moving joint '" + name + "'"});
        }
        continue;
      }
      side.joints.push_back(e);
    }
  }
  if (m.description.empty()) m.description = "URDF robot '" + m.name + "'";
  m.description += no_dynamics;
  m.home.assign(m.joints.size(), 0.0);
  m.limit_sources.assign(m.joints.size(), core::LimitSources{});
  for (std::size_t i = 0; i < m.joints.size(); ++i) {
    const std::string& name = m.joints[i].name;
    const TiXmlElement* entry = nullptr;
    for (const TiXmlElement* e : side.joints) {
      if (name == e->Attribute("name")) entry = e;
    }
    core::LimitSources& from = m.limit_sources[i];
    const std::string limit_at = elements[i] ? ", " + where(elements[i]) : "";
    from.velocity = "URDF <limit velocity>" + limit_at;
    if (m.limits[i].max_torque) from.torque = "URDF <limit effort>" + limit_at;
    std::optional<double> acceleration, jerk, home;
    if (entry != nullptr) {
      read_number(entry, "max_acceleration", acceleration, v);
      read_number(entry, "max_jerk", jerk, v);
      read_number(entry, "home", home, v);
      if (acceleration && !(*acceleration > 0.0)) v.push_back({"urdf", where(entry) + ": max_acceleration must be > 0"});
      if (jerk && !(*jerk > 0.0)) v.push_back({"urdf", where(entry) + ": max_jerk must be > 0"});
      if (acceleration) from.acceleration = "URDF <geotraj> block, " + where(entry);
      if (jerk) from.jerk = "URDF <geotraj> block, " + where(entry);
    }
    // Unknown: kinematics only, until a request's or a file's limits give one (resolve_robot).
    from.acceleration_known = acceleration.has_value();
    m.limits[i].max_acceleration = acceleration.value_or(kUnknownAcceleration);
    m.limits[i].max_jerk = jerk;
    const core::JointLimits& l = m.limits[i];
    const bool continuous = m.joints[i].type == core::JointType::kContinuous;
    if (home) {
      if (!core::within_position_limits(m.joints[i].type, l, *home) || std::abs(*home) > core::kMaxModelMagnitude) {
        v.push_back({"urdf", where(entry) + ": home " + core::number(*home) + " is outside the joint's limits [" +
                                 core::number(l.min_position) + ", " + core::number(l.max_position) + "]"});
      }
      m.home[i] = *home;
    } else if (!continuous && (l.min_position > 0.0 || l.max_position < 0.0)) {
      m.home[i] = 0.5 * (l.min_position + l.max_position);  // 0 is outside the range: its middle
    }
  }
  if (!v.empty()) return tl::unexpected(std::move(v));
  apply_named_limits(options.limits, m);  // checked by the caller; a joint off the chain is not ours
  if (Violations rest = core::validate_robot(m); !rest.empty()) {  // the model it makes (joints[i] counts moving joints)
    for (auto& fv : rest) fv = {"urdf", "the chain's " + fv.field + " " + fv.description};
    return tl::unexpected(std::move(rest));
  }
  return m;
}

}  // namespace geotraj::planner
