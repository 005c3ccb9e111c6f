// The joint-space motion of an arm that follows a Cartesian motion (thesis 6.4), one sample
// at a time: joint positions by warm-started IK (ik.hpp), joint velocities and
// accelerations from the Cartesian ones through the Jacobian and the second-order term
// (Eqs. 1.8-1.11, never finite differences), and the certificates a user needs before
// streaming to a controller: IK residuals, the deviation of joint interpolation between
// samples, manipulability, joint-limit margins. Frames and units: everything Cartesian in
// the world frame W (the robot's base pose is part of the model); [m], [rad], [s].
//
// Redundancy (n > 6, the PA-10), docs/kinematics.md: the self-motion is the null-space
// projection of a joint-limit avoidance velocity,
//   z(q, v) = -k |v_WT| grad H(q),  H(q) = sum_i ((q_i - mid_i) / range_i)^2,
//   grad H_i = 2 (q_i - mid_i) / range_i^2,       (mid, range of joint i's position limits)
// k = IkOptions::limit_avoidance_gain [rad^2/m]. Deviation from a time-based z(q): the
// gain follows the tool speed |v_WT| [m/s], so the self-motion is per metre of travel, the
// joints rest when the tool rests (start, end, cusps, stops) and the joint path does not
// depend on the timing. With J^+ = J^T (J J^T)^-1 and N = I - J^+ J (both at q), the same
// choice is applied to positions, velocities and accelerations:
//   velocity      q_dot  = J^+ [v; omega] + N z                                      (1.8)
//   acceleration  q_ddot = J^+ ([a; alpha] - J_dot q_dot) + N (J_dot^T w + z_dot),     (1.10)
//                 w = (J J^T)^-1 ([v; omega] - J z),
//                 z_dot_i = -k (d|v|/dt grad H_i + |v| 2 q_dot_i / range_i^2),
//                 d|v|/dt = v . a / |v| (|a| at a rest: the motion leaves it forwards);
//   position      q_k = Newton projection (ik.hpp, minimum-norm corrections) of the
//                 second-order predictor q_{k-1} + q_dot_{k-1} dt + q_ddot_{k-1} dt^2 / 2.
// The term N J_dot^T w is d/dt of the projector (N dJ^+/dt = N J_dot^T (J J^T)^-1): without
// it q_ddot would not be the time derivative of q_dot (deviation from the plain N z_dot).
// Hence, where the solves are undamped (away from singularities), J q_dot = [v; omega] and
// J q_ddot + J_dot q_dot = [a; alpha] to rounding, q_dot is the derivative of the q samples
// and q_ddot that of q_dot: the q samples integrate
// q_dot = J^+ [v; omega] + N z with local error O(dt^3) (the predictor) and Newton
// corrections in the row space of J, so central differences of q match q_dot to O(dt^2)
// where the Cartesian motion is smooth. A non-redundant arm (n = 6) has N = 0: q_dot =
// J^-1 [v; omega].
#pragma once

#include <cstddef>
#include <limits>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/binding.hpp"
#include "core/planning/joint_reference.hpp"
#include "core/robot/ik.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::core {

/// The tool's Cartesian state at one sample, in W: pose X_WT, velocity and acceleration of
/// its origin [m/s, m/s^2], angular velocity and acceleration [rad/s, rad/s^2].
struct CartesianState {
  double t = 0.0;  ///< [s]
  /// Along a path: the arc length from its start s [m], s_dot [m/s] and s_ddot [m/s^2] (what
  /// a joint reference in arc length needs: JointReference, ReferenceParameter::kArcLength);
  /// 0 elsewhere.
  double s = 0.0;
  double s_dot = 0.0;
  double s_ddot = 0.0;
  Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
  Eigen::Vector3d v_WT = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_WT = Eigen::Vector3d::Zero();
  Eigen::Vector3d a_WT = Eigen::Vector3d::Zero();
  Eigen::Vector3d alpha_WT = Eigen::Vector3d::Zero();
};

/// The tool's Cartesian state at a motion sample (motion.hpp) with the orientation plan of
/// the same path (orientation.hpp): p, v, a from the sample; R_WT, omega, alpha from
/// orientation_at with s_dot = sample.speed [m/s] and s_ddot = sample.s_ddot [m/s^2].
/// No heap allocation.
CartesianState cartesian_state(const Path& path, const OrientationPlan& orientation, const MotionSample& sample);

/// The tool's state turned about its own z axis by phi(t) [rad], phi_dot [rad/s], phi_ddot
/// [rad/s^2] (RobotSpec.toolAxisFree: the roll that a tool symmetric about its axis leaves
/// free; turn_about_tool_axis, orientation.hpp), in W: the position, velocity and
/// acceleration unchanged. No heap allocation.
void roll_about_tool_axis(CartesianState& x, double phi, double phi_dot, double phi_ddot);

/// The tool's roll chosen ahead for a whole straight line (JointReference of one coordinate
/// [rad] in time, LinearMovePlan::roll) applied to x at x.t; nothing when `roll` is null. (A
/// path's roll is a function of its arc length, in its OrientationPlan.) Scratch vectors of
/// one entry: no heap allocation.
void apply_roll(const JointReference* roll, CartesianState& x);

/// One joint-space sample.
struct JointSample {
  JointVector q;      ///< [rad or m]
  JointVector q_dot;  ///< [rad/s or m/s]
  JointVector q_ddot; ///< [rad/s^2 or m/s^2]
  bool converged = false;
  int iterations = 0;              ///< Newton steps (all attempts)
  double position_error = 0.0;     ///< IK residual |p_target - p_WT(q)| [m]
  double orientation_error = 0.0;  ///< IK residual, angle of R_target R_WT(q)^T [rad]
  double manipulability = 0.0;     ///< sqrt(det(J J^T)) at q (Yoshikawa; [m^3 rad^3] mixed)
  /// |p_WT((q_prev + q) / 2) - (p_prev + p) / 2| [m]: how far linear joint interpolation
  /// between the previous sample and this one strays from the Cartesian chord (0 for the
  /// first sample). On one smooth branch it is O(dt^2) (the chord's sagitta and the
  /// curvature of the joint map); a branch change or a singularity makes it large.
  double midpoint_deviation = 0.0;
  /// The joint torques [N m or N] that drive (q, q_dot, q_ddot) with the model's payload under
  /// standard gravity (inverse_dynamics, dynamics.hpp): written by the samplers of a model
  /// with mass properties (has_dynamics), empty otherwise.
  JointVector tau;
};

/// The tool's Cartesian states between two samples, for JointTracker::follow: a motion that
/// can be evaluated at any time after the tracker's last good sample.
class CartesianSource {
 public:
  /// Writes the tool's state at time t [s] (t increases from call to call within one
  /// follow(), between the tracker's last good sample and the state followed); false where
  /// the motion has none (then the follow fails there).
  virtual bool state_at(double t, CartesianState& x) = 0;

 protected:
  CartesianSource() = default;
  CartesianSource(const CartesianSource&) = default;
  CartesianSource& operator=(const CartesianSource&) = default;
  ~CartesianSource() = default;
};

/// A CartesianSource from a callable bool(double t, CartesianState& x).
template <class F>
class CallableSource final : public CartesianSource {
 public:
  explicit CallableSource(F f) : f_(std::move(f)) {}
  bool state_at(double t, CartesianState& x) override { return f_(t, x); }

 private:
  F f_;
};
template <class F>
CallableSource<F> cartesian_source(F f) {
  return CallableSource<F>(std::move(f));
}

/// The states of a path motion between its samples (motion.hpp): a copy of the motion's
/// sampler as it was after the tracker's last good sample, evaluated off the grid from there
/// (a fresh copy per state: MotionSampler::at steps forwards only, and a walk tries shorter
/// strides after longer ones). mark() after each good sample keeps it there. Copies are
/// small (no heap); `path` and `orientation` must outlive it.
class PathMotionSource final : public CartesianSource {
 public:
  PathMotionSource(const Path& path, const OrientationPlan& orientation, const MotionSampler& sampler)
      : path_(&path), orientation_(&orientation), sampler_(sampler), scratch_(sampler) {}
  /// The sampler has just written the last good sample.
  void mark(const MotionSampler& sampler) { sampler_ = sampler; }
  bool state_at(double t, CartesianState& x) override;

 private:
  const Path* path_;
  const OrientationPlan* orientation_;
  MotionSampler sampler_, scratch_;
  MotionSample sample_;
};

/// When JointTracker::follow accepts a step (the continuation of the samples and of the
/// timing grids, time_optimal.hpp). A step converges, and stays on the branch it started
/// on: its midpoint certificate (JointSample::midpoint_deviation) within branch_tolerance,
/// and the Newton correction of the tracker's predictor (the largest |q_j - q_pred,j|)
/// within max_correction. On one branch that correction is third order in the step (at most
/// 7e-3 rad on the thesis's demo paths at 200 grid intervals, 1e-4 at 1,000; far less between
/// samples at a cycle rate); a predictor that left the branch's basin (a singularity passed in
/// one stride, a self-motion or a wrist flipped) is corrected by a sizeable fraction of a
/// radian (0.08 to 0.9 rad on random paths). Otherwise the interval is walked in steps halved
/// down to min_fraction of it, and doubled again after each accepted one, as a sampler slow
/// enough to follow the path would have tracked it; at the smallest step a converged step is
/// kept.
struct ContinuationRule {
  double branch_tolerance = 1e-3;        ///< [m], JointReportBuilder's default
  double max_correction = 1e-2;          ///< [rad or m]
  double min_fraction = 1.0 / 4096.0;    ///< the smallest step, a fraction of the interval
};

/// The timing grids' rule (time_optimal.hpp): the defaults above. A grid's strides are 10 to
/// 100 times a sample's, and the correction bound keeps them on the samples' branch.
inline constexpr ContinuationRule kGridContinuation{};
/// The samples' rule (TrajectorySampler, the timing's sample checks): a sample that converges
/// within the midpoint certificate is kept, whatever the correction. Between samples at a
/// cycle rate the correction is far below the grid's bound on a branch, except close to a
/// singularity, where a redundant arm's joints depend on the strides taken (each Newton
/// projection moves them in the row space of J): subdividing there changed which samples
/// converged further on (a Panda path that streams in one stride per sample failed after
/// such a walk), and the midpoint certificate already tells a branch change.
inline constexpr ContinuationRule kSampleContinuation{1e-3, std::numeric_limits<double>::infinity(), 1.0 / 4096.0};

/// What JointTracker::follow did.
struct FollowResult {
  bool converged = false;
  int substeps = 0;       ///< intermediate states tracked on the way (0: in one step)
  /// The walk did not converge at its smallest stride and the sample was reached in one
  /// stride from the last state accepted (or, that failing, from the last good sample), as
  /// track() would have: the sample's midpoint certificate says whether it kept the branch.
  bool jumped = false;
  double t_failed = 0.0;  ///< where the walk stopped when it did not converge [s]
};

/// Follows a Cartesian motion sample by sample (a reusable workspace: no heap allocation per
/// sample). The first call solves from `q_seed` (the branch seed, e.g. the request's
/// initialJoints or the model's home) with IkOptions::restarts allowed; later calls
/// warm-start from the previous sample (second-order predictor, above) and stay on its
/// branch: no restarts and no 2 pi wrapping, only the Newton projection (and, if the
/// predicted start fails, one more attempt from the previous configuration).
/// Redundant arms: the null-space choice above, the same in positions and in
/// velocities/accelerations, so q_dot matches finite differences of q.
/// Joint velocities: J q_dot = [v; omega]; accelerations: J q_ddot = [a; alpha] - J_dot q_dot
/// (1.8-1.11), minimum-norm plus the null-space term. Near a singularity (smallest Cholesky
/// pivot of J J^T below 1e-8, ik.hpp) the same damping applies to the velocity solves, and
/// these equations hold only approximately (the manipulability says so).
/// Limits: positions are projected onto the limits like every Newton step (ik.hpp), so q
/// never leaves them. A joint that sits at a limit and whose velocity would take it out is
/// held there (q_dot_i = q_ddot_i = 0) and, while at least 6 joints are left, the others
/// follow the tool with the same formulas on the reduced arm J W (W = diag(1, .., 0, ..)):
/// the motion stays consistent, and the report shows a zero position margin. A motion that
/// needs more than the remaining joints can give fails the IK (kIk).
class JointTracker {
 public:
  /// `model` must outlive the tracker and be valid (validate_robot); q_seed.size() == dof.
  /// With fewer than 6 joints every track() reports not converged (ik.hpp). Allocates its
  /// workspace here, once.
  JointTracker(const RobotModel& model, const JointVector& q_seed, const IkOptions& options = {});
  ~JointTracker();
  JointTracker(JointTracker&&) noexcept;
  JointTracker& operator=(JointTracker&&) noexcept;

  /// Computes the joint sample for `x` (the next sample in time order, x.t increasing)
  /// into `out`; returns out.converged. After a failure the tracker keeps the last good
  /// configuration (and the next call predicts from it); out holds the failed attempt.
  bool track(const CartesianState& x, JointSample& out);
  /// track() with the continuation of ContinuationRule: where the step from the last good
  /// sample to `x` does not converge or leaves its branch, the interval is walked through
  /// states of `between` (the same motion at times between the two samples) in smaller
  /// steps. The first call after construction or reset() solves from the seed, as track().
  /// `out` is the joint sample at x; its midpoint_deviation is measured against the last good
  /// sample before the walk, whatever the walk tracked in between. On failure the tracker
  /// keeps the last configuration it accepted (possibly within the interval) and `out` holds
  /// the failed attempt. Never fails where track() would have converged (FollowResult::jumped).
  /// No heap allocation.
  FollowResult follow(const CartesianState& x, CartesianSource& between, JointSample& out,
                      const ContinuationRule& rule);
  /// Starts again from a new seed (the next track() is a first call).
  void reset(const JointVector& q_seed);
  /// Joints chosen ahead for the whole motion (optim/redundancy), or none (null): each
  /// sample after the first is then the Newton projection of the reference's joints at its
  /// time (x.t, from the motion's start) or arc length (x.s, from the path's start) instead of
  /// the predictor, and the null-space term is the reference's velocity, z = q_ref_dot(t) or
  /// q_s(s) x.s_dot, z_dot = q_ref_ddot(t) or q_ss(s) x.s_dot^2 + q_s(s) x.s_ddot, instead of
  /// the joint-limit avoidance: the self-motion follows the reference, which at its own
  /// samples holds the pose already (no correction). The reference must outlive its use.
  void set_reference(const JointReference* reference);

 private:
  bool attempt(const CartesianState& x, JointSample& out);
  void commit(const CartesianState& x, const JointSample& out);

  struct State;
  std::unique_ptr<State> state_;
};

/// Which limit an event is about.
enum class LimitKind {
  kPosition,      ///< joint position outside [minPosition, maxPosition]
  kVelocity,      ///< |q_dot| > maxVelocity
  kAcceleration,  ///< |q_ddot| > maxAcceleration
  kIk,            ///< the IK did not converge (value: position error [m])
  kBranch,        ///< midpoint deviation above the tolerance (a branch change or singularity)
  kJerk,          ///< |q_ddot_k - q_ddot_k-1| / dt > maxJerk (where the model gives one)
  kTorque,        ///< |tau| > maxTorque (where the model gives one and has mass properties)
};

/// One joint-limit event of a motion: where a limit is broken, or how close it comes.
struct LimitEvent {
  LimitKind kind = LimitKind::kPosition;
  std::size_t joint = 0;   ///< zero-based joint (0 for kIk / kBranch)
  std::size_t sample = 0;  ///< zero-based sample index
  double t = 0.0;          ///< [s]
  double value = 0.0;      ///< the joint value / |velocity| / |acceleration| (or the error)
  double limit = 0.0;      ///< the limit it is compared with
  /// kPosition: distance to the nearer position limit [rad or m] (negative outside);
  /// kVelocity, kAcceleration: limit - |value|; kIk, kBranch: tolerance - value.
  double margin = 0.0;
};

/// How one joint is used over a motion.
struct JointUsage {
  double min_position = std::numeric_limits<double>::infinity();
  double max_position = -std::numeric_limits<double>::infinity();
  double peak_velocity = 0.0;      ///< max |q_dot| [rad/s or m/s]
  double peak_acceleration = 0.0;  ///< max |q_ddot| [rad/s^2 or m/s^2]
  double velocity_usage = 0.0;     ///< peak_velocity / maxVelocity
  double acceleration_usage = 0.0; ///< peak_acceleration / maxAcceleration
  double peak_torque = 0.0;        ///< max |tau| [N m or N] (0 without mass properties)
  std::optional<double> torque_usage;  ///< peak_torque / maxTorque, where the joint has one
  double position_margin = std::numeric_limits<double>::infinity();  ///< smallest distance to a position limit
};

/// At most this many binding stretches are kept (the last one absorbs the rest).
inline constexpr std::size_t kMaxBindingStretches = 64;
/// A new limit takes over the stretch only when its usage exceeds the current one's by this
/// factor (hysteresis: near-equal usages do not split the motion into slivers).
inline constexpr double kUsageHysteresis = 1.05;

/// A limit counts as broken when the value passes it by more than this fraction of the
/// limit (1 for positions below 1 rad or m): rounding, not motion. A time-optimal motion runs
/// exactly at its limits.
inline constexpr double kLimitTolerance = 1e-9;

/// A joint acceleration measured between consecutive samples counts when it passes the limit
/// by more than this fraction: the differences of two joint velocities, each exact to the
/// IK's ~1e-12, over 1e-4 s carry ~1e-8 of rounding; a velocity step is far above.
inline constexpr double kStepTolerance = 1e-3;

/// The joint-space report of a whole motion (what PlanTrajectory returns with a robot).
struct JointMotionReport {
  std::size_t samples = 0;
  /// Samples whose IK converged: the joint figures, the tightest margins and the lowest
  /// manipulability are taken over these only (none: they keep their +-infinity starts).
  std::size_t converged_samples = 0;
  std::vector<JointUsage> joints;
  bool torques = false;  ///< the samples carried joint torques (peak_torque, torque_usage hold)
  LimitEvent tightest_position;      ///< smallest position margin, its joint and time
  LimitEvent tightest_velocity;      ///< smallest velocity margin
  LimitEvent tightest_acceleration;  ///< smallest acceleration margin
  double max_position_error = 0.0;     ///< worst IK residual [m]
  double max_orientation_error = 0.0;  ///< worst IK residual [rad]
  double max_midpoint_deviation = 0.0; ///< worst JointSample::midpoint_deviation [m]
  double max_midpoint_deviation_t = 0.0;
  double min_manipulability = std::numeric_limits<double>::infinity();
  double min_manipulability_t = 0.0;
  /// Every broken limit, the first sample of each (joint, kind) run only, in time order
  /// (bounded: at most one event per joint and kind). Within a sample, causes first: a joint
  /// at or past its position limit, then a branch jump, velocities, accelerations. A joint
  /// that reaches its limit (margin >= 0: the tracker holds it there) is listed only where
  /// another limit breaks in that sample, or (within 1 % of its range) in the last good
  /// sample before an IK failure: it is then the likely cause.
  std::vector<LimitEvent> violations;
  /// Which joint limit is the most used, stretch by stretch, in time order (samples at rest,
  /// where every usage is 0, join the stretch around them; consecutive stretches share their
  /// boundary sample). Joint limits (the jerk by differences of the accelerations, where the
  /// model gives one), and the Cartesian limits of a path or a line where the
  /// request gives them (JointReportBuilder::set_cartesian_limits); usage the largest on
  /// the stretch.
  std::vector<BindingStretch> binding;
  bool feasible() const { return violations.empty(); }
};

/// Accumulates a JointMotionReport sample by sample (O(joints) memory, whatever the
/// motion's length; no heap allocation in add()). The limits are the model's (pass a copy
/// with other limits to check against them).
///  - `branch_tolerance` [m] bounds midpoint_deviation (kBranch above it). The default
///    1 mm is 10x the chord sagitta kappa ds^2 / 8 <= 1e-4 m of the thesis's demo paths at
///    100 Hz (measured on the PA-10: at most 4e-6 m) and far below the deviation of a
///    branch flip (a joint turning by a sizeable angle between samples: centimetres).
///  - `ik_position_tolerance` [m]: the kIk event's limit (the tracker's
///    IkOptions::position_tolerance); kIk is raised by a sample that did not converge.
///  - the acceleration is also measured between consecutive samples, |q_dot_k - q_dot_k-1| / dt
///    (the mean of q_ddot over the step, so within the limit whenever q_ddot is): a step of a
///    joint velocity between samples (the tool's angular velocity jumping at a key frame
///    whose turns are not eased) is an acceleration beyond any limit as dt shrinks, which the
///    samples' own q_ddot on either side do not show. Above the limit by more than
///    kStepTolerance it counts as the joint's acceleration there.
/// Before the first sample the tightest events have margin +infinity.
class JointReportBuilder {
 public:
  explicit JointReportBuilder(const RobotModel& model, double branch_tolerance = 1e-3,
                              double ik_position_tolerance = IkOptions{}.position_tolerance);
  /// Adds sample number `sample` (zero-based, increasing) at time t [s].
  void add(std::size_t sample, double t, const JointSample& s) { add(sample, t, 0.0, s); }
  /// The same, with the sample's arc length along the path s_path [m] (for the stretches).
  void add(std::size_t sample, double t, double s_path, const JointSample& s) { add(sample, t, s_path, s, nullptr); }
  /// The same, with the tool's state at the sample: the Cartesian limits set by
  /// set_cartesian_limits take part in the binding stretches (|v| against the speed limit;
  /// the tangential part of a, a . v / |v|, and the centripetal rest against the
  /// acceleration limit, each; |omega|, |alpha|).
  void add(std::size_t sample, double t, double s_path, const JointSample& s, const CartesianState* tool);
  /// The Cartesian limits of the samples that follow (a path's or a line's; none for a joint
  /// move: CartesianLimits{}).
  void set_cartesian_limits(const CartesianLimits& limits) { cartesian_ = limits; }
  const JointMotionReport& report() const { return report_; }

 private:
  static constexpr std::size_t kKinds = 7;  ///< LimitKind values
  void record(LimitKind kind, std::size_t joint, std::size_t sample, double t, double value, double limit,
              double margin);
  void update_binding(std::size_t sample, double t, double s_path, const JointSample& s, const CartesianState* tool);
  /// Records every (non-continuous) joint of q at or past its position limit, or within
  /// range_fraction of its range from it.
  void record_held(std::size_t sample, double t, const JointVector& q, double range_fraction);

  const RobotModel* model_;
  double branch_tolerance_;
  double ik_position_tolerance_;
  JointMotionReport report_;
  JointVector q_prev_;         ///< the last converged sample's joints
  JointVector q_dot_prev_;     ///< and joint velocities
  JointVector q_ddot_prev_;    ///< and accelerations
  double t_prev_ = 0.0;        ///< and its time [s]
  std::size_t sample_prev_ = 0;  ///< and index
  bool has_prev_ = false;      ///< the last sample converged
  std::vector<bool> reported_;  ///< (joint, kind) already in violations: joint * kKinds + kind
  CartesianLimits cartesian_;   ///< of the samples being added
  JointVector jerk_;            ///< |q_ddot - q_ddot_prev| / dt at the sample being added (0 at the first)
};

/// The binding stretches of a motion without a robot: the tool's Cartesian limits alone, by
/// JointMotionReport::binding's rule (the most used limit at each sample, a new stretch only
/// where another is used kUsageHysteresis times as much; at most kMaxBindingStretches).
/// Allocates only when a stretch begins.
class ToolBindingBuilder {
 public:
  /// The Cartesian limits of the samples that follow (a path's or a line's; none for a
  /// joint move: CartesianLimits{}).
  void set_cartesian_limits(const CartesianLimits& limits) { limits_ = limits; }
  /// Adds sample number `sample` (zero-based, increasing) at time t [s] and arc length
  /// s_path [m] with the tool's state there.
  void add(std::size_t sample, double t, double s_path, const CartesianState& tool);
  const std::vector<BindingStretch>& binding() const { return binding_; }

 private:
  CartesianLimits limits_;
  std::vector<BindingStretch> binding_;
};

}  // namespace geotraj::core
