// A planned trajectory of any kind, sampled at the cycle rate with the tool's full state
// and, with a robot, the joints: the motion along a geometric path (motion.hpp,
// orientation.hpp), a joint-interpolated move or a Cartesian straight-line move (moves.hpp,
// thesis 6.2.2). One sampler serves PlanTrajectory's joint report and StreamSamples.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <variant>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/planning/joint_path.hpp"
#include "core/planning/moves.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::core {

/// The motion along a path: the path, its timing and the tool's orientation (a value).
struct PathMotion {
  Path path;
  MotionPlan timing;
  OrientationPlan orientation;
  /// With a robot: the joints chosen ahead for the whole motion (optim/redundancy), which
  /// the samplers' tracker follows (JointTracker::set_reference); null: sample by sample.
  std::shared_ptr<const JointReference> joints = nullptr;
  // (A roll of the tool chosen ahead, RobotSpec.toolAxisFree, is in orientation.roll: a
  // function of the arc length, which the timings see.)
};

/// One rest-to-rest motion: along a path, a joint move, a straight-line move or a joint path
/// through waypoints.
using StepMotion = std::variant<PathMotion, JointMovePlan, LinearMovePlan, JointPathPlan>;

/// Motions executed one after the other, the robot at rest at each junction (a sequence).
/// Sample times stay on one grid of the cycle rate: step k starts at the first grid time at
/// or after the end of step k - 1 (it rests for the part of a period between), and each
/// step but the last streams its samples without its final one (the rest at its end, which
/// is where the next step's first sample stands, at rest). So the sequence has
/// sum over k < K of (n_k - 1) + n_K samples, n_k those of step k alone, at t = k / rate,
/// the last at exactly the end. All steps have the same cycle rate.
struct SequenceMotion {
  std::vector<StepMotion> steps;   ///< at least one
  std::vector<double> start_times;  ///< of each step [s], on the grid
  std::vector<std::size_t> first_samples;  ///< index of each step's first sample
  std::size_t sample_count = 0;
  double duration_s = 0.0;
  /// Per step: the index a sample reports (TrajectorySample::step), and, where not empty,
  /// one per path segment (a step that is a blended chain of several requested steps).
  std::vector<std::size_t> step_index;
  std::vector<std::vector<std::size_t>> segment_steps;
};

/// Lays out `steps` (at least one, of one cycle rate `rate_hz`) as a sequence.
SequenceMotion make_sequence(std::vector<StepMotion> steps, double rate_hz);

/// Any planned trajectory.
using Trajectory = std::variant<PathMotion, JointMovePlan, LinearMovePlan, SequenceMotion, JointPathPlan>;

/// The motion spec a trajectory was timed with: its own, or its first step's (the steps of a
/// sequence share one cycle rate; each holds the request's motion unless it has its own).
const MotionSpec& motion_spec(const StepMotion& step);
const MotionSpec& motion_spec(const Trajectory& trajectory);

/// Number of samples of a trajectory (exact; t_k = k / rate, the last at the duration).
std::size_t sample_count(const Trajectory& trajectory);
std::size_t sample_count(const StepMotion& step);
/// Duration of a trajectory [s].
double duration(const Trajectory& trajectory);
double duration(const StepMotion& step);

/// One sample: the tool's state in W and, with a robot, the joints.
struct TrajectorySample {
  double t = 0.0;            ///< [s]
  double u = 0.0;            ///< path parameter (paths), progress in [0, 1] (moves)
  double s = 0.0;            ///< arc length from the start [m] (paths, linear moves; 0 for joint moves)
  std::size_t segment = 0;   ///< path segment (0 for moves)
  /// Sequence step (0 otherwise); u, s and segment are then the step's own.
  std::size_t step = 0;
  CartesianState tool;       ///< pose X_WT, v, omega, a, alpha in W
  Eigen::Quaterniond q_WT = Eigen::Quaterniond::Identity();  ///< tool orientation (= tool.X_WT's), continuous
  double speed = 0.0;        ///< |v_WT| [m/s]
  bool has_joints = false;
  JointSample joints;        ///< with a robot: joints and the IK certificates
};

/// A view of one step motion, wherever it is held.
using StepRef = std::variant<const PathMotion*, const JointMovePlan*, const LinearMovePlan*, const JointPathPlan*>;

/// Samples one step motion (see TrajectorySampler); a sequence runs one per step.
class StepSampler {
 public:
  StepSampler(StepRef step, const RobotModel* robot, const JointVector& seed, const IkOptions& options);
  /// Writes the next sample (t from the step's start, q_WT as the step gives it); false
  /// after the last one.
  bool next(TrajectorySample& out);
  /// Writes the sample at time t from the step's start [s], off the grid (times must not
  /// decrease; t is clamped to [0, duration]). Do not mix with next().
  void at(double t, TrajectorySample& out);
  std::size_t index() const { return k_; }
  /// JointSample::tau sized for the caller to fill, not computed (TrajectorySampler::leave_torques).
  void leave_torques() { compute_torques_ = false; }

 private:
  void finish(TrajectorySample& out);

  StepRef step_;
  std::optional<MotionSampler> path_sampler_;
  std::optional<JointMoveSampler> joint_sampler_;
  std::optional<LinearMoveSampler> linear_sampler_;
  std::optional<JointPathSampler> joint_path_sampler_;
  std::optional<JointTracker> tracker_;
  std::optional<PathMotionSource> path_between_;  // with the tracker: the path between samples
  MotionSample motion_sample_;
  MoveSample move_sample_, move_between_;
  std::size_t k_ = 0;
  /// The model whose joint torques each sample carries (JointSample::tau), where it has mass
  /// properties; null otherwise.
  const RobotModel* dynamics_ = nullptr;
  bool compute_torques_ = true;
};

/// Samples a trajectory in time order (no heap allocation per sample; a sequence allocates
/// once per step). With `robot`, path motions and linear moves go through the JointTracker
/// (IK at every sample, seeded by `seed`, and in a sequence by the joints at the end of the
/// previous step); joint moves and joint paths carry their joints and need no IK. Successive orientation
/// quaternions are kept in one hemisphere (q and -q are one rotation), so the stream of
/// quaternions is continuous. `trajectory` and `robot` must outlive the sampler.
class TrajectorySampler {
 public:
  TrajectorySampler(const Trajectory& trajectory, const RobotModel* robot, const JointVector& seed,
                    const IkOptions& options = {});
  /// Writes the next sample; false after the last one.
  bool next(TrajectorySample& out);
  /// Writes the sample at time t [s] off the grid (live execution retimes a trajectory):
  /// the same path, moves, IK and seeding as next(), at any t in [0, duration] (clamped),
  /// t not decreasing from call to call. Do not mix with next().
  void at(double t, TrajectorySample& out);
  /// Index of the next sample.
  std::size_t index() const { return k_; }
  /// Leaves JointSample::tau to the caller: sized, not computed (live execution computes the
  /// torques once, at its speed factor).
  void leave_torques();

 private:
  void finish(TrajectorySample& out);
  StepRef step(std::size_t i) const;
  std::size_t step_count() const;
  void start_step(const JointVector& seed);

  const Trajectory* trajectory_;
  const RobotModel* robot_;
  IkOptions options_;
  std::optional<StepSampler> sampler_;
  std::size_t step_ = 0;
  TrajectorySample scratch_;
  Eigen::Quaterniond previous_q_ = Eigen::Quaterniond::Identity();
  std::size_t k_ = 0;
  bool compute_torques_ = true;
};

}  // namespace geotraj::core
