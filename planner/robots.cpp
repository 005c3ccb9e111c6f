// The built-in arms: core's DH models and the URDF files of models/, compiled in (read once
// by robot_from_urdf, urdf.cpp). See robots.hpp.
#include "planner/robots.hpp"

#include <cstdio>
#include <utility>
#include <vector>

#include "planner/builtin_urdf.hpp"

namespace geotraj::planner {

const std::vector<core::ValidRobot>& builtin_robots() {
  static const std::vector<core::ValidRobot> robots = [] {
    std::vector<core::RobotModel> models = core::builtin_robots();
    for (const BuiltinUrdf& b : kBuiltinUrdfs) {
      auto m = robot_from_urdf(b.text);
      if (!m) {  // a file of this repository: the tests read every one
        for (const auto& fv : m.error()) std::fprintf(stderr, "built-in %s: %s: %s\n", b.name, fv.field.c_str(), fv.description.c_str());
        GEOTRAJ_CHECK(false && "a built-in URDF does not load");
      }
      m->name = b.name;
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
