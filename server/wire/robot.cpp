// Robots on the wire (convert.hpp): poses, models, RobotSpec translated for the planner
// (planner::resolve_robot), the joint-space report.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <set>
#include <string>
#include <utility>

#include <google/protobuf/util/json_util.h>

#include "core/format.hpp"
#include "planner/robot_spec.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using Eigen::Vector3d;
using namespace wire_detail;

Eigen::Isometry3d pose_from_proto(const v1::Pose& pose, const std::string& field, core::Violations& out) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  const Vector3d p = to_core(pose.position());
  if (!p.allFinite()) out.push_back({field + ".position", "must be finite"});
  X.translation() = p;
  if (pose.has_orientation()) {
    const auto& q = pose.orientation();
    Eigen::Quaterniond quat(q.w(), q.x(), q.y(), q.z());  // wire order (w, x, y, z) by name
    const double norm = quat.norm();
    if (!std::isfinite(norm) || std::abs(norm - 1.0) > kUnitQuaternionTolerance) {
      out.push_back({field + ".orientation", "must be a unit quaternion (w, x, y, z), got norm " + core::number(norm, 6)});
    } else {
      X.linear() = quat.normalized().toRotationMatrix();
    }
  }
  return X;
}

void to_proto(const Eigen::Isometry3d& X, v1::Pose& out) {
  to_proto(Vector3d(X.translation()), *out.mutable_position());
  const Eigen::Quaterniond q(X.linear());
  auto* o = out.mutable_orientation();
  o->set_w(q.w());
  o->set_x(q.x());
  o->set_y(q.y());
  o->set_z(q.z());
}

void to_proto(const Eigen::Vector3d& v, v1::Vec3& out) { set(&out, v); }

// --- robots ---------------------------------------------------------------------------------

namespace {

v1::LimitKind to_proto(core::LimitKind k) {
  switch (k) {
    case core::LimitKind::kPosition: return v1::LIMIT_KIND_POSITION;
    case core::LimitKind::kVelocity: return v1::LIMIT_KIND_VELOCITY;
    case core::LimitKind::kAcceleration: return v1::LIMIT_KIND_ACCELERATION;
    case core::LimitKind::kIk: return v1::LIMIT_KIND_IK;
    case core::LimitKind::kBranch: return v1::LIMIT_KIND_BRANCH;
    case core::LimitKind::kJerk: return v1::LIMIT_KIND_JERK;
    case core::LimitKind::kTorque: return v1::LIMIT_KIND_TORQUE;
  }
  return v1::LIMIT_KIND_UNSPECIFIED;
}

}  // namespace

namespace {

core::JointType joint_type_from_proto(v1::JointType type) {
  switch (type) {
    case v1::JOINT_TYPE_PRISMATIC: return core::JointType::kPrismatic;
    case v1::JOINT_TYPE_CONTINUOUS: return core::JointType::kContinuous;
    default: return core::JointType::kRevolute;
  }
}

v1::JointType to_proto(core::JointType type) {
  switch (type) {
    case core::JointType::kPrismatic: return v1::JOINT_TYPE_PRISMATIC;
    case core::JointType::kContinuous: return v1::JOINT_TYPE_CONTINUOUS;
    case core::JointType::kRevolute: break;
  }
  return v1::JOINT_TYPE_REVOLUTE;
}

// A link's mass properties; an inertia of other than 6 values named at `at`.inertia.
core::Inertial inertial_from_proto(const v1::Inertial& in, const std::string& at, core::Violations& out) {
  core::Inertial inertial;
  inertial.mass = in.mass();
  if (in.has_center_of_mass()) inertial.center_of_mass = to_core(in.center_of_mass());
  inertial.inertia.setZero();
  if (in.inertia_size() == 6) {
    const auto& I = in.inertia();  // ixx, ixy, ixz, iyy, iyz, izz
    inertial.inertia << I[0], I[1], I[2], I[1], I[3], I[4], I[2], I[4], I[5];
  } else if (in.inertia_size() != 0) {
    out.push_back({at + ".inertia", "needs 6 values (ixx, ixy, ixz, iyy, iyz, izz) or none, got " +
                                        std::to_string(in.inertia_size())});
  }
  return inertial;
}

// Where joint i's limits come from: the model's own where it records none.
void limit_sources_to_proto(const core::RobotModel& model, std::size_t i, v1::LimitSources& out) {
  static const core::LimitSources own{};
  const core::LimitSources& from = model.limit_sources.empty() ? own : model.limit_sources[i];
  const core::JointLimits& l = model.limits[i];
  const auto said = [](const std::string& source) { return source.empty() ? std::string("the model's") : source; };
  out.set_velocity(said(from.velocity));
  out.set_acceleration(from.acceleration_known ? said(from.acceleration)
                                               : "not known: give robot.jointLimits[].maxAcceleration, MoveIt's "
                                                 "joint_limits.yaml or the URDF's <geotraj> block");
  if (l.max_jerk) out.set_jerk(said(from.jerk));
  if (l.max_torque) out.set_torque(said(from.torque));
}

void to_proto(const core::Inertial& in, v1::Inertial& out) {
  out.set_mass(in.mass);
  set(out.mutable_center_of_mass(), in.center_of_mass);
  const Eigen::Matrix3d& I = in.inertia;
  for (const double x : {I(0, 0), I(0, 1), I(0, 2), I(1, 1), I(1, 2), I(2, 2)}) out.add_inertia(x);
}

}  // namespace

core::Expected<core::RobotModel> robot_model_from_proto(const v1::RobotModel& model, const std::string& prefix) {
  WireCheck check;
  core::RobotModel m;
  m.name = model.name();
  m.description = model.description();
  core::Violations poses;
  if (model.links_size() > 0 && model.joints_size() > 0) {
    check.violations.push_back({prefix + "joints", "and `links` are two ways of writing the chain: give one"});
  }
  if (model.joints_size() > 0) {  // a general chain
    if (model.dh_convention() != v1::DH_CONVENTION_UNSPECIFIED) {
      check.violations.push_back({prefix + "dhConvention", "is for `links` (a DH table); `joints` have none"});
    }
    for (int i = 0; i < model.joints_size(); ++i) {
      const auto& j = model.joints(i);
      const std::string at = prefix + "joints[" + std::to_string(i) + "]";
      check_enum(check, at + ".jointType", j.joint_type(), v1::JointType_descriptor());
      core::Joint joint;
      joint.name = j.name();
      joint.type = joint_type_from_proto(j.joint_type());
      if (j.has_origin()) joint.origin = pose_from_proto(j.origin(), at + ".origin", poses);
      if (j.has_axis()) joint.axis = to_core(j.axis());
      if (j.has_inertial()) joint.inertial = inertial_from_proto(j.inertial(), at + ".inertial", check.violations);
      m.joints.push_back(std::move(joint));
    }
    if (model.has_flange()) m.flange = pose_from_proto(model.flange(), prefix + "flange", poses);
  } else {  // a DH table
    check_enum(check, prefix + "dhConvention", model.dh_convention(), v1::DhConvention_descriptor());
    if (model.has_flange()) {
      check.violations.push_back({prefix + "flange", "is for `joints` (a general chain); a DH table ends in frame n"});
    }
    core::DhTable table;
    table.convention = model.dh_convention() == v1::DH_CONVENTION_MODIFIED ? core::DhConvention::kModified
                                                                           : core::DhConvention::kStandard;
    for (int i = 0; i < model.links_size(); ++i) {
      const auto& l = model.links(i);
      check_enum(check, prefix + "links[" + std::to_string(i) + "].jointType", l.joint_type(),
                 v1::JointType_descriptor());
      table.links.push_back(
          {l.a(), l.alpha(), l.d(), l.theta(), joint_type_from_proto(l.joint_type()), l.offset(), l.name()});
      if (l.has_inertial())
        table.links.back().inertial = inertial_from_proto(
            l.inertial(), prefix + "links[" + std::to_string(i) + "].inertial", check.violations);
    }
    core::set_dh(m, std::move(table));
  }
  for (const auto& l : model.limits()) {
    core::JointLimits limits{l.min_position(), l.max_position(), l.max_velocity(), l.max_acceleration(),
                             std::nullopt};
    if (l.has_max_jerk()) limits.max_jerk = l.max_jerk();
    if (l.has_max_torque()) limits.max_torque = l.max_torque();
    m.limits.push_back(limits);
  }
  m.home.assign(model.home().begin(), model.home().end());
  if (model.has_base()) m.base = pose_from_proto(model.base(), prefix + "base", poses);
  if (model.has_tool()) m.tool = pose_from_proto(model.tool(), prefix + "tool", poses);
  for (auto& v : poses) check.violations.push_back(std::move(v));
  if (!check.violations.empty()) return tl::unexpected(std::move(check.violations));
  return m;
}

core::Expected<core::RobotModel> robot_model_from_json(std::string_view json) {
  v1::RobotModel model;
  const auto status = google::protobuf::util::JsonStringToMessage(std::string(json), &model);
  if (!status.ok()) {
    return tl::unexpected(core::Violations{{"", "is not a RobotModel in proto3 JSON: " + std::string(status.message())}});
  }
  if (model.name().empty()) return tl::unexpected(core::Violations{{"name", "is required: the model's name"}});
  return robot_model_from_proto(model, "");
}

void to_proto(const core::RobotModel& model, v1::RobotModel& out) {
  out.set_name(model.name);
  out.set_description(model.description);
  if (model.dh) {  // written as a DH table: reported as one
    out.set_dh_convention(model.dh->convention == core::DhConvention::kModified ? v1::DH_CONVENTION_MODIFIED
                                                                                : v1::DH_CONVENTION_STANDARD);
    for (const auto& l : model.dh->links) {
      auto* link = out.add_links();
      link->set_a(l.a);
      link->set_alpha(l.alpha);
      link->set_d(l.d);
      link->set_theta(l.theta);
      link->set_joint_type(to_proto(l.type));
      link->set_offset(l.offset);
      link->set_name(l.name);
      if (l.inertial) to_proto(*l.inertial, *link->mutable_inertial());
    }
  } else {
    for (const auto& j : model.joints) {
      auto* joint = out.add_joints();
      joint->set_name(j.name);
      joint->set_joint_type(to_proto(j.type));
      to_proto(j.origin, *joint->mutable_origin());
      to_proto(Vector3d(j.axis), *joint->mutable_axis());
      if (j.inertial) to_proto(*j.inertial, *joint->mutable_inertial());
    }
    to_proto(model.flange, *out.mutable_flange());
  }
  for (std::size_t i = 0; i < model.dof(); ++i) {
    const core::JointLimits& l = model.limits[i];
    auto* limits = out.add_limits();
    limits->set_min_position(l.min_position);
    limits->set_max_position(l.max_position);
    limits->set_max_velocity(l.max_velocity);
    if (model.acceleration_known(i)) limits->set_max_acceleration(l.max_acceleration);  // 0: not known
    if (l.max_jerk) limits->set_max_jerk(*l.max_jerk);
    if (l.max_torque) limits->set_max_torque(*l.max_torque);
    limit_sources_to_proto(model, i, *limits->mutable_sources());
  }
  to_proto(model.base, *out.mutable_base());
  to_proto(model.tool, *out.mutable_tool());
  for (double q : model.home) out.add_home(q);
}

// RobotSpec as the planner's value: a translation, with the violations of what cannot be
// translated (an unreadable inline model, a pose that is not one, an unknown approach) in
// `out`; the planner checks the values (planner::resolve_robot).
planner::RobotSpec wire_detail::robot_spec_from_proto(const v1::RobotSpec& spec, core::Violations& out) {
  planner::RobotSpec s;
  switch (spec.model_source_case()) {
    case v1::RobotSpec::kName: s.source = planner::RobotByName{spec.name()}; break;
    case v1::RobotSpec::kModel: {
      auto model = robot_model_from_proto(spec.model(), "robot.model.");
      if (!model) out.insert(out.end(), model.error().begin(), model.error().end());
      s.source = planner::InlineRobot{model ? std::optional<core::RobotModel>(std::move(*model)) : std::nullopt,
                                      spec.model().joints_size() > 0 ? "robot.model.joints" : "robot.model.links"};
      break;
    }
    case v1::RobotSpec::kUrdf: s.source = planner::UrdfRobot{spec.urdf()}; break;
    case v1::RobotSpec::MODEL_SOURCE_NOT_SET: break;
  }
  s.base_link = spec.base_link();
  s.tip_link = spec.tip_link();
  for (const auto& l : spec.joint_limits()) {
    planner::NamedLimits limits{l.joint(), std::nullopt, std::nullopt, std::nullopt};
    if (l.has_max_velocity()) limits.max_velocity = l.max_velocity();
    if (l.has_max_acceleration()) limits.max_acceleration = l.max_acceleration();
    if (l.has_max_jerk()) limits.max_jerk = l.max_jerk();
    if (l.has_max_torque()) limits.max_torque = l.max_torque();
    s.joint_limits.push_back(std::move(limits));
  }
  // A pose that cannot be read is left out: its violation is answered, the rest still checked.
  const auto pose = [&out](const v1::Pose& p, const char* field) -> std::optional<Eigen::Isometry3d> {
    const std::size_t before = out.size();
    const Eigen::Isometry3d X = pose_from_proto(p, field, out);
    if (out.size() != before) return std::nullopt;
    return X;
  };
  if (spec.has_base()) s.base = pose(spec.base(), "robot.base");
  if (spec.has_tool()) s.tool = pose(spec.tool(), "robot.tool");
  s.report_only = spec.report_only();
  s.joint_limits_yaml = spec.joint_limits_yaml();
  if (spec.has_payload()) {
    core::Payload payload;
    payload.mass = spec.payload().mass();
    if (spec.payload().has_center_of_mass()) payload.center_of_mass = to_core(spec.payload().center_of_mass());
    s.payload = payload;
  }
  s.tool_axis_free = spec.tool_axis_free();
  if (spec.has_branch_tolerance()) s.branch_tolerance = spec.branch_tolerance();
  if (spec.has_start_position_tolerance()) s.start_position_tolerance = spec.start_position_tolerance();
  if (spec.has_start_orientation_tolerance()) s.start_orientation_tolerance = spec.start_orientation_tolerance();
  if (spec.has_velocity_scale()) s.velocity_scale = spec.velocity_scale();
  if (spec.has_acceleration_scale()) s.acceleration_scale = spec.acceleration_scale();
  switch (spec.approach()) {
    case v1::APPROACH_MOVE_UNSPECIFIED: s.approach = planner::Approach::kNone; break;
    case v1::APPROACH_MOVE_JOINT: s.approach = planner::Approach::kJoint; break;
    case v1::APPROACH_MOVE_LINEAR: s.approach = planner::Approach::kLinear; break;
    default:
      out.push_back({"robot.approach", "unknown value " + std::to_string(spec.approach()) +
                                           "; use APPROACH_MOVE_JOINT or APPROACH_MOVE_LINEAR"});
  }
  s.initial_joints.assign(spec.initial_joints().begin(), spec.initial_joints().end());
  return s;
}

void to_proto(const core::BindingStretch& stretch, v1::BindingStretch& out) {
  switch (stretch.kind) {
    case core::BindingKind::kJointVelocity: out.set_kind(v1::BINDING_KIND_JOINT_VELOCITY); break;
    case core::BindingKind::kJointAcceleration: out.set_kind(v1::BINDING_KIND_JOINT_ACCELERATION); break;
    case core::BindingKind::kJointJerk: out.set_kind(v1::BINDING_KIND_JOINT_JERK); break;
    case core::BindingKind::kCartesianSpeed: out.set_kind(v1::BINDING_KIND_CARTESIAN_SPEED); break;
    case core::BindingKind::kTangentialAcceleration:
      out.set_kind(v1::BINDING_KIND_CARTESIAN_TANGENTIAL_ACCELERATION);
      break;
    case core::BindingKind::kCentripetalAcceleration:
      out.set_kind(v1::BINDING_KIND_CARTESIAN_CENTRIPETAL_ACCELERATION);
      break;
    case core::BindingKind::kAngularSpeed: out.set_kind(v1::BINDING_KIND_ANGULAR_SPEED); break;
    case core::BindingKind::kAngularAcceleration: out.set_kind(v1::BINDING_KIND_ANGULAR_ACCELERATION); break;
    case core::BindingKind::kJointTorque: out.set_kind(v1::BINDING_KIND_JOINT_TORQUE); break;
  }
  out.set_joint(static_cast<std::uint32_t>(stretch.joint));
  out.set_t_start(stretch.t_start);
  out.set_t_end(stretch.t_end);
  out.set_s_start(stretch.s_start);
  out.set_s_end(stretch.s_end);
  out.set_usage(stretch.usage);
  out.set_value(stretch.value);
  out.set_limit(stretch.limit);
}

void to_proto(const core::LimitEvent& event, v1::LimitEvent& out) {
  out.set_kind(to_proto(event.kind));
  out.set_joint(static_cast<std::uint32_t>(event.joint));
  out.set_sample(event.sample);
  out.set_t(event.t);
  out.set_value(event.value);
  out.set_limit(event.limit);
  out.set_margin(event.margin);
}

std::string describe(const core::LimitEvent& e) {
  const std::string where = " at t = " + core::number(e.t, 6) + " s (sample " + std::to_string(e.sample) + ")";
  const std::string joint = "joint " + std::to_string(e.joint);
  switch (e.kind) {
    case core::LimitKind::kPosition:
      if (e.margin >= 0.0) {  // at (or near) the limit, named as the cause of what follows
        const bool at = e.margin <= core::kLimitTolerance * std::max(1.0, std::abs(e.limit));
        return joint + " position " + core::number(e.value, 6) +
               (at ? " is at its limit " + core::number(e.limit, 6) + where + ", held there"
                   : " is " + core::number(e.margin, 3) + " from its limit " + core::number(e.limit, 6) + where) +
               ": the path needs more of its range";
      }
      return joint + " position " + core::number(e.value, 6) + " is outside its limits" + where + " (by " + core::number(-e.margin, 6) + ")";
    case core::LimitKind::kVelocity:
      return joint + " speed " + core::number(e.value, 6) + " exceeds maxVelocity " + core::number(e.limit, 6) + where;
    case core::LimitKind::kAcceleration:
      return joint + " acceleration " + core::number(e.value, 6) + " exceeds maxAcceleration " + core::number(e.limit, 6) + where;
    case core::LimitKind::kJerk:
      return joint + " jerk " + core::number(e.value, 6) + " (the change of its acceleration over the sample step) exceeds maxJerk " +
             core::number(e.limit, 6) + where +
             ": an acceleration step (a trapezoidal profile, or the time-optimal sweep that optimize.timing.timeOptimal "
             "asks for alone); MOTION_PROFILE_S_CURVE, durationS 0 or optimize.timing.jerkLimited keeps the jerk limits";
    case core::LimitKind::kIk:
      return "the inverse kinematics did not converge" + where + " (position residual " + core::number(e.value, 6) +
             " m): the pose is out of reach or at a singularity";
    case core::LimitKind::kTorque:
      return joint + " torque " + core::number(e.value, 6) + " exceeds maxTorque " + core::number(e.limit, 6) + where +
             " (with the payload; docs/dynamics.md)";
    case core::LimitKind::kBranch:
      return "joint interpolation strays " + core::number(e.value, 6) + " m from the path" + where +
             " (tolerance " + core::number(e.limit, 6) + " m): a branch change or a singularity crossing";
  }
  return "limit event" + where;
}

void to_proto(const core::RobotModel& model, const core::JointMotionReport& report, v1::RobotReport& out) {
  out.set_name(model.name);
  out.set_samples(report.samples);
  out.set_converged_samples(report.converged_samples);
  out.set_max_ik_position_error(report.max_position_error);
  out.set_max_ik_orientation_error(report.max_orientation_error);
  out.set_feasible(report.feasible());
  for (const auto& v : report.violations) to_proto(v, *out.add_violations());
  if (report.converged_samples == 0) {
    // No joint value was measured: the figures below would be their +-infinity starts.
    for (std::size_t j = 0; j < report.joints.size(); ++j) {
      auto* r = out.add_joints();
      r->set_joint(static_cast<std::uint32_t>(j));
      if (j < model.dof()) limit_sources_to_proto(model, j, *r->mutable_limit_sources());
    }
    return;
  }
  for (std::size_t j = 0; j < report.joints.size(); ++j) {
    const auto& u = report.joints[j];
    auto* r = out.add_joints();
    r->set_joint(static_cast<std::uint32_t>(j));
    r->set_min_position(u.min_position);
    r->set_max_position(u.max_position);
    r->set_peak_velocity(u.peak_velocity);
    r->set_peak_acceleration(u.peak_acceleration);
    r->set_velocity_usage(u.velocity_usage);
    r->set_acceleration_usage(u.acceleration_usage);
    if (std::isfinite(u.position_margin)) r->set_position_margin(u.position_margin);  // none: continuous
    if (report.torques) r->set_peak_torque(u.peak_torque);
    if (report.torques && u.torque_usage) r->set_torque_usage(*u.torque_usage);
    if (j < model.dof()) limit_sources_to_proto(model, j, *r->mutable_limit_sources());
  }
  if (std::isfinite(report.tightest_position.margin)) {  // every joint continuous: none
    to_proto(report.tightest_position, *out.mutable_tightest_position());
  }
  to_proto(report.tightest_velocity, *out.mutable_tightest_velocity());
  to_proto(report.tightest_acceleration, *out.mutable_tightest_acceleration());
  out.set_max_midpoint_deviation(report.max_midpoint_deviation);
  out.set_max_midpoint_deviation_t(report.max_midpoint_deviation_t);
  out.set_min_manipulability(report.min_manipulability);
  out.set_min_manipulability_t(report.min_manipulability_t);
  for (const auto& b : report.binding) to_proto(b, *out.add_binding());
}

}  // namespace geotraj::server
