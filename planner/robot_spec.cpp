// A request's robot resolved: see robot_spec.hpp.
#include "planner/robot_spec.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "core/format.hpp"
#include "core/robot/dynamics.hpp"
#include "planner/joint_limits_yaml.hpp"

namespace geotraj::planner {

const core::ValidRobot* RobotCatalog::find(std::string_view name) const {
  for (const auto& m : models) {
    if (m->name == name) return &m;
  }
  return nullptr;
}

namespace {

std::string at(const char* field, std::size_t i) { return std::string(field) + "[" + std::to_string(i) + "]"; }

// robot.jointLimits: each names a joint, each value within [core::kMinJointLimit,
// core::kMaxJointLimit]; the values that are, kept for the model.
std::vector<NamedLimits> checked_joint_limits(const std::vector<NamedLimits>& given, core::Violations& out) {
  std::vector<NamedLimits> kept;
  for (std::size_t k = 0; k < given.size(); ++k) {
    const NamedLimits& l = given[k];
    const std::string field = at("robot.jointLimits", k);
    if (l.joint.empty()) out.push_back({field + ".joint", "is required: the name of one of the model's joints"});
    NamedLimits limits{l.joint, std::nullopt, std::nullopt, std::nullopt, std::nullopt, field};
    const auto take = [&](const std::optional<double>& value, const char* name, const char* unit,
                          std::optional<double>& to) {
      if (!value) return;
      if (auto bad = core::joint_limit_violation(field + "." + name, *value, unit)) {
        out.push_back(std::move(*bad));
      } else {
        to = value;
      }
    };
    take(l.max_velocity, "maxVelocity", "rad/s or m/s", limits.max_velocity);
    take(l.max_acceleration, "maxAcceleration", "rad/s^2 or m/s^2", limits.max_acceleration);
    take(l.max_jerk, "maxJerk", "rad/s^3 or m/s^3", limits.max_jerk);
    take(l.max_torque, "maxTorque", "N m or N", limits.max_torque);
    kept.push_back(std::move(limits));
  }
  return kept;
}

// The model the source names, checked, or nullopt with its violations in `out`: the
// catalogue's as it was checked when it entered, an inline model or a URDF document's checked
// here.
std::optional<core::ValidRobot> source_model(const RobotSpec& spec, const RobotCatalog& catalog,
                                             const StopAt& stop_at, core::Violations& out) {
  if (const auto* by_name = std::get_if<RobotByName>(&spec.source)) {
    if (const auto* model = catalog.find(by_name->name)) return *model;
    std::string names;
    for (const auto& m : catalog.models) names += (names.empty() ? "" : ", ") + m->name;
    out.push_back({"robot.name", "unknown robot '" + by_name->name + "'; the server knows: " + names});
    return std::nullopt;
  }
  if (const auto* written = std::get_if<InlineRobot>(&spec.source)) {
    if (!written->model) return std::nullopt;  // its wire form was refused
    auto valid = core::ValidRobot::check(*written->model);
    if (valid) return std::move(*valid);
    for (auto& v : core::prefixed(std::move(valid.error()), "robot.model.")) out.push_back(std::move(v));
    return std::nullopt;
  }
  if (const auto* urdf = std::get_if<UrdfRobot>(&spec.source)) {
    const UrdfOptions options{spec.base_link, spec.tip_link, {}, stop_at};  // the limits: resolve_robot
    auto model = robot_from_urdf(urdf->urdf, options);
    if (!model) {
      for (auto& v : core::prefixed(std::move(model.error()), "robot.")) out.push_back(std::move(v));
      return std::nullopt;
    }
    // robot_from_urdf checked the model it makes; the proof of it is made here.
    auto valid = core::ValidRobot::check(std::move(*model));
    if (valid) return std::move(*valid);
    for (auto& v : valid.error()) out.push_back({"robot.urdf", "the chain's " + v.field + " " + v.description});
    return std::nullopt;
  }
  out.push_back({"robot", "needs a model: `name` of a built-in model (see ListRobots), an inline `model` or a "
                          "`urdf` document"});
  return std::nullopt;
}

// robot.jointLimits (or a joint_limits.yaml's, named `field`) over the model's, by joint name.
void apply_joint_limits(const std::vector<NamedLimits>& limits, const char* field, core::RobotModel& model,
                        core::Violations& out) {
  const std::size_t before = out.size();
  for (std::size_t k = 0; k < limits.size(); ++k) {
    const auto it = std::find_if(model.joints.begin(), model.joints.end(),
                                 [&](const core::Joint& j) { return j.name == limits[k].joint; });
    if (it == model.joints.end()) {
      std::string names;
      for (const auto& j : model.joints) names += (names.empty() ? "'" : ", '") + j.name + "'";
      out.push_back({at(field, k) + ".joint",
                     "names no joint of the model ('" + limits[k].joint + "'); its joints: " + names});
    } else if (limits[k].max_torque && !core::has_dynamics(model)) {
      out.push_back({at(field, k) + ".maxTorque",
                     "needs a model with the mass properties of every link (its torques are not known): " +
                         model.name + " has none"});
    }
  }
  if (out.size() == before) apply_named_limits(limits, model);
}

// robot.velocityScale and accelerationScale: fractions in (0, 1] of the model's limits, whose
// products must stay within the range every limit keeps (5e-324 times a limit is 0): the
// first joint a scale takes below it is named.
void apply_scales(const RobotSpec& spec, core::RobotModel& model, bool model_known, core::Violations& out) {
  const auto factor = [&out](const std::optional<double>& value, const char* field) {
    if (value && !(std::isfinite(*value) && *value > 0.0 && *value <= 1.0)) {
      out.push_back({field, "must be in (0, 1] (a fraction of the model's limits), got " + core::number(*value)});
    }
    return value.value_or(1.0);
  };
  const double velocity = factor(spec.velocity_scale, "robot.velocityScale");
  const double acceleration = factor(spec.acceleration_scale, "robot.accelerationScale");
  if (!out.empty() || !model_known || (velocity == 1.0 && acceleration == 1.0)) return;
  model = core::with_scaled_limits(std::move(model), velocity, acceleration);
  if (model.limit_sources.empty()) model.limit_sources.assign(model.dof(), core::LimitSources{});
  const auto scaled_by = [](std::string& source, double scale, const char* field) {
    if (scale != 1.0) source = (source.empty() ? "the model's" : source) + " x " + field + " " + core::number(scale);
  };
  for (std::size_t i = 0; i < model.dof(); ++i) {
    core::LimitSources& from = model.limit_sources[i];
    scaled_by(from.velocity, velocity, "robot.velocityScale");
    scaled_by(from.acceleration, acceleration, "robot.accelerationScale");
    if (model.limits[i].max_jerk) scaled_by(from.jerk, acceleration, "robot.accelerationScale");
  }
  const auto scaled = [&](double scale, const char* field, const char* what, auto limit_of) {
    for (std::size_t i = 0; i < model.dof(); ++i) {
      const std::optional<double> limit = limit_of(model.limits[i]);
      if (!limit || core::within_joint_limit_range(*limit)) continue;
      out.push_back({field, core::number(scale) + " makes joint " + std::to_string(i) + " (" + model.joints[i].name +
                                ")'s " + what + " " + core::number(*limit) + ", outside [" +
                                core::number(core::kMinJointLimit) + ", " + core::number(core::kMaxJointLimit) +
                                "]: give a larger scale"});
      return;
    }
  };
  scaled(velocity, "robot.velocityScale", "maxVelocity",
         [](const core::JointLimits& l) { return std::optional<double>(l.max_velocity); });
  scaled(acceleration, "robot.accelerationScale", "maxAcceleration",
         [](const core::JointLimits& l) { return std::optional<double>(l.max_acceleration); });
  scaled(acceleration, "robot.accelerationScale", "maxJerk", [](const core::JointLimits& l) { return l.max_jerk; });
}

// robot.initialJoints: one per joint, finite, within the joints' limits; empty: the home.
core::JointVector initial_joints(const std::vector<double>& given, const core::RobotModel& model,
                                 core::Violations& out) {
  const std::size_t n = model.dof();
  if (given.empty()) return core::home_configuration(model);
  core::JointVector q = core::JointVector::Zero(static_cast<Eigen::Index>(n));
  if (given.size() != n) {
    out.push_back({"robot.initialJoints", "has " + std::to_string(given.size()) + " values for a " + std::to_string(n) +
                                              "-joint robot"});
    return q;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const double v = given[i];
    const auto& l = model.limits[i];
    if (!std::isfinite(v)) {
      out.push_back({at("robot.initialJoints", i), "must be finite, got " + core::number(v, 6)});
    } else if (std::abs(v) > core::kMaxModelMagnitude) {
      out.push_back({at("robot.initialJoints", i), "magnitude must be at most " +
                                                       core::number(core::kMaxModelMagnitude) + ", got " +
                                                       core::number(v, 6)});
    } else if (!core::within_position_limits(model.joints[i].type, l, v)) {
      out.push_back({at("robot.initialJoints", i), core::number(v, 6) + " is outside the joint's limits [" +
                                                       core::number(l.min_position, 6) + ", " +
                                                       core::number(l.max_position, 6) + "]"});
    }
    q(static_cast<Eigen::Index>(i)) = v;
  }
  return q;
}

}  // namespace

core::Expected<Robot> resolve_robot(const RobotSpec& spec, const RobotCatalog& catalog, bool motion,
                                    const StopAt& stop_at) {
  core::Violations out;
  const std::vector<NamedLimits> limits = checked_joint_limits(spec.joint_limits, out);
  // MoveIt's joint_limits.yaml, under the request's jointLimits.
  std::vector<NamedLimits> yaml;
  if (!spec.joint_limits_yaml.empty()) {
    auto from_yaml = joint_limits_from_yaml(spec.joint_limits_yaml, "robot.jointLimitsYaml");
    if (from_yaml) {
      yaml = std::move(*from_yaml);
    } else {
      for (auto& v : from_yaml.error()) out.push_back(std::move(v));
    }
  }
  for (NamedLimits& l : yaml) l.source = "robot.jointLimitsYaml";
  const std::optional<core::ValidRobot> source = source_model(spec, catalog, stop_at, out);
  // A MoveIt configuration describes the whole robot (a gripper's joints too): the file's
  // joints off the chain are not read, but a file that names none of it is refused; its
  // efforts are read on a model with mass properties (elsewhere no torque is known).
  if (source && !yaml.empty()) {
    const auto& joints = (*source)->joints;
    const auto on_chain = [&](const NamedLimits& l) {
      return std::any_of(joints.begin(), joints.end(), [&](const core::Joint& j) { return j.name == l.joint; });
    };
    std::erase_if(yaml, [&](const NamedLimits& l) { return !on_chain(l); });
    if (yaml.empty()) {
      std::string names;
      for (const auto& j : joints) names += (names.empty() ? "'" : ", '") + j.name + "'";
      out.push_back({"robot.jointLimitsYaml", "names none of the model's joints (" + names + ")"});
    }
    if (!core::has_dynamics(**source))
      for (NamedLimits& l : yaml) l.max_torque.reset();
  }
  if (!std::holds_alternative<UrdfRobot>(spec.source) && (!spec.base_link.empty() || !spec.tip_link.empty())) {
    out.push_back({spec.base_link.empty() ? "robot.tipLink" : "robot.baseLink", "is read with `urdf` only"});
  }
  // What the request changes of the source's model (joint limits, base, tool, scales) is made
  // on a copy, checked once more below; a model the request does not change is used as it
  // was checked.
  const bool changes = !limits.empty() || !yaml.empty() || spec.base || spec.tool || spec.velocity_scale ||
                       spec.acceleration_scale || spec.payload;
  std::optional<core::RobotModel> model;
  if (source && changes) model = source->model();
  if (model && out.empty()) apply_joint_limits(yaml, "robot.jointLimitsYaml", *model, out);
  if (model && out.empty()) apply_joint_limits(limits, "robot.jointLimits", *model, out);
  if (model && spec.base) model->base = *spec.base;
  if (model && spec.tool) model->tool = *spec.tool;
  if (spec.payload) {  // a point mass on the tool: a mass and a centre of mass, on a model with dynamics
    const std::size_t before = out.size();
    core::check_inertial("robot.payload", core::Inertial{spec.payload->mass, spec.payload->center_of_mass, Eigen::Matrix3d::Zero()}, out);
    if (model && spec.payload->mass > 0.0 && !core::has_dynamics(*model)) {
      out.push_back({"robot.payload", "needs a model with the mass properties of every link (Joint.inertial, a URDF's "
                                      "<inertial>): " + model->name + " has none"});
    }
    if (model && out.size() == before) model->payload = *spec.payload;
  }
  double branch_tolerance = 1e-3;
  if (spec.branch_tolerance) {
    branch_tolerance = *spec.branch_tolerance;
    if (!(std::isfinite(branch_tolerance) && branch_tolerance > 0.0)) {
      out.push_back({"robot.branchTolerance", "must be finite and > 0 [m], got " + core::number(branch_tolerance, 6)});
    }
  }
  const auto tolerance = [&out](const std::optional<double>& value, const char* field, const char* unit, double fallback) {
    if (!value) return fallback;
    if (!(std::isfinite(*value) && *value > 0.0)) {
      out.push_back({field, std::string("must be finite and > 0 [") + unit + "], got " + core::number(*value)});
    }
    return *value;
  };
  const double start_position_tolerance =
      tolerance(spec.start_position_tolerance, "robot.startPositionTolerance", "m", kStartPositionTolerance);
  const double start_orientation_tolerance =
      tolerance(spec.start_orientation_tolerance, "robot.startOrientationTolerance", "rad", kStartOrientationTolerance);
  if (model) {
    apply_scales(spec, *model, true, out);
  } else {
    core::RobotModel none;
    apply_scales(spec, none, false, out);
  }
  // The request's base and tool over the model's, within the bounds validate_robot keeps.
  for (const auto& [field, X] : {std::pair<const char*, const std::optional<Eigen::Isometry3d>*>{"robot.base", &spec.base},
                                 std::pair<const char*, const std::optional<Eigen::Isometry3d>*>{"robot.tool", &spec.tool}}) {
    if (!*X) continue;
    const double far = (*X)->translation().cwiseAbs().maxCoeff();
    if (std::isfinite(far) && far > core::kMaxModelMagnitude) {
      out.push_back({std::string(field) + ".position", "magnitude must be at most " +
                                                          core::number(core::kMaxModelMagnitude) + " m, got " +
                                                          core::number(far)});
    }
  }
  if (spec.tool_axis_free && !motion) {
    out.push_back({"robot.toolAxisFree", "frees the tool's roll along a planned motion; the kinematics calls take the "
                                         "full pose: drop it"});
  } else if (spec.tool_axis_free && source &&
             ((*source)->dof() < 6 || (*source)->dof() >= core::kMaxJoints)) {
    out.push_back({"robot.toolAxisFree", "needs an arm of 6 to " + std::to_string(core::kMaxJoints - 1) + " joints: " +
                                             (*source)->name + " has " + std::to_string((*source)->dof()) +
                                             ((*source)->dof() < 6 ? ", too few to hold the tool's position and axis"
                                                                   : ", and the roll is one joint more")});
  }
  core::JointVector seed;
  if (source && (*source)->dof() > 0) seed = initial_joints(spec.initial_joints, model ? *model : source->model(), out);
  // A motion is timed within every joint's acceleration limit, or checked against it; the
  // kinematics read none.
  if (source && motion) {
    if (std::string why = missing_accelerations(model ? *model : source->model()); !why.empty()) {
      out.push_back({"robot.jointLimits", std::move(why)});
    }
  }
  // No model and nothing said: an inline model whose wire form was refused, and named there.
  if (!source || !out.empty()) return tl::unexpected(std::move(out));
  core::ValidRobot valid = *source;
  if (model) {
    // Every change was checked above, each where the request wrote it; what they make
    // together is checked once more here, and the model carries the proof from here on.
    auto changed = core::ValidRobot::check(std::move(*model));
    if (!changed) return tl::unexpected(core::prefixed(std::move(changed.error()), "robot.model."));
    valid = std::move(*changed);
  }
  Robot robot(std::move(valid), std::move(seed));
  robot.report_only = spec.report_only;
  robot.tool_axis_free = spec.tool_axis_free;
  robot.branch_tolerance = branch_tolerance;
  robot.start_position_tolerance = start_position_tolerance;
  robot.start_orientation_tolerance = start_orientation_tolerance;
  robot.inline_model = !std::holds_alternative<RobotByName>(spec.source) &&
                       !std::holds_alternative<std::monostate>(spec.source);
  robot.approach = spec.approach;
  return robot;
}

}  // namespace geotraj::planner
