// The built-in arms: core's DH models and the URDF files of models/, compiled in (read once
// by robot_from_urdf, urdf.cpp). See robots.hpp.
#include "planner/robots.hpp"

#include <cstdio>
#include <utility>
#include <vector>

#include "core/robot/dynamics.hpp"
#include "planner/builtin_urdf.hpp"

namespace geotraj::planner {

std::vector<bool> apply_named_limits(const std::vector<NamedLimits>& limits, core::RobotModel& model) {
  std::vector<bool> named(limits.size(), false);
  const bool dynamics = core::has_dynamics(model);
  for (std::size_t k = 0; k < limits.size(); ++k) {
    const NamedLimits& given = limits[k];
    for (std::size_t i = 0; i < model.dof(); ++i) {
      if (model.joints[i].name != given.joint) continue;
      named[k] = true;
      if (model.limit_sources.empty()) model.limit_sources.assign(model.dof(), core::LimitSources{});
      core::JointLimits& to = model.limits[i];
      core::LimitSources& from = model.limit_sources[i];
      const std::string source = given.source.empty() ? "robot.jointLimits" : given.source;
      if (given.max_velocity) {
        to.max_velocity = *given.max_velocity;
        from.velocity = source;
      }
      if (given.max_acceleration) {
        to.max_acceleration = *given.max_acceleration;
        from.acceleration = source;
        from.acceleration_known = true;
      }
      if (given.max_jerk) {
        to.max_jerk = given.max_jerk;
        from.jerk = source;
      }
      if (given.max_torque && dynamics) {
        to.max_torque = given.max_torque;
        from.torque = source;
      }
    }
  }
  return named;
}

std::string missing_accelerations(const core::RobotModel& model) {
  std::string joints;
  std::string first;
  std::size_t count = 0;
  for (std::size_t i = 0; i < model.dof(); ++i) {
    if (model.acceleration_known(i)) continue;
    joints += (joints.empty() ? "" : ", ") + std::to_string(i) + " (" + model.joints[i].name + ")";
    if (first.empty()) first = model.joints[i].name;
    ++count;
  }
  if (count == 0) return {};
  return std::string(count == 1 ? "joint " : "joints ") + joints + (count == 1 ? " has" : " have") +
         " no acceleration limit, which a motion needs (it is timed within it or checked against it) and a URDF "
         "cannot say: give it in the request's robot.jointLimits ({\"joint\": \"" + first +
         "\", \"maxAcceleration\": ...} [rad/s^2 or m/s^2]), in MoveIt's joint_limits.yaml "
         "(robot.jointLimitsYaml, or geotrajd --joint-limits FILE), or in a <geotraj> block beside the URDF's links "
         "(<geotraj><joint name=\"" + first + "\" max_acceleration=\"...\"/></geotraj>) (docs/kinematics.md)";
}

const std::vector<core::ValidRobot>& builtin_robots() {
  static const std::vector<core::ValidRobot> robots = [] {
    std::vector<core::RobotModel> models = core::builtin_robots();
    for (const BuiltinUrdf& b : kBuiltinUrdfs) {
      auto m = robot_from_urdf(b.text);
      if (!m) {  // a file of this repository: the tests read every one
        for (const auto& fv : m.error()) std::fprintf(stderr, "built-in %s: %s: %s\n", b.name, fv.field.c_str(), fv.description.c_str());
        GEOTRAJ_CHECK(false && "a built-in URDF does not load");
      }
      GEOTRAJ_CHECK(missing_accelerations(*m).empty() && "a built-in model has every limit");
      m->name = b.name;
      m->limit_sources.clear();  // the model's own, every one
      models.push_back(std::move(*m));
    }
    std::vector<core::ValidRobot> out;
    for (auto& m : models) {
      auto valid = core::ValidRobot::check(std::move(m));
      GEOTRAJ_CHECK(valid.has_value() && "a built-in model is valid");
      out.push_back(std::move(*valid));
    }
    return out;
  }();
  return robots;
}

const core::RobotModel* find_builtin_robot(std::string_view name) {
  for (const auto& m : builtin_robots()) {
    if (m->name == name) return &m.model();
  }
  return nullptr;
}

std::string_view builtin_urdf(std::string_view name) {
  for (const BuiltinUrdf& b : kBuiltinUrdfs) {
    if (name == b.name) return b.text;
  }
  return {};
}

}  // namespace geotraj::planner
