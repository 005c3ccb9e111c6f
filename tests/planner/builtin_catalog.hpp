// The server's catalogue of built-in robots, as geotrajd starts with it: for the planner's
// and the wire's tests.
#pragma once

#include "planner/robot_spec.hpp"
#include "planner/robots.hpp"

namespace geotraj::testing {

inline const planner::RobotCatalog& builtin_catalog() {
  static const planner::RobotCatalog catalog{planner::builtin_robots()};
  return catalog;
}

}  // namespace geotraj::testing
