// A planned trajectory of any kind, sampled at the cycle rate with the tool's full state
// and, with a robot, the joints: the motion along a geometric path (motion.hpp,
// orientation.hpp), a joint-interpolated move or a Cartesian straight-line move (moves.hpp,
// thesis 6.2.2). One sampler serves PlanTrajectory's joint report and StreamSamples.
#pragma once

#include <cstddef>
#include <optional>
#include <variant>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/planning/moves.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::core {

/// The motion along a path: the path, its timing and the tool's orientation (a value).
struct PathMotion {
  Path path;
  MotionPlan timing;
  OrientationPlan orientation;
};

/// Any planned trajectory.
using Trajectory = std::variant<PathMotion, JointMovePlan, LinearMovePlan>;

/// Number of samples of a trajectory (exact; t_k = k / rate, the last at the duration).
std::size_t sample_count(const Trajectory& trajectory);
/// Duration of a trajectory [s].
double duration(const Trajectory& trajectory);

/// One sample: the tool's state in W and, with a robot, the joints.
struct TrajectorySample {
  double t = 0.0;            ///< [s]
  double u = 0.0;            ///< path parameter (paths), progress in [0, 1] (moves)
  double s = 0.0;            ///< arc length from the start [m] (paths, linear moves; 0 for joint moves)
  std::size_t segment = 0;   ///< path segment (0 for moves)
  CartesianState tool;       ///< pose X_WT, v, omega, a, alpha in W
  Eigen::Quaterniond q_WT = Eigen::Quaterniond::Identity();  ///< tool orientation (= tool.X_WT's), continuous
  double speed = 0.0;        ///< |v_WT| [m/s]
  bool has_joints = false;
  JointSample joints;        ///< with a robot: joints and the IK certificates
};

/// Samples a trajectory in time order (no heap allocation per sample). With `robot`, path
/// motions and linear moves go through the JointTracker (IK at every sample, seeded by
/// `seed`); joint moves carry their joints and need no IK. Successive orientation
/// quaternions are kept in one hemisphere (q and -q are one rotation), so the stream of
/// quaternions is continuous. `trajectory` and `robot` must outlive the sampler.
class TrajectorySampler {
 public:
  TrajectorySampler(const Trajectory& trajectory, const RobotModel* robot, const JointVector& seed,
                    const IkOptions& options = {});
  /// Writes the next sample; false after the last one.
  bool next(TrajectorySample& out);
  /// Index of the next sample.
  std::size_t index() const { return k_; }

 private:
  const Trajectory* trajectory_;
  std::optional<MotionSampler> path_sampler_;
  std::optional<JointMoveSampler> joint_sampler_;
  std::optional<LinearMoveSampler> linear_sampler_;
  std::optional<JointTracker> tracker_;
  MotionSample motion_sample_;
  MoveSample move_sample_;
  Eigen::Quaterniond previous_q_ = Eigen::Quaterniond::Identity();
  std::size_t k_ = 0;
};

}  // namespace geotraj::core
