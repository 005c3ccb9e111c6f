// Jerk-limited timing of a joint path through waypoints (core/planning/joint_path.hpp): its
// exact time-optimal sweep, re-timed portion by portion by the jerk-limited NLP of
// time_optimal_jerk.hpp on the same grids (jerk_limited_rounds), so that the joint
// accelerations are continuous everywhere (zero at the rests) and every joint jerk is
// within its maxJerk between the samples as on them.
#pragma once

#include "core/error.hpp"
#include "core/planning/joint_path.hpp"
#include "optim/common/report.hpp"
#include "optim/timing/time_optimal_jerk.hpp"

namespace geotraj::optim {

/// The exact sweep's grid under a jerk-limited joint path: coarser than the sweep's own
/// (the NLP's cost grows with the grid: each blend 24 uniform intervals, the lines of a portion
/// 100).
inline core::JointPathOptions joint_path_jerk_exact_options() {
  core::JointPathOptions options;
  options.blend_intervals = 24;
  options.line_intervals = 100;
  options.crowd_blend_ends = false;
  return options;
}

/// A jerk-limited joint path.
struct JerkLimitedJointPath {
  /// The motion: its profile (acceleration continuous), duration, samples and usages (the
  /// last sample check's; binding empty: the joint report says which limit binds where).
  /// Its grids, solutions and limit scales are the exact sweep's.
  core::JointPathPlan plan;
  double exact_duration_s = 0.0;  ///< the time-optimal sweep's duration on the same grids [s]
  double jerk_usage = 0.0;        ///< largest mean joint jerk over a period / maxJerk
  JerkRounds rounds;              ///< the NLP's portions, report, refinements, slow-down
};

/// Times `path` for `robot` within its joints' maxVelocity, maxAcceleration and (where
/// given, else options.joint_jerk) maxJerk, each scaled by speedScale (v s, a s^2, j s^3):
/// core::plan_joint_path on exact_options' grids, then jerk_limited_rounds with the sample
/// check of core::check_joint_path_samples (the cycle rate and exact_options.check_rate_hz,
/// the jerk as the difference of successive accelerations over the period). With
/// motion.durationS > 0 the result is stretched to it (as core::plan_joint_path does).
/// Errors: core::plan_joint_path's and jerk_limited_rounds'.
core::Expected<JerkLimitedJointPath> plan_joint_path_jerk(const core::ValidRobot& robot, core::JointPath path,
                                                          const core::MotionSpec& motion,
                                                          const core::JointPathOptions& exact_options =
                                                              joint_path_jerk_exact_options(),
                                                          JerkTimingOptions options = {});

}  // namespace geotraj::optim
