// Jerk-limited timing of a joint path. See joint_path_jerk.hpp.
#include "optim/timing/joint_path_jerk.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "core/format.hpp"
#include "core/motion/speed_profile.hpp"

namespace geotraj::optim {

namespace {

// A given duration stretches the timed motion uniformly; the sample count.
core::Expected<JerkLimitedJointPath> finish(JerkLimitedJointPath& out, const core::MotionSpec& motion) {
  core::JointPathPlan& plan = out.plan;
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
  return std::move(out);
}

}  // namespace

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

  // Every portion one line (two waypoints; collinear ones; back and forth, which rests at
  // each reversal): the jerk-limited optimum is the joint move's, a double S in sigma under
  // the line's own limits (each joint's limit over |d_j|, the slowest joint's sets each),
  // in closed form instead of the programme on a grid (up to 10 % slower there).
  // Each portion between rests one line: its segments all lines of one direction (collinear
  // waypoints pass on the line without a rest).
  bool lines_only = true;
  std::vector<core::SpeedProfile> line_profiles;
  const auto& rests = plan.path.rests;
  for (std::size_t p = 0, first = 0; p + 1 < rests.size() && lines_only; ++p) {
    if (first >= plan.path.segments.size()) {
      lines_only = false;
      break;
    }
    const core::JointPathSegment& seg = plan.path.segments[first];
    std::size_t last = first;
    while (last < plan.path.segments.size() && plan.path.segments[last].sigma1 <= rests[p + 1]) {
      const auto& s = plan.path.segments[last];
      lines_only = lines_only && s.kind == core::JointPathSegment::Kind::kLine && (s.d - seg.d).norm() <= 1e-12;
      ++last;
    }
    lines_only = lines_only && last > first;
    first = last;
    if (!lines_only) break;
    constexpr double kInf = std::numeric_limits<double>::infinity();
    double v = kInf, a = kInf, j = kInf;
    for (Eigen::Index k = 0; k < seg.d.size(); ++k) {
      const double dk = std::abs(seg.d(k));
      if (!(dk > 0.0)) continue;
      v = std::min(v, plan.limits.joint_velocity(k) / dk);
      a = std::min(a, plan.limits.joint_acceleration(k) / dk);
      j = std::min(j, options.joint_jerk(k) / dk);
    }
    auto profile = std::isfinite(j) ? core::min_time_double_s(rests[p + 1] - rests[p], v, a, j)
                                    : core::Expected<core::SpeedProfile>();
    if (!std::isfinite(j) || !profile) {
      lines_only = false;
      break;
    }
    line_profiles.push_back(std::move(*profile));
  }
  if (lines_only) {
    core::SpeedProfile exact_profile = std::move(plan.profile);
    plan.profile = core::joined_profile(line_profiles, plan.path.rests);
    plan.duration_s = plan.profile.duration;
    core::TimeOptimalLimits checked = plan.limits;
    checked.joint_jerk = options.joint_jerk;
    auto check = core::check_joint_path_samples(plan, checked, exact_stoppable);
    if (!check) return tl::make_unexpected(check.error());
    if (!check->check.broken) {
      plan.velocity_usage = check->velocity_usage;
      plan.acceleration_usage = check->acceleration_usage;
      plan.check_rate_hz = check->check.check_rate_hz;
      out.jerk_usage = check->jerk_usage;
      out.rounds.report.status = OptimizerStatus::kConverged;
      out.rounds.report.message =
          "closed form: a double S along each of the " + std::to_string(line_profiles.size()) + " lines";
      out.rounds.worst_sample_usage = check->check.worst_usage;
      out.rounds.check_rate_hz = check->check.check_rate_hz;
      plan.binding.clear();
      plan.refinements = 0;
      plan.duration_grid_error = 0.0;
      return finish(out, motion);
    }
    plan.profile = std::move(exact_profile);  // not expected of the closed form: the programme decides
    plan.duration_s = exact_duration;
  }

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
  return finish(out, motion);
}

}  // namespace geotraj::optim
