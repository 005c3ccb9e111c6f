// Serial manipulators (thesis 1.1.2; Table 6.1's manipulator parameters): the immutable model
// that kinematics.hpp, ik.hpp and joint_motion.hpp work on. Units: metres and radians (a
// prismatic joint's value is in metres); limits per joint in [rad] or [m], per second, per
// second squared.
//
// A general serial chain (the form of URDF, KDL and Pinocchio): joint i is a fixed transform
// O_i (its origin, in the frame of the joint before it after that joint's motion; in the
// robot's base frame for joint 1) followed by a motion M_i(q_i) about (revolute,
// continuous) or along (prismatic) a fixed unit axis a_i of the frame O_i ends in:
//   X_WT = base * O_1 M_1(q_1) * O_2 M_2(q_2) * ... * O_n M_n(q_n) * flange * tool,
//   M_i(q) = Rot(a_i, q) or Trans(q a_i),
// flange the fixed transform from the last joint's frame to the last link (URDF: the tip
// link; DH: frame n), tool the tool in that link's frame.
//
// Denavit-Hartenberg tables (thesis Eq. 1.3) are one way of writing such a chain (dh_joints):
//   modified DH (Craig; the thesis's Eq. 1.3): A_i = RotX(alpha_i) TransX(a_i) RotZ(theta_i*) TransZ(d_i*)
//     (row i holds alpha_{i-1}, a_{i-1} of Eq. 1.3: the twist and length BEFORE joint i),
//   standard DH:                               A_i = RotZ(theta_i*) TransZ(d_i*) TransX(a_i) RotX(alpha_i),
// with theta_i* = theta_i + offset_i + q_i and d_i* = d_i for a revolute joint, and
// theta_i* = theta_i, d_i* = d_i + offset_i + q_i for a prismatic one; the pose is
// base * A_1(q_1) ... A_n(q_n) * tool.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/error.hpp"

namespace geotraj::core {

/// Most joints a model may have: joint-space values are fixed-capacity Eigen vectors, so
/// the sampling loop never allocates.
inline constexpr std::size_t kMaxJoints = 12;

/// Joint values, velocities or accelerations [rad or m, per s, per s^2], one per joint.
using JointVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, static_cast<int>(kMaxJoints), 1>;
/// A 6 x n matrix whose rows are (linear [m], angular [rad]) and columns joints.
using JointJacobian = Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::ColMajor, 6, static_cast<int>(kMaxJoints)>;
/// A spatial vector: linear part (rows 0-2) then angular part (rows 3-5), in W.
using Vector6d = Eigen::Matrix<double, 6, 1>;

enum class DhConvention {
  kModified,  ///< Craig's convention, the thesis's Eq. (1.3)
  kStandard,  ///< the classic (distal) convention
};

/// How a joint moves: about its axis within position limits, about it without end (URDF
/// `continuous`: the position limits are not read, every angle is allowed), or along it.
enum class JointType { kRevolute, kPrismatic, kContinuous };

/// Whether the joint turns (revolute or continuous) rather than slides.
constexpr bool turns(JointType type) { return type != JointType::kPrismatic; }

/// The mass properties of a rigid body (proto Inertial, URDF `<inertial>`): its mass [kg],
/// its centre of mass c [m] and its rotational inertia I [kg m^2] about c, both in the body's
/// frame. I is symmetric and positive semi-definite, its principal moments obey the triangle
/// inequality (validate_robot).
struct Inertial {
  double mass = 0.0;
  Eigen::Vector3d center_of_mass = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
};

/// Mass properties given in frame b, in frame a (X_ab: frame b in frame a): the centre of
/// mass moved, the inertia turned (R I R^T).
Inertial in_frame(const Inertial& body, const Eigen::Isometry3d& X_ab);

/// Two bodies in one frame as one rigid body: the total mass at the combined centre of mass,
/// each inertia moved there by the parallel-axis theorem (I + m (|r|^2 1 - r r^T)).
Inertial combined(const Inertial& a, const Inertial& b);

/// One joint of a general chain (see the top of this file). Lengths [m].
struct Joint {
  /// The joint's name for people ("panda_joint1"); joints are numbered from 0 at the base
  /// everywhere, the name says which one that is. At most kMaxJointName bytes.
  std::string name{};
  JointType type = JointType::kRevolute;
  /// O_i: the joint's frame in the frame of the joint before it after that joint's motion
  /// (in the robot's base frame for joint 0).
  Eigen::Isometry3d origin = Eigen::Isometry3d::Identity();
  /// a_i: the unit axis the joint turns about or slides along, in its frame.
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  /// The link the joint moves, in the joint's frame after its motion (O_i M_i(q_i) ends
  /// there); for the last joint the flange and tool are on that link. None: the model gives
  /// no dynamics (core/robot/dynamics.hpp needs every joint's).
  std::optional<Inertial> inertial{};
};

/// One row of the DH table (proto DhLink). Lengths [m], angles [rad].
struct DhLink {
  double a = 0.0;
  double alpha = 0.0;
  double d = 0.0;
  double theta = 0.0;
  JointType type = JointType::kRevolute;
  double offset = 0.0;  ///< added to theta (revolute) [rad] or d (prismatic) [m] with q
  /// The joint's name for people ("S1", "shoulder_pan"); joints are numbered from 0 at the
  /// base everywhere, the name says which one that is. Empty: none. At most kMaxJointName bytes.
  std::string name{};
  /// The link the joint moves, in the table's frame i (set_dh moves it to Joint::inertial's
  /// frame: the same in the modified form; standard: frame i is that frame times the row's
  /// fixed part).
  std::optional<Inertial> inertial{};
};

/// The longest joint name [bytes].
inline constexpr std::size_t kMaxJointName = 64;

/// The largest |length| of a model (a, d, offset [m]) and |joint value| (position limits,
/// joint values given to the kinematics [rad or m]): far beyond any arm, and small enough
/// that no pose, Jacobian or manipulability of 12 joints overflows.
inline constexpr double kMaxModelMagnitude = 1e6;

/// The range of every joint rate limit (maxVelocity [rad/s or m/s], maxAcceleration
/// [rad/s^2 or m/s^2], maxJerk [rad/s^3 or m/s^3]), as given and after a request's scaling:
/// nine orders of magnitude either side of 1, far beyond any arm (the built-in ones use 0.5 to
/// 1e4), and narrow enough that their products and quotients in the timings and the jog
/// (v s, a / 0.05 s, v^2 / a, a^3 / j^2, ...) stay finite and normal: an acceleration of
/// 1e308 or a velocity of 5e-324 is refused, never carried into a computation that overflows.
inline constexpr double kMinJointLimit = 1e-9;
inline constexpr double kMaxJointLimit = 1e9;

/// Whether `x` is a usable joint rate limit: in [kMinJointLimit, kMaxJointLimit] (so finite).
inline bool within_joint_limit_range(double x) { return x >= kMinJointLimit && x <= kMaxJointLimit; }

/// One joint's limits (proto JointLimits).
struct JointLimits {
  double min_position = 0.0;   ///< [rad or m]
  double max_position = 0.0;   ///< [rad or m], >= min_position
  double max_velocity = 0.0;   ///< [rad/s or m/s], in [kMinJointLimit, kMaxJointLimit]
  double max_acceleration = 0.0;  ///< [rad/s^2 or m/s^2], in [kMinJointLimit, kMaxJointLimit]
  std::optional<double> max_jerk;  ///< [rad/s^3 or m/s^3], in that range; absent: unlimited
  /// [N m or N] (URDF's <limit effort>), in that range; absent: none given.
  std::optional<double> max_torque{};
};

/// Where a joint's rate and torque limits come from, as a plan's report and ListRobots say it
/// (text for the user: "URDF <limit velocity>, line 12", "robot.jointLimits[0]",
/// "joint_limits.yaml (robot.jointLimitsYaml)"). An empty source is the model's own (a
/// built-in or inline model's), or no such limit (jerk, torque).
struct LimitSources {
  std::string velocity, acceleration, jerk, torque;
  /// False where nothing gave the joint an acceleration limit (a URDF as shipped: URDF has no
  /// field for one): JointLimits::max_acceleration then holds kMaxJointLimit, which the
  /// kinematics never read, and a motion is refused (planner::resolve_robot) until a limit is
  /// given.
  bool acceleration_known = true;
};

/// Whether joint value q is within the joint's position limits (always, for a continuous
/// joint, whose limits are not read).
inline bool within_position_limits(JointType type, const JointLimits& l, double q) {
  return type == JointType::kContinuous || (q >= l.min_position && q <= l.max_position);
}

/// A DH table (proto RobotModel.links and dhConvention): one row per joint, base outwards.
struct DhTable {
  DhConvention convention = DhConvention::kModified;
  std::vector<DhLink> links;
};

/// A load on the tool (proto Payload): its mass [kg] at its centre of mass [m] in the tool
/// frame T, a point mass (its own rotational inertia neglected, as a robot's payload rating
/// gives it).
struct Payload {
  double mass = 0.0;
  Eigen::Vector3d center_of_mass = Eigen::Vector3d::Zero();
};

/// A serial arm. A value: copy it to change it (base and tool of a request replace the
/// model's own).
struct RobotModel {
  std::string name;
  std::string description;  ///< manufacturer, source of the parameters
  std::vector<Joint> joints;        ///< one per moving joint, base outwards
  std::vector<JointLimits> limits;  ///< one per joint
  /// X_n,F: the last link's frame in the last joint's frame (after its motion).
  Eigen::Isometry3d flange = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();  ///< X_W,base: robot base in W
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();  ///< X_F,T: tool in the last link's frame
  /// The home configuration [rad or m] (the IK seed of a request without initialJoints);
  /// within the limits. Empty means all zeros.
  std::vector<double> home;
  /// The DH table the joints and flange were written from (set_dh), reported back in that
  /// form; empty for a chain given otherwise (URDF, general joints).
  std::optional<DhTable> dh;
  /// What the tool carries (RobotSpec.payload): a point mass at a point of the tool frame T,
  /// in every inverse-dynamics call of the model (dynamics_options); none by default.
  Payload payload{};
  /// Where each joint's limits come from: empty (the model's own), or one per joint.
  std::vector<LimitSources> limit_sources;

  std::size_t dof() const { return joints.size(); }
  /// Whether joint i has an acceleration limit that something gave (LimitSources).
  bool acceleration_known(std::size_t i) const {
    return limit_sources.empty() || limit_sources[i].acceleration_known;
  }
};

/// The joints and flange of a DH table (see the top of this file), exactly:
///   modified:  O_i = RotX(alpha_i) TransX(a_i) RotZ(theta_i + offset_i) TransZ(d_i) (revolute;
///              prismatic: RotZ(theta_i) TransZ(d_i + offset_i)), M_i about or along z,
///              flange = identity (RotZ(q) and TransZ(q) commute with RotZ and TransZ);
///   standard:  A_i = M_i(q_i) F_i with F_i = RotZ(theta_i + offset_i) TransZ(d_i) TransX(a_i)
///              RotX(alpha_i) (revolute; the offset on d for prismatic), regrouped
///              base * M_1 (F_1 M_2) ... (F_{n-1} M_n) F_n * tool: O_1 = identity,
///              O_i = F_{i-1}, flange = F_n.
/// Sets model.joints, model.flange and model.dh (the table kept as given); names from the rows.
void set_dh(RobotModel& model, DhTable table);

/// Every problem with `model` (field paths relative to the model, proto JSON names):
/// `joints` (none, or more than kMaxJoints; `links` for a DH model), `limits` (not one per
/// joint), `limitSources` (neither empty nor one per joint), `links[i].a` ... not finite (a DH
/// model), `joints[i].origin` not finite or not a rigid transform, `joints[i].axis` not a unit vector, `flange`, `limits[i].minPosition` >
/// maxPosition, `limits[i].maxVelocity`, `limits[i].maxAcceleration`, `limits[i].maxJerk` not
/// finite or outside [kMinJointLimit, kMaxJointLimit] (joint_limit_violation),
/// `base.orientation` / `tool.orientation` not a rotation, `base.position` / `tool.position`
/// beyond kMaxModelMagnitude, `home` of the wrong size or outside the limits, `payload.mass`
/// and `payload.centerOfMass` as check_inertial's, `payload` on a model without every link's
/// mass properties. Empty when the model is usable.
Violations validate_robot(const RobotModel& model);

/// Appends to `out` what makes `in` no body's, named `field`.mass, .centerOfMass, .inertia:
/// a mass outside [0, kMaxModelMagnitude] kg or not finite, a centre of mass not finite or
/// beyond kMaxModelMagnitude m, an inertia not finite, not symmetric, not positive
/// semi-definite or whose principal moments break the triangle inequality (to 1e-9 of its
/// size). What validate_robot applies to every link's.
void check_inertial(const std::string& field, const Inertial& in, Violations& out);

/// A model that validate_robot accepted: immutable and shared, the proof that it was checked.
/// Made once where a model enters (a catalogue, a request, a URDF document) and copied for the
/// cost of a reference count; what takes one (plan_joint_move, the planner's robot) checks
/// nothing again. Reads as the model wherever a `const RobotModel&` is asked for.
class ValidRobot {
 public:
  /// `model` when validate_robot finds nothing in it, else every violation it finds (field
  /// paths relative to the model).
  static Expected<ValidRobot> check(RobotModel model);

  const RobotModel& model() const { return *model_; }
  const RobotModel& operator*() const { return *model_; }
  const RobotModel* operator->() const { return model_.get(); }
  operator const RobotModel&() const { return *model_; }  // NOLINT(google-explicit-constructor)

 private:
  explicit ValidRobot(std::shared_ptr<const RobotModel> model) : model_(std::move(model)) {}
  friend ValidRobot with_default_jerk(const ValidRobot& robot, double ramp_s);
  friend ValidRobot with_tool_roll(const ValidRobot& robot);
  std::shared_ptr<const RobotModel> model_;
};

/// The problem with one joint rate limit `value` at `field` ("limits[2].maxVelocity"), if any:
/// not finite, or outside [kMinJointLimit, kMaxJointLimit] in `unit` ("rad/s"); the message
/// names the value and the bounds. What validate_robot applies to every limit, and the wire
/// to a request's jointLimits and to the limits its velocityScale and accelerationScale make.
std::optional<FieldViolation> joint_limit_violation(const std::string& field, double value, std::string_view unit);

/// The built-in models, in a fixed order: "pa10" (Mitsubishi PA-10, 7 DOF, the thesis's
/// demonstration arm, modified DH), "ur5" (Universal Robots UR5, 6 DOF, standard DH) and the
/// arms written as URDF (core/robot/models/*.urdf: "panda", "iiwa14", "ur5e"; see
/// builtin_urdf_robots() in urdf.hpp). Each model's `description` cites where its
/// parameters come from.
const std::vector<RobotModel>& builtin_robots();

/// The built-in model called `name`, or nullptr.
const RobotModel* find_builtin_robot(std::string_view name);

/// The model's home configuration as a JointVector (zeros when `home` is empty).
JointVector home_configuration(const RobotModel& model);

/// The model with its joint limits overridden for one motion (the thesis's SpeedScale, Table
/// 6.2, per limit; MoveIt's velocity and acceleration scaling factors): every maxVelocity
/// times `velocity`, every maxAcceleration and maxJerk times `acceleration`, both in (0, 1]
/// (checked by the caller). Position limits are unchanged.
RobotModel with_scaled_limits(RobotModel model, double velocity, double acceleration);

/// [s] Where a motion must not step its acceleration (a jog; a motion timed by the limits)
/// and a joint has no max_jerk, its acceleration is taken to ramp from 0 to max_acceleration
/// in this time: its jerk bound is max_acceleration / kDefaultJerkRampS (20 a_max).
inline constexpr double kDefaultJerkRampS = 0.05;

/// A joint's jerk bound [rad/s^3 or m/s^3]: its max_jerk, or max_acceleration / ramp_s
/// (ramp_s > 0), at most kMaxJointLimit.
double jerk_bound(const JointLimits& limits, double ramp_s = kDefaultJerkRampS);

/// Whether every joint of `model` has a max_jerk.
bool jerk_limited(const RobotModel& model);

/// The model with every joint without max_jerk given jerk_bound(its limits, ramp_s).
RobotModel with_default_jerk(RobotModel model, double ramp_s = kDefaultJerkRampS);
/// The same for a checked model, still valid: every bound it adds is within
/// [kMinJointLimit, kMaxJointLimit] for 0 < ramp_s <= 1 (checked). `robot` itself when every
/// joint has a max_jerk already.
ValidRobot with_default_jerk(const ValidRobot& robot, double ramp_s = kDefaultJerkRampS);

/// The name of the joint with_tool_roll appends.
inline constexpr std::string_view kToolRollJoint = "tool roll";

/// `robot` with the roll of its tool about the tool's z axis as one more joint
/// (RobotSpec.toolAxisFree: a tool symmetric about its axis): a continuous joint about z at
/// the tool frame, appended after the last (origin flange * tool; the new flange and tool the
/// identity), so X_WT'(q, phi) = X_WT(q) RotZ(phi): the pose of the augmented arm is the
/// real arm's tool turned by phi, and a pose it holds is held by the real joints q with the
/// tool's axis and position and its roll off by phi. Limits of the roll: kMaxJointLimit
/// (velocity and acceleration; it costs nothing, the real joints carry it), no jerk; home 0.
/// Valid by construction (one joint more than `robot`, which must have fewer than kMaxJoints:
/// checked); not a DH table.
ValidRobot with_tool_roll(const ValidRobot& robot);

}  // namespace geotraj::core
