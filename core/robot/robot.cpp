// Robot models: validation and the built-in arms. See robot.hpp.
#include "core/robot/robot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <memory>
#include <numbers>
#include <string>

#include <Eigen/Eigenvalues>

#include "core/format.hpp"

namespace geotraj::core {
namespace {

std::string idx(const char* what, std::size_t i, const char* field) {
  return std::string(what) + "[" + std::to_string(i) + "]." + field;
}

// A field of the model, spelled out only when a violation names it: validate_robot runs on
// every plan, and building "limits[3].maxVelocity" for each value it checks cost more than
// the checks themselves (3.8 of a joint move's 4.9 us).
struct Field {
  static constexpr std::size_t kWhole = static_cast<std::size_t>(-1);
  const char* group;  ///< "links", "joints", "limits", or the whole name ("flange")
  std::size_t index = kWhole;
  const char* name = nullptr;
  std::string path() const { return index == kWhole ? std::string(group) : idx(group, index, name); }
};

void check_rotation(const Eigen::Isometry3d& X, const char* field, Violations& out) {
  const Eigen::Matrix3d R = X.linear();
  if (!R.allFinite() || !X.translation().allFinite()) {
    out.push_back({std::string(field), "must be finite"});
    return;
  }
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-9 || R.determinant() < 0.0) {
    out.push_back({std::string(field) + ".orientation", "is not a rotation (give a unit quaternion)"});
  }
}

constexpr double deg = std::numbers::pi / 180.0;

JointLimits revolute_limits(double range_deg, double speed_deg_s, double accel_deg_s2) {
  return JointLimits{-range_deg * deg, range_deg * deg, speed_deg_s * deg, accel_deg_s2 * deg, std::nullopt};
}

Eigen::Isometry3d rot_x(double angle) {
  return Eigen::Isometry3d(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitX()));
}
Eigen::Isometry3d rot_z(double angle) {
  return Eigen::Isometry3d(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
}
Eigen::Isometry3d trans(double x, double z) {
  return Eigen::Isometry3d(Eigen::Translation3d(x, 0.0, z));
}

// Mitsubishi PA-10 (PA10-7C), the thesis's demonstration arm (7.2.2). Modified DH (Craig,
// Eq. 1.3): alternating +-90 degree twists, shoulder height 0.317 m, upper arm 0.45 m,
// forearm 0.48 m, wrist to flange 0.07 m (the tool offset). Joint ranges and speeds are the
// manufacturer's PA10-7C specification (S1 177, S2 94, S3 174, E1 137, E2 255, W1 165,
// W2 255 degrees; 57 deg/s on S1, S2, 114 deg/s on S3, E1, 360 deg/s on E2, W1, W2).
// Acceleration limits are not published: 2 x the speed limit per second is assumed.
void name_joints(DhTable& t, std::initializer_list<const char*> names) {
  std::size_t i = 0;
  for (const char* name : names) t.links[i++].name = name;
}

RobotModel pa10() {
  RobotModel m;
  m.name = "pa10";
  m.description =
      "Mitsubishi PA-10 (PA10-7C), 7-DOF redundant arm of the thesis's demonstration (7.2.2). Modified DH "
      "(Craig, thesis Eq. 1.3): shoulder 0.317 m, upper arm 0.45 m, forearm 0.48 m, flange 0.07 m (tool). "
      "Ranges and speeds: Mitsubishi Heavy Industries PA10-7C specification. Accelerations: not published; "
      "assumed 2 x the speed limit per second.";
  DhTable t;
  t.convention = DhConvention::kModified;
  const double h = std::numbers::pi / 2.0;
  //        a    alpha  d      theta
  t.links = {{0.0, 0.0, 0.317, 0.0},  {0.0, -h, 0.0, 0.0}, {0.0, h, 0.45, 0.0}, {0.0, -h, 0.0, 0.0},
             {0.0, h, 0.48, 0.0},     {0.0, -h, 0.0, 0.0}, {0.0, h, 0.0, 0.0}};
  m.limits = {revolute_limits(177, 57, 114),  revolute_limits(94, 57, 114),   revolute_limits(174, 114, 228),
              revolute_limits(137, 114, 228), revolute_limits(255, 360, 720), revolute_limits(165, 360, 720),
              revolute_limits(255, 360, 720)};
  m.tool.translation() = Eigen::Vector3d(0.0, 0.0, 0.07);
  // The thesis's start pose (frame 1 of Table 7.8, "home": p_WT = (0.106, 0, 0.975) m with
  // the base at the world origin, tool z along +x, tool y along -y, R_WT = [-B N T]) to
  // 2e-7 m and 4e-7 rad: the arm in the x-z plane (S1 = S3 = E2 = 0), shoulder back
  // -43.6 deg, elbow 89.8 deg, wrist 43.8 deg (pitches summing to 90 deg), and W2 = -180 deg
  // (W2 = +180 deg is the same pose, but the demo paths then turn W2 to within 0.02 rad of
  // its +255 deg limit; from -180 deg they keep it 1.3 rad away).
  m.home = {0.0, -0.761313, 0.0, 1.567648, 0.0, 0.764461, -std::numbers::pi};
  name_joints(t, {"S1", "S2", "S3", "E1", "E2", "W1", "W2"});  // Mitsubishi's names, shoulder to wrist
  set_dh(m, std::move(t));
  return m;
}

// Universal Robots UR5 (CB3), 6 DOF, standard DH as published by Universal Robots ("DH
// parameters for calculations of kinematics and dynamics"): d1 0.089159, a2 -0.425,
// a3 -0.39225, d4 0.10915, d5 0.09465, d6 0.0823 m; alpha 90, 0, 0, 90, -90, 0 degrees.
// Ranges +-360 degrees and speeds 180 deg/s per the UR5 technical specification.
// Acceleration limits are not published: 2 x the speed limit per second is assumed.
RobotModel ur5() {
  RobotModel m;
  m.name = "ur5";
  m.description =
      "Universal Robots UR5 (CB3), 6-DOF. Standard DH from Universal Robots' published DH parameters. Ranges "
      "+-360 deg and speeds 180 deg/s: UR5 technical specification. Accelerations: not published; assumed 2 x "
      "the speed limit per second.";
  DhTable t;
  t.convention = DhConvention::kStandard;
  const double h = std::numbers::pi / 2.0;
  //        a         alpha  d         theta
  t.links = {{0.0, h, 0.089159, 0.0},  {-0.425, 0.0, 0.0, 0.0}, {-0.39225, 0.0, 0.0, 0.0},
             {0.0, h, 0.10915, 0.0},   {0.0, -h, 0.09465, 0.0}, {0.0, 0.0, 0.0823, 0.0}};
  for (int i = 0; i < 6; ++i) m.limits.push_back(revolute_limits(360, 180, 360));
  m.home = {0.0, -h, h, -h, -h, 0.0};
  name_joints(t, {"shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"});  // Universal Robots' names
  set_dh(m, std::move(t));
  return m;
}

}  // namespace

Inertial in_frame(const Inertial& body, const Eigen::Isometry3d& X_ab) {
  const Eigen::Matrix3d R = X_ab.linear();
  return Inertial{body.mass, X_ab * body.center_of_mass, R * body.inertia * R.transpose()};
}

Inertial combined(const Inertial& a, const Inertial& b) {
  const double mass = a.mass + b.mass;
  if (!(mass > 0.0)) return Inertial{0.0, a.center_of_mass, a.inertia + b.inertia};
  const Eigen::Vector3d c = (a.mass * a.center_of_mass + b.mass * b.center_of_mass) / mass;
  const auto moved = [&](const Inertial& body) {
    const Eigen::Vector3d r = body.center_of_mass - c;
    return Eigen::Matrix3d(body.inertia + body.mass * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose()));
  };
  return Inertial{mass, c, moved(a) + moved(b)};
}

void set_dh(RobotModel& model, DhTable table) {
  const bool modified = table.convention == DhConvention::kModified;
  const std::size_t n = table.links.size();
  model.joints.assign(n, Joint{});
  // The fixed part of link i: theta and d with the offset on the joint's own variable.
  const auto fixed = [](const DhLink& l, bool modified_form) {
    const bool revolute = l.type != JointType::kPrismatic;
    const double theta = l.theta + (revolute ? l.offset : 0.0), d = l.d + (revolute ? 0.0 : l.offset);
    return modified_form ? rot_x(l.alpha) * trans(l.a, 0.0) * rot_z(theta) * trans(0.0, d)   // (1.3)
                         : rot_z(theta) * trans(0.0, d) * trans(l.a, 0.0) * rot_x(l.alpha);  // F_i
  };
  for (std::size_t i = 0; i < n; ++i) {
    Joint& j = model.joints[i];
    const DhLink& link = table.links[i];
    j.name = link.name;
    j.type = link.type;
    j.axis = Eigen::Vector3d::UnitZ();
    if (modified) {
      j.origin = fixed(link, true);
    } else {
      j.origin = i == 0 ? Eigen::Isometry3d::Identity() : fixed(table.links[i - 1], false);
    }
    if (link.inertial)  // standard form: frame i = (the joint's frame after its motion) * F_i
      j.inertial = modified ? *link.inertial : in_frame(*link.inertial, fixed(link, false));
  }
  model.flange = !modified && n > 0 ? fixed(table.links[n - 1], false) : Eigen::Isometry3d::Identity();
  model.dh = std::move(table);
}

namespace {

void check_magnitude(const Field& field, double v, Violations& out) {
  if (!std::isfinite(v)) {
    out.push_back({field.path(), "must be finite, got " + number(v)});
  } else if (std::abs(v) > kMaxModelMagnitude) {
    out.push_back({field.path(), "magnitude must be at most " + number(kMaxModelMagnitude) + ", got " + number(v)});
  }
}

void check_name(const Field& field, const std::string& name, Violations& out) {
  if (name.size() > kMaxJointName) {
    out.push_back({field.path(), "has " + std::to_string(name.size()) + " bytes; at most " + std::to_string(kMaxJointName)});
  }
}

// A fixed transform of the chain: finite, lengths within kMaxModelMagnitude, a rotation.
void check_transform(const Field& field, const Eigen::Isometry3d& X, Violations& out) {
  const Eigen::Matrix3d R = X.linear();
  const Eigen::Vector3d p = X.translation();
  if (!R.allFinite() || !p.allFinite()) {
    out.push_back({field.path(), "must be finite"});
    return;
  }
  if (p.cwiseAbs().maxCoeff() > kMaxModelMagnitude) {
    out.push_back({field.path() + ".position", "magnitude must be at most " + number(kMaxModelMagnitude)});
  }
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-9 || R.determinant() < 0.0) {
    out.push_back({field.path() + ".orientation", "is not a rotation (give a unit quaternion)"});
  }
}

}  // namespace

void check_inertial(const std::string& field, const Inertial& in, Violations& out) {
  if (!std::isfinite(in.mass) || in.mass < 0.0 || in.mass > kMaxModelMagnitude)
    out.push_back({field + ".mass", "must be in [0, " + number(kMaxModelMagnitude) + "] kg, got " + number(in.mass)});
  if (!in.center_of_mass.allFinite() || in.center_of_mass.cwiseAbs().maxCoeff() > kMaxModelMagnitude)
    out.push_back({field + ".centerOfMass", "must be finite, within " + number(kMaxModelMagnitude) + " m"});
  const Eigen::Matrix3d& I = in.inertia;
  if (!I.allFinite() || I.cwiseAbs().maxCoeff() > kMaxModelMagnitude) {
    out.push_back({field + ".inertia", "must be finite, each entry within " + number(kMaxModelMagnitude) + " kg m^2"});
    return;
  }
  const double tolerance = 1e-9 * std::max(1.0, I.cwiseAbs().maxCoeff());
  if ((I - I.transpose()).cwiseAbs().maxCoeff() > tolerance) {
    out.push_back({field + ".inertia", "must be symmetric"});
    return;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  const Eigen::Vector3d moments = solver.computeDirect(I, Eigen::EigenvaluesOnly).eigenvalues();  // ascending
  if (moments(0) < -tolerance)
    out.push_back({field + ".inertia", "must be positive semi-definite, has a principal moment " + number(moments(0))});
  else if (moments(0) + moments(1) < moments(2) - tolerance)
    out.push_back({field + ".inertia", "principal moments " + number(moments(0)) + ", " + number(moments(1)) + ", " +
                                           number(moments(2)) + " break the triangle inequality: no body has them"});
}

Violations validate_robot(const RobotModel& model) {
  Violations out;
  const char* joints_field = model.dh ? "links" : "joints";
  if (model.joints.empty()) out.push_back({joints_field, "must list at least one joint"});
  if (model.joints.size() > kMaxJoints) {
    out.push_back({joints_field, "has " + std::to_string(model.joints.size()) + " joints; at most " +
                                     std::to_string(kMaxJoints) + " are supported"});
  }
  if (model.limits.size() != model.joints.size()) {
    out.push_back({"limits", "has " + std::to_string(model.limits.size()) + " entries for " +
                                 std::to_string(model.joints.size()) + " joints: give one per joint"});
  }
  if (!model.limit_sources.empty() && model.limit_sources.size() != model.joints.size()) {
    out.push_back({"limitSources", "has " + std::to_string(model.limit_sources.size()) + " entries for " +
                                       std::to_string(model.joints.size()) + " joints: none, or one per joint"});
  }
  if (model.dh) {  // the joints are derived from the table: its rows are what the user wrote
    for (std::size_t i = 0; i < model.dh->links.size(); ++i) {
      const DhLink& l = model.dh->links[i];
      const std::pair<const char*, double> values[] = {
          {"a", l.a}, {"alpha", l.alpha}, {"d", l.d}, {"theta", l.theta}, {"offset", l.offset}};
      for (const auto& [name, v] : values) check_magnitude({"links", i, name}, v, out);
      check_name({"links", i, "name"}, l.name, out);
      if (l.inertial) check_inertial(idx("links", i, "inertial"), *l.inertial, out);
    }
  } else {
    for (std::size_t i = 0; i < model.joints.size(); ++i) {
      const Joint& j = model.joints[i];
      check_transform({"joints", i, "origin"}, j.origin, out);
      if (!j.axis.allFinite() || std::abs(j.axis.norm() - 1.0) > 1e-9) {
        out.push_back({idx("joints", i, "axis"), "must be a unit vector, got length " + number(j.axis.norm())});
      }
      check_name({"joints", i, "name"}, j.name, out);
      if (j.inertial) check_inertial(idx("joints", i, "inertial"), *j.inertial, out);
    }
    check_transform({"flange"}, model.flange, out);
  }
  for (std::size_t i = 0; i < model.limits.size(); ++i) {
    const JointLimits& l = model.limits[i];
    const bool continuous = i < model.joints.size() && model.joints[i].type == JointType::kContinuous;
    for (const auto& [name, v] : {std::pair<const char*, double>{"minPosition", l.min_position},
                                  std::pair<const char*, double>{"maxPosition", l.max_position}}) {
      if (continuous) break;  // not read
      check_magnitude({"limits", i, name}, v, out);
    }
    if (!continuous && std::isfinite(l.min_position) && std::isfinite(l.max_position) &&
        l.min_position > l.max_position) {
      out.push_back({idx("limits", i, "minPosition"),
                     number(l.min_position) + " is above maxPosition " + number(l.max_position)});
    }
    const bool prismatic = i < model.joints.size() && model.joints[i].type == JointType::kPrismatic;
    const auto rate = [&](const char* name, double v, const char* rad_unit, const char* m_unit) {
      if (within_joint_limit_range(v)) return;
      if (auto bad = joint_limit_violation(idx("limits", i, name), v, prismatic ? m_unit : rad_unit)) {
        out.push_back(std::move(*bad));
      }
    };
    rate("maxVelocity", l.max_velocity, "rad/s", "m/s");
    rate("maxAcceleration", l.max_acceleration, "rad/s^2", "m/s^2");
    if (l.max_jerk) rate("maxJerk", *l.max_jerk, "rad/s^3", "m/s^3");
    if (l.max_torque) rate("maxTorque", *l.max_torque, "N m", "N");
  }
  if (model.payload.mass != 0.0 || !model.payload.center_of_mass.isZero()) {
    check_inertial("payload", Inertial{model.payload.mass, model.payload.center_of_mass, Eigen::Matrix3d::Zero()}, out);
    const bool dynamics = std::all_of(model.joints.begin(), model.joints.end(),
                                      [](const Joint& j) { return j.inertial.has_value(); });
    if (model.payload.mass > 0.0 && !dynamics && !model.joints.empty())
      out.push_back({"payload", "needs the mass properties of every link (an inertial per joint or link): the model has none"});
  }
  check_rotation(model.base, "base", out);
  check_rotation(model.tool, "tool", out);
  for (const auto& [name, X] : {std::pair<const char*, const Eigen::Isometry3d*>{"base", &model.base},
                                std::pair<const char*, const Eigen::Isometry3d*>{"tool", &model.tool}}) {
    if (X->translation().allFinite() && X->translation().cwiseAbs().maxCoeff() > kMaxModelMagnitude) {
      out.push_back({std::string(name) + ".position",
                     "magnitude must be at most " + number(kMaxModelMagnitude) + " m, got " +
                         number(X->translation().cwiseAbs().maxCoeff())});
    }
  }
  if (!model.home.empty()) {
    if (model.home.size() != model.joints.size()) {
      out.push_back({"home", "has " + std::to_string(model.home.size()) + " values for " +
                                 std::to_string(model.joints.size()) + " joints"});
    } else if (model.limits.size() == model.joints.size()) {
      for (std::size_t i = 0; i < model.home.size(); ++i) {
        const double q = model.home[i];
        if (!std::isfinite(q) || std::abs(q) > kMaxModelMagnitude ||
            !within_position_limits(model.joints[i].type, model.limits[i], q)) {
          out.push_back({"home[" + std::to_string(i) + "]", number(q) + " is outside the joint's limits [" +
                                                                  number(model.limits[i].min_position) + ", " +
                                                                  number(model.limits[i].max_position) + "]"});
        }
      }
    }
  }
  return out;
}

std::optional<FieldViolation> joint_limit_violation(const std::string& field, double value, std::string_view unit) {
  if (within_joint_limit_range(value)) return std::nullopt;
  return FieldViolation{field, "must be > 0, in [" + number(kMinJointLimit) + ", " + number(kMaxJointLimit) + "] " +
                                   std::string(unit) + ", got " + number(value)};
}

const std::vector<RobotModel>& builtin_robots() {
  static const std::vector<RobotModel> robots = {pa10(), ur5()};
  return robots;
}

const RobotModel* find_builtin_robot(std::string_view name) {
  for (const auto& m : builtin_robots()) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

RobotModel with_scaled_limits(RobotModel model, double velocity, double acceleration) {
  for (JointLimits& l : model.limits) {
    l.max_velocity *= velocity;
    l.max_acceleration *= acceleration;
    if (l.max_jerk) *l.max_jerk *= acceleration;
  }
  return model;
}

double jerk_bound(const JointLimits& limits, double ramp_s) {
  return limits.max_jerk ? *limits.max_jerk : std::min(kMaxJointLimit, limits.max_acceleration / ramp_s);
}

bool jerk_limited(const RobotModel& model) {
  return std::all_of(model.limits.begin(), model.limits.end(), [](const JointLimits& l) { return l.max_jerk.has_value(); });
}

RobotModel with_default_jerk(RobotModel model, double ramp_s) {
  if (model.limit_sources.empty()) model.limit_sources.assign(model.dof(), LimitSources{});
  for (std::size_t i = 0; i < model.dof(); ++i) {
    if (!model.limits[i].max_jerk) {
      model.limit_sources[i].jerk = "default: maxAcceleration / " + number(ramp_s) + " s";
    }
    model.limits[i].max_jerk = jerk_bound(model.limits[i], ramp_s);
  }
  return model;
}

ValidRobot with_default_jerk(const ValidRobot& robot, double ramp_s) {
  // max_acceleration in [kMinJointLimit, kMaxJointLimit] over ramp_s in (0, 1] is at least
  // kMinJointLimit; jerk_bound caps it at kMaxJointLimit.
  GEOTRAJ_CHECK(ramp_s > 0.0 && ramp_s <= 1.0);
  if (jerk_limited(robot)) return robot;
  return ValidRobot(std::make_shared<const RobotModel>(with_default_jerk(robot.model(), ramp_s)));
}

ValidRobot with_tool_roll(const ValidRobot& robot) {
  GEOTRAJ_CHECK(robot->dof() < kMaxJoints);
  RobotModel model = robot.model();
  Joint roll;
  roll.name = std::string(kToolRollJoint);
  roll.type = JointType::kContinuous;
  roll.origin = model.flange * model.tool;
  roll.axis = Eigen::Vector3d::UnitZ();
  model.joints.push_back(std::move(roll));
  JointLimits limits;
  limits.min_position = -std::numbers::pi;  // not read (continuous)
  limits.max_position = std::numbers::pi;
  limits.max_velocity = kMaxJointLimit;
  limits.max_acceleration = kMaxJointLimit;
  model.limits.push_back(limits);
  if (!model.limit_sources.empty()) {
    const std::string unlimited = "the tool's roll (unlimited)";
    model.limit_sources.push_back({unlimited, unlimited, "", "", true});
  }
  model.flange = Eigen::Isometry3d::Identity();
  model.tool = Eigen::Isometry3d::Identity();
  if (!model.home.empty()) model.home.push_back(0.0);
  model.dh.reset();
  return ValidRobot(std::make_shared<const RobotModel>(std::move(model)));
}

Expected<ValidRobot> ValidRobot::check(RobotModel model) {
  if (Violations v = validate_robot(model); !v.empty()) return tl::make_unexpected(std::move(v));
  return ValidRobot(std::make_shared<const RobotModel>(std::move(model)));
}

JointVector home_configuration(const RobotModel& model) {
  JointVector q = JointVector::Zero(static_cast<Eigen::Index>(model.dof()));
  if (model.home.size() == model.dof()) {
    for (std::size_t i = 0; i < model.dof(); ++i) q(static_cast<Eigen::Index>(i)) = model.home[i];
  }
  return q;
}

}  // namespace geotraj::core
