// A RobotModel (core/robot/robot.hpp) as an Orocos KDL chain, the independent implementation the
// kinematics tests compare with. Test code only: geotraj_core never links KDL. A model written
// as a DH table is built from the table with KDL's DH frames; a general chain joint by joint.
//
// DH: KDL puts a segment's joint at the segment's START: pose(q) = joint(q) * f_tip. The chain:
//   standard DH:  [fixed: base] [joint 1: DH(link 1)] ... [joint n: DH(link n)] [fixed: tool]
//     RotZ(q_i) (or TransZ(q_i)) then RotZ(theta_i) TransZ(d_i) TransX(a_i) RotX(alpha_i);
//   modified DH:  [fixed: base] [fixed: DH_Craig1989(link 1)] [joint 1: DH_Craig1989(link 2)]
//                 ... [joint n-1: DH_Craig1989(link n)] [joint n: identity] [fixed: tool]
//     joint i turns about (or slides along) z of frame i, which ends RotX(alpha) TransX(a)
//     RotZ(theta) TransZ(d): RotZ(q) and TransZ(q) commute with its last two factors, so the
//     joint sits at the start of the NEXT segment.
// Offsets go into the link frame (revolute: theta + offset; prismatic: d + offset), not
// into KDL::Joint's offset: a KDL::Segment stores its tip as given AT q = 0 (its constructor
// takes joint.pose(0)^-1 * f_tip), so a joint offset would cancel out.
#pragma once

#include <optional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <kdl/chain.hpp>
#include <kdl/frames.hpp>
#include <kdl/jacobian.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/rigidbodyinertia.hpp>
#include <kdl/rotationalinertia.hpp>
#include <kdl/joint.hpp>
#include <kdl/segment.hpp>

#include "core/robot/robot.hpp"

namespace geotraj::test {

inline KDL::Frame to_kdl(const Eigen::Isometry3d& X) {
  const Eigen::Matrix3d R = X.linear();
  const Eigen::Vector3d p = X.translation();
  return KDL::Frame(KDL::Rotation(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)),
                    KDL::Vector(p.x(), p.y(), p.z()));
}

inline Eigen::Isometry3d from_kdl(const KDL::Frame& F) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) X.linear()(r, c) = F.M(r, c);
    X.translation()(r) = F.p(r);
  }
  return X;
}

// KDL holds a segment's inertia in the segment's tip frame, about the centre of mass.
inline KDL::RigidBodyInertia to_kdl(const core::Inertial& in) {
  const Eigen::Matrix3d& I = in.inertia;
  return KDL::RigidBodyInertia(in.mass, KDL::Vector(in.center_of_mass.x(), in.center_of_mass.y(), in.center_of_mass.z()),
                               KDL::RotationalInertia(I(0, 0), I(1, 1), I(2, 2), I(0, 1), I(0, 2), I(1, 2)));
}
inline KDL::RigidBodyInertia inertia_of(const std::optional<core::Inertial>& in) {
  return in ? to_kdl(*in) : KDL::RigidBodyInertia::Zero();
}

inline KDL::JntArray to_kdl(const core::JointVector& q) {
  KDL::JntArray out(static_cast<unsigned int>(q.size()));
  for (Eigen::Index i = 0; i < q.size(); ++i) out(static_cast<unsigned int>(i)) = q(i);
  return out;
}

// A DH model from its table, with KDL's own DH frames (independent of core::set_dh).
inline KDL::Chain dh_to_kdl_chain(const core::RobotModel& m) {
  const core::DhTable& table = *m.dh;
  const bool modified = table.convention == core::DhConvention::kModified;
  // The link's transform at q = 0, offset included.
  const auto link_frame = [&](const core::DhLink& l) {
    const bool revolute = l.type != core::JointType::kPrismatic;
    const double theta = l.theta + (revolute ? l.offset : 0.0), d = l.d + (revolute ? 0.0 : l.offset);
    return modified ? KDL::Frame::DH_Craig1989(l.a, l.alpha, d, theta) : KDL::Frame::DH(l.a, l.alpha, d, theta);
  };
  const auto joint = [](const core::DhLink& l) {
    return KDL::Joint(l.type != core::JointType::kPrismatic ? KDL::Joint::RotZ : KDL::Joint::TransZ);
  };
  KDL::Chain chain;
  chain.addSegment(KDL::Segment("base", KDL::Joint(KDL::Joint::Fixed), to_kdl(m.base)));
  const std::size_t n = table.links.size();
  if (modified) {
    chain.addSegment(KDL::Segment("link1", KDL::Joint(KDL::Joint::Fixed), link_frame(table.links[0])));
    for (std::size_t i = 0; i < n; ++i) {
      const KDL::Frame next = i + 1 < n ? link_frame(table.links[i + 1]) : KDL::Frame::Identity();
      chain.addSegment(KDL::Segment("joint" + std::to_string(i + 1), joint(table.links[i]), next));
    }
  } else {
    // Standard form: the segment's tip is frame i, where DhLink::inertial is given.
    for (std::size_t i = 0; i < n; ++i)
      chain.addSegment(KDL::Segment("joint" + std::to_string(i + 1), joint(table.links[i]), link_frame(table.links[i]),
                                    inertia_of(table.links[i].inertial)));
  }
  chain.addSegment(KDL::Segment("tool", KDL::Joint(KDL::Joint::Fixed), to_kdl(m.tool)));
  return chain;
}

// A general chain as KDL builds one from URDF: per joint a fixed segment to the joint's
// frame, then a segment whose joint turns about (slides along) the axis through its origin;
// the flange and the tool as fixed segments. A link's inertia (Joint::inertial) on the
// segment whose tip is the joint's frame after its motion; `payload` (mass, centre of mass in
// the tool frame) on the tool's segment.
inline KDL::Chain general_to_kdl_chain(const core::RobotModel& m, const core::Inertial& payload = {}) {
  KDL::Chain chain;
  chain.addSegment(KDL::Segment("base", KDL::Joint(KDL::Joint::Fixed), to_kdl(m.base)));
  for (std::size_t i = 0; i < m.joints.size(); ++i) {
    const core::Joint& j = m.joints[i];
    chain.addSegment(KDL::Segment("origin" + std::to_string(i), KDL::Joint(KDL::Joint::Fixed), to_kdl(j.origin)));
    const KDL::Joint moving("joint" + std::to_string(i), KDL::Vector::Zero(), KDL::Vector(j.axis.x(), j.axis.y(), j.axis.z()),
                            j.type == core::JointType::kPrismatic ? KDL::Joint::TransAxis : KDL::Joint::RotAxis);
    chain.addSegment(KDL::Segment("link" + std::to_string(i), moving, KDL::Frame::Identity(), inertia_of(j.inertial)));
  }
  chain.addSegment(KDL::Segment("flange", KDL::Joint(KDL::Joint::Fixed), to_kdl(m.flange)));
  chain.addSegment(KDL::Segment("tool", KDL::Joint(KDL::Joint::Fixed), to_kdl(m.tool), to_kdl(payload)));
  return chain;
}

inline KDL::Chain to_kdl_chain(const core::RobotModel& m) { return m.dh ? dh_to_kdl_chain(m) : general_to_kdl_chain(m); }

}  // namespace geotraj::test
