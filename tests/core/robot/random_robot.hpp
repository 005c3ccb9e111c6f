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
  std::string out;
  char buf[256];
  const auto type = [](core::JointType t) {
    return t == core::JointType::kRevolute ? "R" : t == core::JointType::kPrismatic ? "P" : "C";
  };
  const auto pose = [&](const char* name, const Eigen::Isometry3d& X) {
    const Eigen::Quaterniond r(X.linear());
    std::snprintf(buf, sizeof buf, "%s: p (%.17g, %.17g, %.17g) q_wxyz (%.17g, %.17g, %.17g, %.17g)\n", name,
                  X.translation().x(), X.translation().y(), X.translation().z(), r.w(), r.x(), r.y(), r.z());
    out += buf;
  };
  if (m.dh) {
    out += std::string("convention: ") + (m.dh->convention == core::DhConvention::kModified ? "modified" : "standard") +
           "\nlinks (a, alpha, d, theta, type, offset):\n";
    for (const auto& l : m.dh->links) {
      std::snprintf(buf, sizeof buf, "  {%.17g, %.17g, %.17g, %.17g, %s, %.17g}\n", l.a, l.alpha, l.d, l.theta,
                    type(l.type), l.offset);
      out += buf;
    }
  } else {
    out += "joints (type, axis; origin):\n";
    for (const auto& j : m.joints) {
      std::snprintf(buf, sizeof buf, "  %s axis (%.17g, %.17g, %.17g) ", type(j.type), j.axis.x(), j.axis.y(), j.axis.z());
      out += buf;
      pose("origin", j.origin);
    }
    pose("flange", m.flange);
  }
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
  core::DhTable table;
  table.convention = coin(rng) < 0.5 ? core::DhConvention::kModified : core::DhConvention::kStandard;
  const int n = joints(rng);
  for (int i = 0; i < n; ++i) {
    core::DhLink l;
    l.a = unit(rng);
    l.alpha = angle(rng);
    l.d = unit(rng);
    l.theta = angle(rng);
    l.type = coin(rng) < 0.25 ? core::JointType::kPrismatic : core::JointType::kRevolute;
    l.offset = l.type == core::JointType::kRevolute ? angle(rng) : 0.5 * unit(rng);
    table.links.push_back(l);
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
  core::set_dh(m, std::move(table));
  m.base = random_pose();
  m.tool = random_pose();
  return m;
}

/// A random general chain (URDF-like): 1..kMaxJoints joints, revolute, continuous or
/// prismatic, each origin a random rigid transform (lengths in [-0.5, 0.5] m), each axis a
/// random unit vector or (half of them) a signed coordinate axis; random flange, base, tool.
inline core::RobotModel random_general_robot(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0), coin(0.0, 1.0);
  std::uniform_int_distribution<int> joints(1, static_cast<int>(core::kMaxJoints)), axis(0, 2);
  const auto random_pose = [&](double length) {
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    X.linear() = Eigen::Quaterniond(Eigen::Vector4d(unit(rng), unit(rng), unit(rng), unit(rng)).normalized())
                     .toRotationMatrix();
    X.translation() = length * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    return X;
  };
  core::RobotModel m;
  m.name = "random_general";
  const int n = joints(rng);
  for (int i = 0; i < n; ++i) {
    core::Joint j;
    const double kind = coin(rng);
    j.type = kind < 0.2 ? core::JointType::kPrismatic : kind < 0.4 ? core::JointType::kContinuous : core::JointType::kRevolute;
    j.origin = coin(rng) < 0.2 ? Eigen::Isometry3d(Eigen::Translation3d(0.5 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng))))
                               : random_pose(0.5);
    if (coin(rng) < 0.5) {
      j.axis = (coin(rng) < 0.5 ? 1.0 : -1.0) * Eigen::Vector3d::Unit(axis(rng));
    } else {
      j.axis = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized();
    }
    m.joints.push_back(j);
    const double range = j.type == core::JointType::kPrismatic ? 1.0 : 2 * std::numbers::pi;
    m.limits.push_back({-range, range, 2.0, 4.0, std::nullopt});
  }
  m.flange = random_pose(0.5);
  m.base = random_pose(1.0);
  m.tool = random_pose(0.3);
  return m;
}

/// Random mass properties of a link: mass in [0.2, 5] kg, centre of mass within 0.2 m of
/// the link's origin, principal moments in [0.005, 0.1] kg m^2 (drawn again until they obey
/// the triangle inequality) about random principal axes.
inline core::Inertial random_inertial(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0), mass(0.2, 5.0), moment(0.005, 0.1);
  core::Inertial in;
  in.mass = mass(rng);
  in.center_of_mass = 0.2 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
  Eigen::Vector3d m;
  do {
    m = Eigen::Vector3d(moment(rng), moment(rng), moment(rng));
  } while (m.sum() < 2.0 * m.maxCoeff());  // the triangle inequality
  const Eigen::Matrix3d R =
      Eigen::Quaterniond(Eigen::Vector4d(unit(rng), unit(rng), unit(rng), unit(rng)).normalized()).toRotationMatrix();
  in.inertia = R * m.asDiagonal() * R.transpose();
  in.inertia = 0.5 * (in.inertia + in.inertia.transpose()).eval();
  return in;
}

/// The model with every joint's link given random mass properties (random_inertial).
inline core::RobotModel with_random_inertials(core::RobotModel m, std::mt19937_64& rng) {
  for (core::Joint& j : m.joints) j.inertial = random_inertial(rng);
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
