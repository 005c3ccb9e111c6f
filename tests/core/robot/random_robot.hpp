// Random arms and configurations for the kinematics and move tests, with a replayable
// description of a model (17 significant digits) for a failing case.
#pragma once

#include <cstdio>
#include <numbers>
#include <random>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/robot/robot.hpp"

namespace geotraj::test {

/// A replayable description of a model and a configuration (17 significant digits).
inline std::string describe_robot(const core::RobotModel& m, const core::JointVector& q, const core::JointVector& q_dot) {
  std::string out = std::string("convention: ") +
                    (m.convention == core::DhConvention::kModified ? "modified" : "standard") + "\nlinks (a, alpha, d, theta, type, offset):\n";
  char buf[256];
  for (const auto& l : m.links) {
    std::snprintf(buf, sizeof buf, "  {%.17g, %.17g, %.17g, %.17g, %s, %.17g}\n", l.a, l.alpha, l.d, l.theta,
                  l.type == core::JointType::kRevolute ? "R" : "P", l.offset);
    out += buf;
  }
  const auto pose = [&](const char* name, const Eigen::Isometry3d& X) {
    const Eigen::Quaterniond r(X.linear());
    std::snprintf(buf, sizeof buf, "%s: p (%.17g, %.17g, %.17g) q_wxyz (%.17g, %.17g, %.17g, %.17g)\n", name,
                  X.translation().x(), X.translation().y(), X.translation().z(), r.w(), r.x(), r.y(), r.z());
    out += buf;
  };
  pose("base", m.base);
  pose("tool", m.tool);
  const auto vec = [&](const char* name, const core::JointVector& v) {
    out += name;
    out += ":";
    for (Eigen::Index i = 0; i < v.size(); ++i) {
      std::snprintf(buf, sizeof buf, " %.17g", v(i));
      out += buf;
    }
    out += "\n";
  };
  vec("q", q);
  vec("q_dot", q_dot);
  return out;
}

/// A random arm: 1..kMaxJoints joints, a quarter of them prismatic, either convention,
/// DH lengths in [-1, 1] m, angles in [-pi, pi], random base and tool poses. Limits wide
/// (+-2 pi or +-1 m) so that the model validates.
inline core::RobotModel random_robot(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0), angle(-std::numbers::pi, std::numbers::pi), coin(0.0, 1.0);
  std::uniform_int_distribution<int> joints(1, static_cast<int>(core::kMaxJoints));
  core::RobotModel m;
  m.name = "random";
  m.convention = coin(rng) < 0.5 ? core::DhConvention::kModified : core::DhConvention::kStandard;
  const int n = joints(rng);
  for (int i = 0; i < n; ++i) {
    core::DhLink l;
    l.a = unit(rng);
    l.alpha = angle(rng);
    l.d = unit(rng);
    l.theta = angle(rng);
    l.type = coin(rng) < 0.25 ? core::JointType::kPrismatic : core::JointType::kRevolute;
    l.offset = l.type == core::JointType::kRevolute ? angle(rng) : 0.5 * unit(rng);
    m.links.push_back(l);
    const double range = l.type == core::JointType::kRevolute ? 2 * std::numbers::pi : 1.0;
    m.limits.push_back({-range, range, 2.0, 4.0, std::nullopt});
  }
  const auto random_pose = [&] {
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    X.linear() = Eigen::Quaterniond(Eigen::Vector4d(unit(rng), unit(rng), unit(rng), unit(rng)).normalized())
                     .toRotationMatrix();
    X.translation() = Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    return X;
  };
  m.base = random_pose();
  m.tool = random_pose();
  return m;
}

/// Random joint values within the limits and velocities in [-2, 2] per second.
inline core::JointVector random_joints(const core::RobotModel& m, std::mt19937_64& rng) {
  core::JointVector q(static_cast<Eigen::Index>(m.dof()));
  for (std::size_t i = 0; i < m.dof(); ++i) {
    std::uniform_real_distribution<double> d(m.limits[i].min_position, m.limits[i].max_position);
    q(static_cast<Eigen::Index>(i)) = d(rng);
  }
  return q;
}

inline core::JointVector random_rates(const core::RobotModel& m, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> d(-2.0, 2.0);
  core::JointVector v(static_cast<Eigen::Index>(m.dof()));
  for (Eigen::Index i = 0; i < v.size(); ++i) v(i) = d(rng);
  return v;
}

}  // namespace geotraj::test
