// An independent Denavit-Hartenberg forward kinematics for the tests, written from the
// conventions stated in the proto (not from the server's kinematics), with the small
// conversions of wire values it needs.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "geotraj/v1/geotraj.pb.h"

namespace geotraj::testing {

inline Eigen::Vector3d vec(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

// Wire order (w, x, y, z), by name.
inline Eigen::Quaterniond quat(const v1::Quaternion& q) { return {q.w(), q.x(), q.y(), q.z()}; }

// A Pose message as X_PC (child C in parent P); an absent orientation is the identity.
inline Eigen::Isometry3d pose(const v1::Pose& p) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = vec(p.position());
  if (p.has_orientation()) X.linear() = quat(p.orientation()).normalized().toRotationMatrix();
  return X;
}

// Forward kinematics X_WT(q) of a RobotModel as ListRobots describes it, written from the
// conventions in the proto, independently of the server's kinematics:
//   X_WT = base * A_1(q_1) * ... * A_n(q_n) * tool,
//   modified (Craig): A_i = RotX(alpha) TransX(a) RotZ(theta) TransZ(d),
//   standard:         A_i = RotZ(theta) TransZ(d) TransX(a) RotX(alpha),
// with theta = theta_i + offset_i + q_i (revolute) or d = d_i + offset_i + q_i (prismatic).
// Units: [m], [rad].
// A general chain (`joints`, the form of URDF models):
//   X_WT = base * origin_1 M_1(q_1) * ... * origin_n M_n(q_n) * flange * tool,
// M_i the turn about (revolute, continuous) or slide along (prismatic) the joint's axis.
template <class Joints>
Eigen::Isometry3d forward_kinematics(const v1::RobotModel& model, const Joints& q) {
  Eigen::Isometry3d X_WT = pose(model.base());
  if (model.joints_size() > 0) {
    for (int i = 0; i < model.joints_size(); ++i) {
      const auto& j = model.joints(i);
      const Eigen::Vector3d axis = j.has_axis() ? vec(j.axis()).normalized() : Eigen::Vector3d::UnitZ();
      X_WT = X_WT * pose(j.origin());
      if (j.joint_type() == v1::JOINT_TYPE_PRISMATIC) {
        X_WT = X_WT * Eigen::Translation3d(q[i] * axis);
      } else {
        X_WT = X_WT * Eigen::AngleAxisd(q[i], axis);
      }
    }
    return X_WT * pose(model.flange()) * pose(model.tool());
  }
  for (int i = 0; i < model.links_size(); ++i) {
    const auto& l = model.links(i);
    const bool prismatic = l.joint_type() == v1::JOINT_TYPE_PRISMATIC;
    const double theta = l.theta() + (prismatic ? 0.0 : l.offset() + q[i]);
    const double d = l.d() + (prismatic ? l.offset() + q[i] : 0.0);
    const Eigen::AngleAxisd rot_x(l.alpha(), Eigen::Vector3d::UnitX());
    const Eigen::AngleAxisd rot_z(theta, Eigen::Vector3d::UnitZ());
    const Eigen::Translation3d trans_x(l.a(), 0.0, 0.0);
    const Eigen::Translation3d trans_z(0.0, 0.0, d);
    if (model.dh_convention() == v1::DH_CONVENTION_MODIFIED) {
      X_WT = X_WT * rot_x * trans_x * rot_z * trans_z;
    } else {
      X_WT = X_WT * rot_z * trans_z * trans_x * rot_x;
    }
  }
  return X_WT * pose(model.tool());
}

}  // namespace geotraj::testing
