// Inverse dynamics by the recursive Newton-Euler algorithm. See dynamics.hpp.
#include "core/robot/dynamics.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Geometry>

namespace geotraj::core {

bool has_dynamics(const RobotModel& model) {
  return !model.joints.empty() &&
         std::all_of(model.joints.begin(), model.joints.end(), [](const Joint& j) { return j.inertial.has_value(); });
}

bool torque_limited(const RobotModel& model) {
  return has_dynamics(model) && std::any_of(model.limits.begin(), model.limits.end(),
                                            [](const JointLimits& l) { return l.max_torque.has_value(); });
}

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

/// The links' poses at q, in W (the part of the recursion that depends on q alone): each
/// link's orientation R, origin p, joint axis z and centre of mass c (from p), and the
/// payload's place r_load (from the last link's origin).
struct Poses {
  std::array<Matrix3d, kMaxJoints> R;
  std::array<Vector3d, kMaxJoints> p, z, c;
  Vector3d r_load = Vector3d::Zero();
};

/// R times the rotation by angle (cos c, sin s) about `axis`: by columns where the axis is
/// one of the frame's (a DH chain's z, most URDF joints), else Rodrigues' matrix.
Matrix3d turned(const Matrix3d& R, const Vector3d& axis, double c, double s) {
  Matrix3d out;
  const auto spin = [&](int i, int j, int k) {  // about column k: columns i, j turn
    out.col(i) = c * R.col(i) + s * R.col(j);
    out.col(j) = c * R.col(j) - s * R.col(i);
    out.col(k) = R.col(k);
  };
  if (axis.x() == 0.0 && axis.y() == 0.0 && std::abs(axis.z()) == 1.0) {
    spin(0, 1, 2);
    if (axis.z() < 0.0) out.col(0) = c * R.col(0) - s * R.col(1), out.col(1) = c * R.col(1) + s * R.col(0);
  } else if (axis.y() == 0.0 && axis.z() == 0.0 && std::abs(axis.x()) == 1.0) {
    spin(1, 2, 0);
    if (axis.x() < 0.0) out.col(1) = c * R.col(1) - s * R.col(2), out.col(2) = c * R.col(2) + s * R.col(1);
  } else if (axis.x() == 0.0 && axis.z() == 0.0 && std::abs(axis.y()) == 1.0) {
    spin(2, 0, 1);
    if (axis.y() < 0.0) out.col(2) = c * R.col(2) - s * R.col(0), out.col(0) = c * R.col(0) + s * R.col(2);
  } else {
    Matrix3d K;
    K << 0.0, -axis.z(), axis.y(), axis.z(), 0.0, -axis.x(), -axis.y(), axis.x(), 0.0;
    out = R * (Matrix3d::Identity() + s * K + (1.0 - c) * K * K);
  }
  return out;
}

void pose_pass(const RobotModel& model, const JointVector& q, const Payload& payload, Poses& out) {
  Matrix3d R_prev = model.base.linear();
  Vector3d p_prev = model.base.translation();
  for (std::size_t i = 0; i < model.dof(); ++i) {
    const Joint& joint = model.joints[i];
    const auto k = static_cast<Eigen::Index>(i);
    const Matrix3d R_origin = R_prev * joint.origin.linear();
    const Vector3d origin = p_prev + R_prev * joint.origin.translation();
    out.z[i] = R_origin * joint.axis;
    if (turns(joint.type)) {
      out.R[i] = turned(R_origin, joint.axis, std::cos(q(k)), std::sin(q(k)));
      out.p[i] = origin;
    } else {
      out.R[i] = R_origin;
      out.p[i] = origin + out.z[i] * q(k);
    }
    out.c[i] = out.R[i] * joint.inertial->center_of_mass;
    R_prev = out.R[i];
    p_prev = out.p[i];
  }
  if (model.dof() > 0 && payload.mass != 0.0) out.r_load = R_prev * (model.flange * model.tool * payload.center_of_mass);
}

/// The torques of (q_dot, q_ddot) at the poses of q, under `gravity` [m/s^2 in W] with
/// `payload`: the velocity and acceleration recursion (forward) and the forces (backward).
void motion_pass(const RobotModel& model, const Poses& x, const JointVector& q_dot, const JointVector& q_ddot,
                 const Vector3d& gravity, const Payload& payload, JointVector& tau) {
  const std::size_t n = model.dof();
  std::array<Vector3d, kMaxJoints> w, w_dot, a;
  Vector3d p_prev = model.base.translation();
  Vector3d w_prev = Vector3d::Zero(), w_dot_prev = Vector3d::Zero(), a_prev = -gravity;
  for (std::size_t i = 0; i < n; ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    const Vector3d rate = x.z[i] * q_dot(k);
    const bool revolute = turns(model.joints[i].type);
    if (revolute) {
      w[i] = w_prev + rate;
      w_dot[i] = w_dot_prev + x.z[i] * q_ddot(k) + w_prev.cross(rate);
    } else {
      w[i] = w_prev;
      w_dot[i] = w_dot_prev;
    }
    const Vector3d d = x.p[i] - p_prev;
    a[i] = a_prev + w_dot_prev.cross(d) + w_prev.cross(w_prev.cross(d));
    if (!revolute) a[i] += 2.0 * w_prev.cross(rate) + x.z[i] * q_ddot(k);
    p_prev = x.p[i];
    w_prev = w[i];
    w_dot_prev = w_dot[i];
    a_prev = a[i];
  }
  // The force and moment (about the child's origin) the child link exerts on its parent.
  Vector3d f = Vector3d::Zero(), moment = Vector3d::Zero(), p_child = Vector3d::Zero();
  tau.resize(static_cast<Eigen::Index>(n));
  for (std::size_t i = n; i-- > 0;) {
    const Inertial& body = *model.joints[i].inertial;
    const Matrix3d& R = x.R[i];
    // The acceleration of a point of the link at r (from its origin, in W).
    const auto acceleration_at = [&](const Vector3d& r) {
      return Vector3d(a[i] + w_dot[i].cross(r) + w[i].cross(w[i].cross(r)));
    };
    const Vector3d& c = x.c[i];
    const Vector3d F = body.mass * acceleration_at(c);
    // Euler's equation in the link's frame (its inertia as given), turned into W.
    const Vector3d w_link = R.transpose() * w[i], w_dot_link = R.transpose() * w_dot[i];
    Vector3d n_i = R * (body.inertia * w_dot_link + w_link.cross(body.inertia * w_link)) + c.cross(F);
    Vector3d f_i = F;
    if (i + 1 < n) {
      n_i += moment + (p_child - x.p[i]).cross(f);
      f_i += f;
    } else if (payload.mass != 0.0) {
      const Vector3d& r = x.r_load;
      const Vector3d F_load = payload.mass * acceleration_at(r);
      n_i += r.cross(F_load);
      f_i += F_load;
    }
    tau(static_cast<Eigen::Index>(i)) = turns(model.joints[i].type) ? x.z[i].dot(n_i) : x.z[i].dot(f_i);
    f = f_i;
    moment = n_i;
    p_child = x.p[i];
  }
}

}  // namespace

void inverse_dynamics(const RobotModel& model, const JointVector& q, const JointVector& q_dot,
                      const JointVector& q_ddot, const DynamicsOptions& options, JointVector& tau) {
  const auto size = static_cast<Eigen::Index>(model.dof());
  GEOTRAJ_CHECK(has_dynamics(model) && q.size() == size && q_dot.size() == size && q_ddot.size() == size);
  Poses x;
  pose_pass(model, q, options.payload, x);
  motion_pass(model, x, q_dot, q_ddot, options.gravity, options.payload, tau);
}

void gravity_torques(const RobotModel& model, const JointVector& q, const DynamicsOptions& options, JointVector& tau) {
  const auto size = static_cast<Eigen::Index>(model.dof());
  GEOTRAJ_CHECK(has_dynamics(model) && q.size() == size);
  Poses x;
  pose_pass(model, q, options.payload, x);
  const JointVector zero = JointVector::Zero(size);
  motion_pass(model, x, zero, zero, options.gravity, options.payload, tau);
}

void path_torque_terms(const RobotModel& model, const JointVector& q, const JointVector& q_s, const JointVector& q_ss,
                       const DynamicsOptions& options, JointVector& a, JointVector& b, JointVector& c) {
  const auto size = static_cast<Eigen::Index>(model.dof());
  GEOTRAJ_CHECK(has_dynamics(model) && q.size() == size && q_s.size() == size && q_ss.size() == size);
  Poses x;
  pose_pass(model, q, options.payload, x);
  const JointVector zero = JointVector::Zero(size);
  motion_pass(model, x, zero, q_s, Vector3d::Zero(), options.payload, a);     // M q_s
  motion_pass(model, x, q_s, q_ss, Vector3d::Zero(), options.payload, b);     // M q_ss + C(q, q_s) q_s
  motion_pass(model, x, zero, zero, options.gravity, options.payload, c);     // g(q)
}

}  // namespace geotraj::core
