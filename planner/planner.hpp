// The application layer between the wire and the math: one request value in (everything a
// PlanRequest says, already converted), one plan out. It decides what runs and in which
// order (the optimisers of the path, the path, the orientation, the timing, the robot's
// joint-space pass) under one budget (a deadline and a stop token), and returns the plan
// with its reports or an error that carries its kind as a value. No gRPC, no protobuf: the
// server converts the request once, plans, converts the result once and maps the error kind
// to a status once (server/wire/status.cpp).
//
// Field paths in every violation are absolute from the request's root, in proto JSON names
// (`path.frames[1].curvature`, `motion.maxAcceleration`, `optimize.tangentScales.minScale`).
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <stop_token>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "core/error.hpp"
#include "core/geometry/analysis.hpp"
#include "core/geometry/geometry_report.hpp"
#include "core/geometry/key_frame.hpp"
#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/planning/joint_path.hpp"
#include "core/planning/corner_blend.hpp"
#include "core/planning/moves.hpp"
#include "core/planning/time_optimal.hpp"
#include "core/planning/trajectory.hpp"
#include "core/robot/robot.hpp"
#include "optim/breakpoints/breakpoints.hpp"
#include "optim/common/report.hpp"
#include "optim/redundancy/redundancy.hpp"
#include "optim/tangent_scales/tangent_scales.hpp"

namespace geotraj::planner {

/// How far a given joint start (a jointMove's start in a sequence, a jointPath's first
/// waypoint) may be from where the robot is (the previous step's end, robot.initialJoints)
/// [rad or m], joint by joint.
inline constexpr double kSequenceJointTolerance = 1e-6;

/// What a plan does when its path starts away from the tool pose of the robot's initial
/// joints (RobotSpec.approach).
enum class Approach {
  kNone,    ///< refuse: kUnattainable on robot.initialJoints with the distance
  kJoint,   ///< a joint move first, to the IK solution of the path's first pose nearest the joints
  kLinear,  ///< a straight-line move first, to the path's first pose
};

/// How far a path's first tool pose may be from the pose of the initial joints by default
/// (RobotSpec.startPositionTolerance [m], startOrientationTolerance [rad]).
inline constexpr double kStartPositionTolerance = 1e-4;
inline constexpr double kStartOrientationTolerance = 1e-3;

/// The robot of a request, resolved (a catalog name looked up, base, tool and limits applied)
/// and checked once, there: `model` is the proof.
struct Robot {
  Robot(core::ValidRobot checked, core::JointVector initial) : model(std::move(checked)), seed(std::move(initial)) {}

  core::ValidRobot model;
  core::JointVector seed;          ///< the initial joints, or the model's home [rad, m]
  bool report_only = false;        ///< report broken limits instead of refusing the plan
  /// RobotSpec.toolAxisFree: the roll about the tool's z axis is chosen with the joints for
  /// the whole motion (optimize_joints on core::with_tool_roll's arm); the streamed tool keeps
  /// the planned position and z axis.
  bool tool_axis_free = false;
  double branch_tolerance = 1e-3;  ///< [m]
  /// How far a path's first tool pose may be from the pose of `seed` [m], [rad].
  double start_position_tolerance = kStartPositionTolerance;
  double start_orientation_tolerance = kStartOrientationTolerance;
  bool inline_model = false;       ///< given as `robot.model` (not by name): where its errors point
  Approach approach = Approach::kNone;
};

/// The optimisers a request asks for (OptimizeSpec), converted.
struct Optimize {
  std::optional<optim::TangentScaleOptions> tangent_scales;
  std::optional<optim::BreakpointOptions> breakpoints;
  bool time_optimal = false;  ///< optimize.timing.timeOptimal
  bool jerk_limited = false;  ///< optimize.timing.jerkLimited
  /// optimize.redundancy: a redundant arm's joints along a path chosen for the whole motion
  /// (optim/redundancy), which every sample then follows.
  std::optional<optim::RedundancyWeights> redundancy;
  double budget_s = 10.0;     ///< all optimisers of the request together [s]
};

/// How a joint move to a pose picks its goal among the IK branches.
enum class GoalChoice {
  kNearest,        ///< the solution nearest the start (a jointMove's goalPose)
  kLargestMargin,  ///< the largest margin to the joint limits, nearest the start among equals
                   ///< (robot.approach: the path then starts where the joints have room)
};

/// A joint-interpolated move to a tool pose (Appendix C): the goal's joints are an IK
/// solution chosen by `choice`, every branch searched (core::search_ik).
struct JointMoveToPose {
  std::vector<double> start;  ///< [rad or m], one per joint
  Eigen::Isometry3d goal = Eigen::Isometry3d::Identity();  ///< X_WT at the goal
  GoalChoice choice = GoalChoice::kNearest;
};

/// A straight-line move to joint values (Appendix C, Cartesian-interpolated): the goal pose
/// is their forward kinematics, and the robot tracking the line must end at them.
struct LinearMoveToJoints {
  core::ToolPose start;       ///< X_WT at the start
  std::vector<double> goal;   ///< [rad or m], one per joint
};

/// What a request plans: the key frames of a path, a joint move or a straight-line move,
/// each move to joints or to a pose.
using Geometry = std::variant<core::PathSpec, core::JointMoveSpec, core::LinearMoveSpec, JointMoveToPose,
                              LinearMoveToJoints, core::JointPathSpec>;

/// One step of a sequence (PlanRequest.sequence[i]), converted. Its errors are named
/// `sequence[i].<field>`.
struct Step {
  Geometry geometry;
  core::MotionSpec motion;
  bool own_motion = false;   ///< sequence[i].motion was given (else the request's motion)
  /// The fields sequence[i].motion gives (API names: "maxSpeed", ...); the others come from
  /// the request's motion, and a violation of one of them is named there.
  std::vector<std::string> own_motion_fields;
  /// A move's start was given (jointMove.start, linearMove.start): it must be where the
  /// previous step ends. Not given: it is that end (the wire's placeholder is replaced).
  bool start_given = false;
  /// [m] > 0: the corner to the next step replaced by a blend within this distance of it
  /// (core::blend_chain); 0: the robot rests there.
  double blend_tolerance = 0.0;
  /// A step the planner added (robot.approach): how its errors are named, "" for the
  /// request's own fields as they are. Absent: `sequence[i].<field>`.
  std::optional<std::string> name;
};

/// Everything a plan request says, converted once by the wire layer.
struct Request {
  Geometry geometry;                       ///< unused when `sequence` is given
  std::optional<core::MotionSpec> motion;  ///< absent: the path's geometry only
  std::shared_ptr<const Robot> robot;      ///< shared: a plan's samplers refer to its model
  std::optional<Optimize> optimize;
  /// Steps planned in order instead of `geometry` (PlanRequest.sequence); `optimize` applies
  /// to each path among them.
  std::vector<Step> sequence;
  /// The tool orientation a path starts in where its first frame defines none (see
  /// core::plan_orientation). Absent: the robot's at its initial joints, or the world axes.
  std::optional<Eigen::Quaterniond> start_orientation;
  /// The fraction of every acceleration kept free by the motions timed by the limits
  /// (reserve_room), and whether `motion` has been scaled for it.
  double reserve = 0.0;
  bool motion_reserved = false;
  bool reserve_applied = false;  ///< some motion (the approach included) was scaled for it
};

/// Leaves `reserve` (in [0, 0.99]) of every acceleration free, for live speed changes, in the
/// motions the limits time (time_optimally_timed: time-optimal paths, minimum-time moves,
/// and robot.approach): their acceleration and jerk limits (joint and Cartesian) times
/// 1 - reserve (core::MotionSpec::acceleration_scale); their velocity limits unchanged, so a
/// motion whose pace a speed limit sets (a process speed: welding, dispensing) cruises at
/// it, and only its speed-ups and slow-downs take longer. A motion with a durationS keeps
/// the room it has. A step of a sequence that takes
/// the request's motion (own_motion false) holds a copy of it, scaled with the others.
/// Execute plans the request so prepared; everything else is planned as for PlanTrajectory
/// and StreamSamples.
void reserve_room(Request& request, double reserve);

/// The server's bounds on one call's work.
struct Limits {
  std::size_t max_samples = 1'000'000;  ///< samples of one motion: streamed, followed by a robot or summarised
  std::string max_samples_name;         ///< how a refusal names that limit ("geotrajd --max-stream-samples")
};

/// One budget for all long work of a call: the caller's deadline and a stop token (the RPC's
/// cancellation). Every stage checks it, and every optimiser and sampling pass watches both.
struct Budget {
  std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max();
  std::stop_token stop;
  /// Observes each optimiser's run (name, wall-clock seconds), e.g. for metrics.
  std::function<void(std::string_view, double)> on_optimizer;

  bool stop_requested() const { return stop.stop_requested(); }
  bool expired() const { return std::chrono::steady_clock::now() >= deadline; }
};

/// Whether a path's motion is timed by the time-optimal planner (thesis 6.4): when the request
/// asks (optimize.timing.timeOptimal or jerkLimited), or when it gives no duration
/// (durationS 0) with a robot or a TRAPEZOIDAL profile, whose minimum time the limits set.
/// The wire's checks and the planner both follow this one rule.
bool time_optimally_timed(const core::MotionSpec& motion, bool robot, bool time_optimal, bool jerk_limited);

/// What kind of failure an Error is: the server maps each to one status code.
enum class ErrorKind {
  kInvalidArgument,     ///< `violations`: fields of the request and what is wrong with them
  kUnattainable,        ///< `violations`, every one core::ViolationKind::kUnattainable: the request is
                        ///< well-formed, and the path cannot be followed at any speed there, or the
                        ///< minimum-time motion is too long to sample
  kRobotCannotFollow,   ///< `limits`: the robot's broken limits (not reportOnly)
  kStopped,             ///< the budget's stop token was requested (the call was cancelled)
  kDeadlineExceeded,    ///< the budget's deadline passed before the work was done
};

struct Error {
  ErrorKind kind = ErrorKind::kInvalidArgument;
  core::Violations violations;
  std::vector<core::LimitEvent> limits;  ///< kRobotCannotFollow
  std::string robot;                     ///< kRobotCannotFollow: the model's name
  /// kRobotCannotFollow although robot.reportOnly: an IK failure or a branch jump, which a
  /// stream never carries (its joints would mean nothing).
  bool report_only = false;
};

template <class T>
using Expected = tl::expected<T, Error>;

/// The tool's peaks over a motion's samples: speed, whole acceleration and angular speed.
struct ToolPeaks {
  double speed = 0.0;          ///< [m/s]
  double acceleration = 0.0;   ///< |a_WT| [m/s^2]
  double angular_speed = 0.0;  ///< |omega_WT| [rad/s]
};

/// A timed motion summed up (PlanResponse.motion): its duration and samples, the tool's peaks
/// over the samples, and the timing's own peak along the path.
struct MotionSummary {
  double duration_s = 0.0;  ///< [s]
  std::size_t sample_count = 0;
  ToolPeaks tool;
  /// The largest |s''| of the timing of a path or a line (a sequence: of its steps) [m/s^2];
  /// 0 for a joint move, whose tool follows no path.
  double peak_tangential_acceleration = 0.0;
  /// Without a robot: which of the tool's Cartesian limits (maxSpeed, the tangential and
  /// centripetal parts of maxAcceleration, the angular limits) is the most used, stretch by
  /// stretch, measured on the samples (core::ToolBindingBuilder). With a robot,
  /// JointMotionReport::binding has them beside the joints'.
  std::vector<core::BindingStretch> binding;
};

/// What the timing optimiser did, with which limit binds where along the path, and how far
/// its result can be trusted between the samples and from its grid.
struct TimingReport {
  optim::OptimizerReport report;
  /// The time-optimal sweep's (the limit active on each grid interval); for a jerk-limited
  /// timing, the stretches measured on its samples (the sweep is only its warm start, a
  /// faster motion): the joint-space report's with a robot, the tool's without.
  std::vector<core::BindingStretch> binding;
  bool jerk_limited = false;  ///< the timing is the jerk-limited one
  /// The finest rate at which every limit was checked on the result (the cycle rate, then
  /// core::TimeOptimalOptions::check_rate_hz) [Hz].
  double check_rate_hz = 0.0;
  /// The largest value / limit over every sample checked (velocity, acceleration, jerk).
  double worst_limit_usage = 0.0;
  /// Re-solves after a sample broke a limit.
  int refinements = 0;
  /// |T(N) - T(N / 2)| [s]: the duration's error from the grid, estimated.
  double duration_grid_error_s = 0.0;
};

/// The jerk bounds that a motion timed by the limits (no durationS, or optimize.timing) kept
/// on the joints whose model gives no max_jerk, so that it starts and ends with zero
/// acceleration and a bounded jerk: each joint's max_acceleration / ramp_s
/// (core::jerk_bound, the jog's rule).
struct DefaultJerk {
  double ramp_s = core::kDefaultJerkRampS;  ///< [s]
  std::vector<std::size_t> joints;          ///< the joints without max_jerk, base outwards
  std::vector<double> max_jerk;             ///< their bounds [rad/s^3 or m/s^3]
  std::string message;                      ///< the same in words, with how to choose otherwise
};

/// The reports of the optimisers that ran.
struct OptimizerReports {
  std::optional<optim::TangentScaleResult> tangent_scales;
  std::optional<optim::BreakpointResult> breakpoints;
  std::optional<TimingReport> timing;
  /// optimize.redundancy's: the criteria objective before and after (redundancy.hpp).
  std::optional<optim::OptimizerReport> redundancy;
};

/// The path's geometry as planned: the achieved frames, the closed loop and the geometry
/// between the frames with its warnings.
struct PathReport {
  std::vector<core::AchievedFrame> achieved;
  core::ClosedLoopError closed_loop;
  core::GeometryReport geometry;
};

/// One step of a planned sequence, where it lies in time and in the samples.
struct StepReport {
  std::size_t index = 0;       ///< the step's index in the request's sequence
  std::size_t last_index = 0;  ///< > index: the steps index..last_index blended into one path
  std::string kind;           ///< "path", "jointMove", "linearMove", or "blended" (a chain)
  double start_time_s = 0.0;  ///< [s]
  double duration_s = 0.0;    ///< [s]
  std::size_t first_sample = 0;
  std::size_t sample_count = 0;  ///< streamed (its last rest is the next step's first sample)
  double arc_length = 0.0;    ///< [m] (paths and linear moves)
  std::optional<PathReport> path;  ///< a path or a blended chain, kPlan
  /// A blended chain: its corners (collinear junctions, which turn nothing and are blended
  /// by the line itself, are not corners).
  std::vector<core::CornerBlend> corners;
  /// A joint move to a pose: which IK branch its goal is, and why ("the largest margin to
  /// the joint limits, 0.43 rad (joint 3, panda_joint4), of 9 branches found; ...").
  std::string goal_choice;
  OptimizerReports optimizers;     ///< a path's optimisers
  ToolPeaks tool;                  ///< kPlan: the tool's peaks over the step's own samples
  double peak_tangential_acceleration = 0.0;  ///< [m/s^2], as MotionSummary's
};

/// Which call a request serves: what it needs of the request (planner::admit) and what its
/// plan is for.
enum class Use {
  kPlan,     ///< PlanTrajectory: the geometry and, with `motion`, its timing (`motion` is required
             ///< with a robot or a move); reports, the robot's joint report (reportOnly keeps every
             ///< limit broken), the tool's peaks over the samples
  kStream,   ///< StreamSamples and Execute: `motion` is required, and the robot must follow
             ///< (reportOnly streams broken joint limits only, never a failed IK or a branch jump)
  kAnalyze,  ///< AnalyzePath: the path and its optimisers only (a robot or motion is not read);
             ///< planned by analyze(), not plan()
};

/// A plan: the trajectory (with a motion) or the path alone, and what was measured on it.
struct Plan {
  std::optional<core::Trajectory> trajectory;  ///< with a motion
  std::optional<core::Path> path;              ///< without a motion: the path's geometry only
  std::shared_ptr<const Robot> robot;
  std::optional<PathReport> path_report;       ///< kPlan, when the plan follows a path
  OptimizerReports optimizers;
  std::optional<core::JointMotionReport> joints;  ///< with a robot
  std::optional<MotionSummary> summary;           ///< kPlan with a motion
  std::vector<StepReport> steps;                  ///< a sequence: one per step
  /// With a robot whose model lacks jerk limits, when a motion (a step) is timed by the limits.
  std::optional<DefaultJerk> default_jerk;
  /// Execute (reserve_room): the reserve kept where it changed a motion timed by the limits
  /// (0: it changed none), and what that means, in words.
  double reserve = 0.0;
  std::string reserve_note;

  /// The path the plan follows, if any.
  const core::Path* followed_path() const;
};

/// Plans `request` for `use` (kPlan or kStream) within `budget` and `limits`.
Expected<Plan> plan(const Request& request, const Budget& budget, const Limits& limits, Use use = Use::kPlan);

/// The optimised path of `request` (its tangent scales and breakpoints, within the budget),
/// sampled at `points` points uniform in u. Precondition: the geometry is a path.
struct Analysis {
  core::Path path;
  std::vector<core::ProfilePoint> points;
};
Expected<Analysis> analyze(const Request& request, std::size_t points, const Budget& budget);

/// Chapter 5 alone (ConvertConstraints): every key frame's parametric constraints, per side,
/// under the path's reading of unspecified constraints.
Expected<std::vector<core::FrameConstraints>> convert(const core::PathSpec& path);

/// The error of a stopped or expired budget, if either.
std::optional<Error> check(const Budget& budget);

}  // namespace geotraj::planner
