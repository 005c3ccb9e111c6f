// Joint-space paths through waypoints (what a sampling planner returns), passed without
// stopping: the polyline of the waypoints in joint space with each corner replaced by a
// curvature-continuous blend, and the fastest motion along it within the joints' velocity
// and acceleration limits (the time-optimal sweep of time_optimal.hpp, on a grid that
// refines where the path bends), sampled at the cycle rate with the joints and the tool.
// Appendix C's PlanMoveVia with joint via points; the same job as MoveIt's time-optimal
// trajectory generation (Kunz and Stilman, "Time-optimal trajectory generation for path
// following with bounded acceleration and velocity", RSS 2012) and TOPP-RA, whose corners
// are circular arcs (their joint accelerations jump where an arc meets a line).
//
// Geometry. The path parameter sigma is the joint-space arc length on the lines (Euclidean
// over the joints: rad and m together, as the tolerance is) [rad]. A line from waypoint w_k
// with unit direction d_k is q = w_k + (sigma - sigma_k) d_k. At an interior waypoint w with
// incoming direction d1 and outgoing d2, the blend is the quintic Bezier curve
//   P0 = w - l d1, P1 = w - (1 - c) l d1, P2 = w - (1 - 2c) l d1,
//   P3 = w + (1 - 2c) l d2, P4 = w + (1 - c) l d2, P5 = w + l d2,      t in [0, 1],
// with t = (sigma - sigma_0) / h, h = 5 c l. It meets each line with its position, its
// tangent dq/dsigma = d (unit: B'(0) = 5 c l d1) and a zero second derivative (P0, P1, P2
// equally spaced on the line): G2, and C2 in sigma, so q_dot and q_ddot are continuous where
// it meets the lines (the jerk is not). By symmetry its middle is B(1/2) = w + g(c) l
// (d2 - d1), g(c) = (16 - 25 c) / 32, the point nearest the waypoint: the waypoint is passed
// at the distance g(c) l |d2 - d1|. The corner lies in the plane of d1 and d2, so its shape
// is a planar problem: c is chosen (golden section) to make the blend's largest curvature
// smallest for the corner's angle, within 3-10 % of the circular arc of the same deviation
// (which is the smallest possible but not G2), and l as large as the tolerance allows,
// never more than half a line shared with another blend, nor more than a line that ends at
// a rest or a straight pass.
//
// Rests: the first and last waypoints, every waypoint with `stop`, every waypoint where the
// path reverses (d1 . d2 < -1 + 1e-9: a corner of 180 degrees has no blend that does not
// stop), and every interior waypoint when the tolerance is 0. A waypoint where the
// direction does not change (|d2 - d1| < 1e-12) is passed on the line. Consecutive
// waypoints within kJointWaypointMerge of each other are one waypoint (it stops if either
// does).
//
// Units: joint values [rad or m], sigma [rad or m, mixed as the joints are], time [s].
#pragma once

#include <array>
#include <cstddef>
#include <stop_token>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/speed_profile.hpp"
#include "core/planning/binding.hpp"
#include "core/planning/moves.hpp"
#include "core/planning/time_optimal.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::core {

/// The most waypoints of one joint path.
inline constexpr std::size_t kMaxJointWaypoints = 10'000;
/// Consecutive waypoints closer than this (Euclidean over the joints) are one [rad or m].
inline constexpr double kJointWaypointMerge = 1e-9;
/// Grid intervals of each blend in the time-optimal sweep (cosine spacing in its t: short
/// intervals where it meets the lines, so the joint accelerations are nearly continuous
/// there).
inline constexpr std::size_t kBlendGridIntervals = 96;
/// The limit scale (velocities by it, accelerations by its square) a blend's grid points
/// start with in the sweep: between them (with the limits imposed at each interval's ends
/// and middle) a joint acceleration passes them by up to a few 1e-4 of its limit, which
/// the sample check would otherwise remove in refinement rounds of the whole grid.
inline constexpr double kBlendLimitMargin = 2.5e-4;
/// Grid intervals of each line at least (uniform in sigma).
inline constexpr std::size_t kMinLineIntervals = 16;

/// A waypoint of a joint path (proto JointWaypoint).
struct JointWaypoint {
  std::vector<double> positions;  ///< [rad or m], one per joint
  bool stop = false;              ///< rest here
};

/// A joint path (proto JointPath; field paths `jointPath.waypoints[i].positions[j]`,
/// `jointPath.blendTolerance`).
struct JointPathSpec {
  std::vector<JointWaypoint> waypoints;
  /// The largest joint-space distance (Euclidean over the joints) [rad or m] at which the
  /// path may pass an interior waypoint; 0: through each, resting there.
  double blend_tolerance = 0.0;
};

/// One piece of the path: a line or a blend, over [sigma0, sigma1].
struct JointPathSegment {
  enum class Kind { kLine, kBlend };
  Kind kind = Kind::kLine;
  double sigma0 = 0.0, sigma1 = 0.0;
  /// kLine: from a to b, q = (1 - f) a + f b with f = (sigma - sigma0) / (sigma1 - sigma0)
  /// (a and b exactly at its ends), q_s = d = (b - a) / |b - a|.
  JointVector a, b, d;
  /// kBlend: the control points P0..P5 and h = sigma1 - sigma0 = 5 c l.
  std::array<JointVector, 6> P;
  /// The requested waypoint the piece passes (blend) or starts from (line).
  std::size_t waypoint = 0;
};

/// What the path does at a requested waypoint.
struct JointWaypointPass {
  enum class Kind {
    kRest,     ///< the path rests there (first, last, stop, reversal, tolerance 0)
    kBlend,    ///< a blend passes it at `deviation`
    kThrough,  ///< the path goes straight through it (no change of direction)
    kMerged,   ///< within kJointWaypointMerge of the waypoint before: one with it
  };
  Kind kind = Kind::kRest;
  double sigma = 0.0;      ///< where the path passes nearest [rad or m of sigma]
  double deviation = 0.0;  ///< its distance from the path there (0 unless kBlend) [rad or m]
  /// kBlend: the blend's half-length l along each line and its shape c.
  double blend_length = 0.0, blend_shape = 0.0;
};

/// A joint path: a value.
struct JointPath {
  std::size_t dof = 0;
  std::vector<JointPathSegment> segments;  ///< in order, back to back in sigma
  std::vector<double> rests;               ///< sigma of every rest, from 0 to length, increasing
  std::vector<JointWaypointPass> waypoints;  ///< one per requested waypoint
  double length = 0.0;                     ///< total sigma [rad or m]
  JointVector first, last;                 ///< the first and last waypoints, met exactly
};

/// The path at one sigma: q and its derivatives in sigma.
struct JointPathPoint {
  JointVector q;      ///< [rad or m]
  JointVector q_s;    ///< dq/dsigma (unit on lines)
  JointVector q_ss;   ///< d2q/dsigma2 [1/(rad or m)]
  JointVector q_sss;  ///< d3q/dsigma3
  std::size_t segment = 0;
};

/// The path through spec's waypoints for `robot` (see the file comment).
/// Errors (all collected; fields relative to the joint path): `waypoints` with fewer than 2
/// or more than kMaxJointWaypoints; `waypoints[i].positions` of the wrong size;
/// `waypoints[i].positions[j]` not finite, or outside joint j's position limits (a continuous
/// joint: beyond 1e6); `blendTolerance` not finite or negative.
Expected<JointPath> build_joint_path(const RobotModel& robot, const JointPathSpec& spec);

/// The path at `sigma` (clamped to [0, length]); `hint` (a segment index, updated) makes a
/// non-decreasing sequence O(1) each. No heap allocation.
void evaluate(const JointPath& path, double sigma, JointPathPoint& out, std::size_t& hint);

/// Largest curvature [1/(rad or m)] of the quintic blend of shape c across a corner of angle
/// theta in (0, pi) [rad], for l = 1 (it scales as 1 / l): the planar curve of the file
/// comment, measured at 65 points of its half (it is symmetric).
double blend_peak_curvature(double c, double theta);

/// Options of plan_joint_path.
struct JointPathOptions {
  /// Grid intervals of the lines of a portion together, shared by length (each line at
  /// least kMinLineIntervals); each blend has `blend_intervals` more.
  std::size_t line_intervals = 400;
  std::size_t blend_intervals = kBlendGridIntervals;
  /// Crowd each blend's grid points towards its ends (cosine spacing; else uniform): the
  /// sweep's acceleration is constant on each interval, so short intervals where a blend
  /// meets a line keep the joint accelerations nearly continuous there. The jerk-limited
  /// timing, which ramps every step, takes a uniform grid (its windows are as wide as the
  /// intervals: tiny ones make its programme stiff).
  bool crowd_blend_ends = true;
  /// The sample check and its refinements, as TimeOptimalOptions (time_optimal.hpp);
  /// verify_samples false: the sweep's timing alone (its limits hold at the grid points, both
  /// sides), what a comparison with another timing of the same grid measures.
  bool verify_samples = true;
  int max_refinements = 8;
  int uniform_refinement_from = 4;
  double sample_tolerance = 1e-9;
  double check_rate_hz = 2'000.0;
  std::size_t max_check_samples = 200'000;
  std::stop_token stop;
};

/// A timed joint path: sigma(t) on one profile over the whole path (the portions between
/// rests back to back, at rest at each junction), the joints q(sigma(t)).
struct JointPathPlan {
  ValidRobot model;
  MotionSpec spec;  ///< as given
  JointPath path;
  SpeedProfile profile;  ///< sigma(t) over [0, duration_s]; at rest at every path.rests
  double duration_s = 0.0;
  std::size_t sample_count = 0;
  /// Which limit sets the pace, stretch by stretch (s_start, s_end: sigma) [time-optimal only].
  std::vector<BindingStretch> binding;
  /// Largest |q_dot_j| / maxVelocity_j and |q_ddot_j| / maxAcceleration_j over every sample
  /// checked (the cycle rate and the check rate): within speedScale and speedScale^2 when
  /// the limits time the motion; with a duration they may exceed 1 (it is honoured as given).
  double velocity_usage = 0.0;
  double acceleration_usage = 0.0;
  int refinements = 0;             ///< re-solves after the sample check
  double check_rate_hz = 0.0;      ///< the finest rate checked [Hz]
  std::size_t grid_points = 0;     ///< of the sweep, over every portion
  /// |T(N) - T(N / 2)| [s]: the duration against the one on every second grid point.
  double duration_grid_error = 0.0;
  /// What the sweep solved (what a jerk-limited timing starts from): per portion between
  /// rests, its grid (s from the portion's start), its exact solution and the refinements'
  /// per-point limit scales; the limits (speedScale applied).
  std::vector<std::vector<GridPoint>> grids;
  std::vector<TimeOptimalSolution> solutions;
  std::vector<std::vector<double>> limit_scale;
  TimeOptimalLimits limits;
};

/// The samples of `plan` against `limits`, as check_time_optimal_samples does for a path:
/// at the cycle rate, then (if every sample there is within the limits) at the check rate
/// (options.check_rate_hz, a multiple of the cycle rate, within options.max_check_samples):
/// |q_dot_j|, |q_ddot_j| and, where limits.joint_jerk has finite values, the joint jerk as
/// the difference of successive accelerations over the period. The factors to tighten the
/// grid points around each excess (SampleCheck::shrink, jerk_shrink) refer to plan.grids.
struct JointPathCheck {
  SampleCheck check;
  double velocity_usage = 0.0;      ///< largest |q_dot_j| / limit
  double acceleration_usage = 0.0;  ///< largest |q_ddot_j| / limit
  double jerk_usage = 0.0;          ///< largest mean jerk over a period / limit (0 without)
  double torque_usage = 0.0;        ///< largest |tau_j| / maxTorque (0 without torque limits)
};
/// Errors (field `motion`): options.stop requested.
Expected<JointPathCheck> check_joint_path_samples(const JointPathPlan& plan, const TimeOptimalLimits& limits,
                                                  const JointPathOptions& options);

/// sigma(t) of a whole path from its portions' profiles (each rest to rest, over
/// [rests[p], rests[p + 1]]): back to back in time.
SpeedProfile joined_profile(const std::vector<SpeedProfile>& profiles, const std::vector<double>& rests);

/// Times `path` (built by build_joint_path for robot):
///  - motion.duration_s = 0: the fastest motion within the joints' maxVelocity and
///    maxAcceleration (times speedScale, speedScale^2 accelerationScale), portion by portion
///    (rest to rest) by the time-optimal sweep on a grid of each blend's
///    kBlendGridIntervals intervals and the lines' options.line_intervals; every sample at
///    the cycle rate and at the check rate is then checked and the grid's limits tightened
///    where one breaks a limit (as plan_time_optimal does). The acceleration jumps where
///    the sweep switches between accelerating and braking (bang-bang), nowhere else.
///  - motion.duration_s = D > 0: the same motion uniformly stretched (or compressed) in time
///    to T = D / speedScale; the usages say how close it comes to the limits.
///  - A path of zero length: one sample at rest (duration 0), or a rest for T with a duration.
/// The MotionSpec's Cartesian limits are not used (refused by the caller).
/// Errors: validate_motion's (field `motion`); `motion.durationS` when the motion would
/// have more than kMaxMotionSamples samples; `motion` when a point admits no speed, the
/// sample check does not settle, or options.stop is requested.
Expected<JointPathPlan> plan_joint_path(const ValidRobot& robot, JointPath path, const MotionSpec& motion,
                                        const JointPathOptions& options = {});

/// The joint path at time t [s]: q, q_dot = q_s sigma_dot, q_ddot = q_s sigma_ddot +
/// q_ss sigma_dot^2 and the tool's state by forward kinematics as joint_move_at gives it
/// (u = sigma / length, s = 0). Exactly the last waypoint at rest from t = duration on.
/// `hint` and `cursor` make non-decreasing times O(1). No heap allocation.
void joint_path_at(const JointPathPlan& plan, double t, ProfileCursor& cursor, std::size_t& hint, MoveSample& out);

/// The joint jerk at time t [s]: q_sss sigma_dot^3 + 3 q_ss sigma_dot sigma_ddot +
/// q_s sigma_dddot (in the profile's piece at t) [rad/s^3 or m/s^3].
JointVector joint_path_jerk(const JointPathPlan& plan, double t);

/// Samples a joint path at the cycle rate (a workspace; `plan` must outlive it).
class JointPathSampler {
 public:
  explicit JointPathSampler(const JointPathPlan& plan);
  bool next(MoveSample& sample);
  void at(double t, MoveSample& sample);
  void reset();
  std::size_t index() const { return k_; }

 private:
  const JointPathPlan* plan_;
  ProfileCursor cursor_;
  std::size_t hint_ = 0;
  Eigen::Quaterniond q_prev_ = Eigen::Quaterniond::Identity();
  std::size_t k_ = 0;
};

}  // namespace geotraj::core
