// Jerk-limited timing of a joint path. See joint_path_jerk.hpp.
#include "optim/timing/joint_path_jerk.hpp"

#include <limits>
#include <utility>
#include <vector>

#include "core/format.hpp"

namespace geotraj::optim {

core::Expected<JerkLimitedJointPath> plan_joint_path_jerk(const core::ValidRobot& robot, core::JointPath path,
                                                          const core::MotionSpec& motion,
                                                          const core::JointPathOptions& exact_options,
                                                          JerkTimingOptions options) {
  core::JointPathOptions exact_stoppable = exact_options;
  if (!exact_stoppable.stop.stop_possible()) exact_stoppable.stop = options.stop;
  core::MotionSpec fastest = motion;
  fastest.duration_s = 0.0;
  auto exact = core::plan_joint_path(robot, std::move(path), fastest, exact_stoppable);
  if (!exact) return tl::make_unexpected(exact.error());
  const double exact_duration = exact->duration_s;
  JerkLimitedJointPath out{.plan = std::move(*exact), .exact_duration_s = exact_duration, .jerk_usage = 0.0,
                           .rounds = {}};
  core::JointPathPlan& plan = out.plan;
  if (plan.path.segments.empty()) return out;  // nothing moves: the exact plan's rest
  const core::RobotModel& model = robot;
  const double sc = motion.speed_scale, sc3 = sc * sc * sc * motion.acceleration_scale;
  if (options.joint_jerk.size() == 0) {
    const auto n = static_cast<Eigen::Index>(model.dof());
    options.joint_jerk = core::JointVector::Constant(n, std::numeric_limits<double>::infinity());
    for (Eigen::Index j = 0; j < n; ++j)
      if (const auto& mj = model.limits[static_cast<std::size_t>(j)].max_jerk) options.joint_jerk(j) = *mj * sc3;
  }
  options.max_jerk.reset();  // a joint path has no Cartesian limits

  JerkRoundHooks hooks;
  hooks.assemble = [&](const std::vector<core::SpeedProfile>& profiles) -> core::Expected<void> {
    plan.profile = core::joined_profile(profiles, plan.path.rests);
    plan.duration_s = plan.profile.duration;
    return {};
  };
  hooks.check = [&](const core::TimeOptimalLimits& limits) -> core::Expected<core::SampleCheck> {
    auto check = core::check_joint_path_samples(plan, limits, exact_stoppable);
    if (!check) return tl::make_unexpected(check.error());
    plan.velocity_usage = check->velocity_usage;
    plan.acceleration_usage = check->acceleration_usage;
    out.jerk_usage = check->jerk_usage;
    plan.check_rate_hz = check->check.check_rate_hz;
    return std::move(check->check);
  };
  auto rounds = jerk_limited_rounds(plan.grids, plan.solutions, plan.limits, std::move(options), exact_stoppable.stop,
                                    hooks);
  if (!rounds) return tl::make_unexpected(rounds.error());
  // An NLP that found no point leaves the sweep's profile slowed until its jerk is within
  // the limits: a motion many times longer than the path needs (87 times on a 200-waypoint
  // UR5 walk under the default jerk). Refused, naming what times the path instead.
  if (rounds->report.status == OptimizerStatus::kFailed) {
    const std::string& why = rounds->report.message;
    return tl::make_unexpected(core::Violations{core::unattainable(
        "optimize.timing", "the jerk-limited timing of this joint path found no solution (" +
                               why.substr(0, why.find("; slowed")) + "); optimize.timing.timeOptimal times it within the velocity and acceleration "
                               "limits alone, or give the joints a larger maxJerk")});
  }
  out.rounds = std::move(*rounds);
  plan.binding.clear();
  plan.refinements = out.rounds.refinements;
  plan.duration_grid_error = out.rounds.duration_grid_error;
  double duration = plan.duration_s;
  if (motion.duration_s > 0.0) {
    // The given duration: the same motion stretched (or compressed) uniformly in time.
    const double T = motion.duration_s / motion.speed_scale, c = T / duration;
    plan.profile = core::time_scaled(std::move(plan.profile), c);
    plan.profile.duration = T;
    plan.velocity_usage /= c;
    plan.acceleration_usage /= c * c;
    out.jerk_usage /= c * c * c;
    duration = T;
  }
  if (!(duration * motion.cycle_rate_hz < core::kMaxMotionSamples))
    return tl::make_unexpected(core::Violations{core::unattainable(
        "motion.durationS", "the joint path lasts " + core::number(duration, 6) +
                                " s, more samples than a motion may hold")});
  plan.duration_s = duration;
  plan.sample_count = core::grid_sample_count(duration, motion.cycle_rate_hz);
  return out;
}

}  // namespace geotraj::optim
