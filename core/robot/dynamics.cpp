// Inverse dynamics by the recursive Newton-Euler algorithm. See dynamics.hpp.
#include "core/robot/dynamics.hpp"

#include <algorithm>
#include <array>

#include <Eigen/Geometry>

namespace geotraj::core {

bool has_dynamics(const RobotModel& model) {
  return !model.joints.empty() &&
         std::all_of(model.joints.begin(), model.joints.end(), [](const Joint& j) { return j.inertial.has_value(); });
}

void inverse_dynamics(const RobotModel& model, const JointVector& q, const JointVector& q_dot,
                      const JointVector& q_ddot, const DynamicsOptions& options, JointVector& tau) {
  using Eigen::Matrix3d;
  using Eigen::Vector3d;
  const std::size_t n = model.dof();
  const auto size = static_cast<Eigen::Index>(n);
  GEOTRAJ_CHECK(has_dynamics(model) && q.size() == size && q_dot.size() == size && q_ddot.size() == size);
  // Per link, in W: orientation, origin, joint axis, angular velocity and acceleration, and
  // the acceleration of the origin (gravity folded in as the base's upward acceleration).
  std::array<Matrix3d, kMaxJoints> R;
  std::array<Vector3d, kMaxJoints> p, z, w, w_dot, a;
  Matrix3d R_prev = model.base.linear();
  Vector3d p_prev = model.base.translation();
  Vector3d w_prev = Vector3d::Zero(), w_dot_prev = Vector3d::Zero(), a_prev = -options.gravity;
  for (std::size_t i = 0; i < n; ++i) {
    const Joint& joint = model.joints[i];
    const auto k = static_cast<Eigen::Index>(i);
    const Matrix3d R_origin = R_prev * joint.origin.linear();
    const Vector3d origin = p_prev + R_prev * joint.origin.translation();
    z[i] = R_origin * joint.axis;
    const Vector3d rate = z[i] * q_dot(k);
    if (turns(joint.type)) {
      R[i] = R_origin * Eigen::AngleAxisd(q(k), joint.axis).toRotationMatrix();
      p[i] = origin;
      w[i] = w_prev + rate;
      w_dot[i] = w_dot_prev + z[i] * q_ddot(k) + w_prev.cross(rate);
    } else {
      R[i] = R_origin;
      p[i] = origin + z[i] * q(k);
      w[i] = w_prev;
      w_dot[i] = w_dot_prev;
    }
    const Vector3d d = p[i] - p_prev;
    a[i] = a_prev + w_dot_prev.cross(d) + w_prev.cross(w_prev.cross(d));
    if (!turns(joint.type)) a[i] += 2.0 * w_prev.cross(rate) + z[i] * q_ddot(k);
    R_prev = R[i];
    p_prev = p[i];
    w_prev = w[i];
    w_dot_prev = w_dot[i];
    a_prev = a[i];
  }
  // The force and moment (about the child's origin) the child link exerts on its parent.
  Vector3d f = Vector3d::Zero(), moment = Vector3d::Zero(), p_child = Vector3d::Zero();
  tau.resize(size);
  for (std::size_t i = n; i-- > 0;) {
    const Inertial& body = *model.joints[i].inertial;
    // The acceleration of a point of the link at r (from its origin, in W).
    const auto acceleration_at = [&](const Vector3d& r) {
      return Vector3d(a[i] + w_dot[i].cross(r) + w[i].cross(w[i].cross(r)));
    };
    const Vector3d c = R[i] * body.center_of_mass;
    const Vector3d F = body.mass * acceleration_at(c);
    // Euler's equation in the link's frame (its inertia as given), turned into W.
    const Vector3d w_link = R[i].transpose() * w[i], w_dot_link = R[i].transpose() * w_dot[i];
    Vector3d n_i = R[i] * (body.inertia * w_dot_link + w_link.cross(body.inertia * w_link)) + c.cross(F);
    Vector3d f_i = F;
    if (i + 1 < n) {
      n_i += moment + (p_child - p[i]).cross(f);
      f_i += f;
    } else if (options.payload.mass != 0.0) {
      const Vector3d r = R[i] * (model.flange * model.tool * options.payload.center_of_mass);
      const Vector3d F_load = options.payload.mass * acceleration_at(r);
      n_i += r.cross(F_load);
      f_i += F_load;
    }
    tau(static_cast<Eigen::Index>(i)) = turns(model.joints[i].type) ? z[i].dot(n_i) : z[i].dot(f_i);
    f = f_i;
    moment = n_i;
    p_child = p[i];
  }
}

}  // namespace geotraj::core
