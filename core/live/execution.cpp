// Live execution of a planned trajectory. See execution.hpp.
#include "core/live/execution.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <variant>

#include "core/format.hpp"
#include "core/robot/dynamics.hpp"

namespace geotraj::core {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The largest speed-factor acceleration [1/s] and jerk [1/s^2] the bounds give: from rest to
// full speed in a microsecond is beyond any cycle, and a lower bound is always safe. A plan
// that barely moves a limited quantity (a peak rate of 1e-300) would otherwise give a room
// of 1e300 and, over ramp_s, an infinite jerk that no rate profile can use.
constexpr double kMaxFactorAcceleration = 1e6;
constexpr double kMaxFactorJerk = 1e12;

// The smallest multiple of the cycle rate at or above `wanted` [Hz] with at most
// `max_samples` samples over `duration` [s] (never below the cycle rate).
double check_rate(double cycle_hz, double wanted_hz, double duration_s, std::size_t max_samples) {
  double multiple = std::max(1.0, std::ceil(wanted_hz / cycle_hz - 1e-9));
  while (multiple > 1.0 && duration_s * cycle_hz * multiple > static_cast<double>(max_samples)) multiple -= 1.0;
  return cycle_hz * multiple;
}

// d s / d tau along the plan and its derivative: the path speed and the tangential
// acceleration (the whole acceleration where the tool is at rest).
double tangential(const TrajectorySample& x) {
  const double speed = x.tool.v_WT.norm();
  return speed > 0.0 ? x.tool.a_WT.dot(x.tool.v_WT) / speed : x.tool.a_WT.norm();
}

// The Cartesian limits a step's plan keeps, and so live execution with it: a path's and a
// straight line's own motion spec; none for a joint move or path (its tool goes where the joints
// take it, at whatever Cartesian rates their limits give).
const MotionSpec* kept_cartesian(const PathMotion& m) { return &m.timing.spec; }
const MotionSpec* kept_cartesian(const LinearMovePlan& m) { return &m.spec; }
const MotionSpec* kept_cartesian(const JointMovePlan&) { return nullptr; }
const MotionSpec* kept_cartesian(const JointPathPlan&) { return nullptr; }
const MotionSpec* kept_cartesian(const SequenceMotion&) { return nullptr; }  // per step, below
const MotionSpec* kept_cartesian(const StepMotion& m) {
  return std::visit([](const auto& step) { return kept_cartesian(step); }, m);
}

// Where a step's tool rows are among the rows (kNoRow: the step keeps no such limit).
constexpr std::size_t kNoRow = static_cast<std::size_t>(-1);
struct ToolRows {
  std::size_t tangential = kNoRow;
  std::size_t angular = kNoRow;
};

// Appends the tool rows of a step whose plan keeps `spec`'s Cartesian limits (`where`
// names the step in a sequence).
ToolRows add_tool_rows(const MotionSpec* spec, const std::string& where, std::vector<LiveRow>& rows) {
  ToolRows out;
  if (spec == nullptr) return out;
  if (spec->max_acceleration || spec->max_jerk) {
    out.tangential = rows.size();
    rows.push_back({"tool tangential" + where, "m", 0, 0, 0, spec->max_acceleration.value_or(kInf),
                    spec->max_jerk.value_or(kInf)});
  }
  if (spec->max_angular_acceleration) {
    out.angular = rows.size();
    rows.push_back({"tool angular" + where, "rad", 0, 0, 0, *spec->max_angular_acceleration, kInf});
  }
  return out;
}

}  // namespace

LiveLimits live_limits(const RobotModel* robot) {
  LiveLimits out;
  if (robot != nullptr) {
    const auto n = static_cast<Eigen::Index>(robot->limits.size());
    out.acceleration.resize(n);
    out.jerk.resize(n);
    for (Eigen::Index j = 0; j < n; ++j) {
      const JointLimits& l = robot->limits[static_cast<std::size_t>(j)];
      out.acceleration[j] = l.max_acceleration;
      out.jerk[j] = l.max_jerk.value_or(kInf);
    }
  }
  return out;
}

FactorBounds factor_bounds(const std::vector<LiveRow>& rows, double r_high, double ramp_s) {
  const double r = std::clamp(r_high, 0.0, 1.0);
  FactorBounds b;
  b.acceleration = kInf;
  // The speed factor's acceleration: the acceleration room, and half the jerk room.
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const LiveRow& row = rows[i];
    if (!(row.peak_rate > 0.0)) continue;  // a quantity the plan does not move
    double bound = kInf;
    if (std::isfinite(row.max_acceleration)) {
      bound = std::max(0.0, row.max_acceleration - row.peak_acceleration * r * r) / row.peak_rate;
    }
    // A plan at its jerk limit leaves no jerk room (start() refuses one beyond it).
    if (std::isfinite(row.max_jerk) && row.peak_jerk < row.max_jerk && row.peak_acceleration * r > 0.0) {
      const double room = row.max_jerk - row.peak_jerk * r * r * r;
      bound = std::min(bound, room / (6.0 * row.peak_acceleration * r));
    }
    if (bound < b.acceleration) {
      b.acceleration = bound;
      b.acceleration_row = i;
    }
  }
  if (!std::isfinite(b.acceleration)) {  // nothing limits: rest to full speed in ramp_s
    b.acceleration = 1.0 / ramp_s;
    b.acceleration_from_ramp = true;
  }
  // The speed factor's jerk: what the jerk room leaves after the acceleration term.
  b.jerk = kInf;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const LiveRow& row = rows[i];
    if (!(row.peak_rate > 0.0) || !std::isfinite(row.max_jerk) || !(row.peak_jerk < row.max_jerk)) continue;
    const double room = row.max_jerk - row.peak_jerk * r * r * r - 3.0 * row.peak_acceleration * r * b.acceleration;
    const double bound = std::max(0.0, room) / row.peak_rate;
    if (bound < b.jerk) {
      b.jerk = bound;
      b.jerk_row = i;
    }
  }
  b.acceleration = std::min(b.acceleration, kMaxFactorAcceleration);
  if (!std::isfinite(b.jerk)) {
    b.jerk = b.acceleration / ramp_s;
    b.jerk_from_ramp = true;
  }
  b.jerk = std::min(b.jerk, kMaxFactorJerk);
  return b;
}

StopPrediction predict_stop(double r, double r_dot, const FactorBounds& bounds) {
  if (!(bounds.acceleration > 0.0) || !(bounds.jerk > 0.0)) return {kInf, kInf};
  const RateProfile p = RateProfile::plan(r, r_dot, 0.0, bounds.acceleration, bounds.jerk);
  return {p.duration(), p.distance()};
}

LiveExecution::LiveExecution(const Trajectory& trajectory, const RobotModel* robot, const JointVector& seed,
                             const IkOptions& ik)
    : trajectory_(&trajectory),
      dynamics_(robot != nullptr && has_dynamics(*robot) ? robot : nullptr),
      sampler_(trajectory, robot, seed, ik) {
  sampler_.leave_torques();  // computed once per cycle, at the speed factor (write)
}

Expected<LiveExecution> LiveExecution::start(const Trajectory& trajectory, const RobotModel* robot,
                                             const JointVector& seed, const LiveLimits& limits, double cycle_rate_hz,
                                             const LiveOptions& options) {
  GEOTRAJ_CHECK(cycle_rate_hz > 0.0 && options.ramp_s > 0.0);
  LiveExecution live(trajectory, robot, seed, options.ik);
  live.period_ = 1.0 / cycle_rate_hz;
  live.duration_ = duration(trajectory);
  live.ramp_s_ = options.ramp_s;

  // The plan's peaks per unit of plan time, at the check rate.
  const std::size_t dof = robot != nullptr ? robot->dof() : 0;
  std::vector<LiveRow>& rows = live.rows_;
  for (std::size_t j = 0; j < dof; ++j) {
    LiveRow row;
    row.name = "joint " + std::to_string(j) + " (" + robot->joints[j].name + ")";  // from 0, as everywhere
    row.unit = robot->joints[j].type == JointType::kPrismatic ? "m" : "rad";
    row.max_acceleration = limits.acceleration[static_cast<Eigen::Index>(j)];
    row.max_jerk = limits.jerk[static_cast<Eigen::Index>(j)];
    rows.push_back(row);
  }
  // The tool's rows, per step: each step keeps its own plan's Cartesian limits.
  const auto* sequence = std::get_if<SequenceMotion>(&trajectory);
  std::vector<ToolRows> tool_rows;
  if (sequence != nullptr) {
    for (std::size_t i = 0; i < sequence->steps.size(); ++i) {
      const std::size_t shown = i < sequence->step_index.size() ? sequence->step_index[i] : i;
      tool_rows.push_back(add_tool_rows(kept_cartesian(sequence->steps[i]), " in step " + std::to_string(shown), rows));
    }
  } else {
    const MotionSpec* spec = std::visit([](const auto& motion) { return kept_cartesian(motion); }, trajectory);
    tool_rows.push_back(add_tool_rows(spec, "", rows));
  }

  const double rate = check_rate(cycle_rate_hz, options.check_rate_hz, live.duration_, options.max_check_samples);
  const double h = 1.0 / rate;
  TrajectorySampler pass(trajectory, robot, seed, options.ik);
  TrajectorySample x;
  JointVector previous_q_ddot = JointVector::Zero(static_cast<Eigen::Index>(dof));
  double previous_tangential = 0.0;
  std::size_t previous_step = 0;
  // The plan's own joint jerk as the samples show it (the refusal below): differences of
  // the accelerations at the cycle rate and at the final sample, as the planner's joint
  // report takes them, so that what PlanTrajectory reports within the jerk limits runs here.
  const auto per_cycle = static_cast<std::size_t>(std::llround(rate / cycle_rate_hz));
  JointVector cycle_q_ddot = JointVector::Zero(static_cast<Eigen::Index>(dof));
  JointVector cycle_jerk = JointVector::Zero(static_cast<Eigen::Index>(dof));
  double cycle_t = 0.0;
  const auto n = static_cast<std::size_t>(std::ceil(live.duration_ * rate - 1e-9));
  for (std::size_t k = 0; k <= n; ++k) {
    const double t = std::min(live.duration_, static_cast<double>(k) * h);
    if (k % 64 == 0 && options.stop.stop_requested()) {
      return tl::unexpected(Violations{{"motion", "stopped: the pass over the plan was cancelled"}});
    }
    pass.at(t, x);
    if (x.has_joints && !x.joints.converged) {
      return tl::unexpected(Violations{{"motion", "the robot's inverse kinematics fails on the plan at t = " +
                                                      number(t, 6) + " s (s = " + number(x.s, 6) + " m)"}});
    }
    for (std::size_t i = 0; i < dof && x.has_joints; ++i) {
      const auto j = static_cast<Eigen::Index>(i);
      LiveRow& row = rows[i];
      row.peak_rate = std::max(row.peak_rate, std::abs(x.joints.q_dot[j]));
      row.peak_acceleration = std::max(row.peak_acceleration, std::abs(x.joints.q_ddot[j]));
      if (k > 0) row.peak_jerk = std::max(row.peak_jerk, std::abs(x.joints.q_ddot[j] - previous_q_ddot[j]) / h);
      previous_q_ddot[j] = x.joints.q_ddot[j];
    }
    if (x.has_joints && (k % per_cycle == 0 || k == n)) {
      for (Eigen::Index j = 0; j < static_cast<Eigen::Index>(dof); ++j) {
        if (k > 0 && t > cycle_t) {
          cycle_jerk[j] = std::max(cycle_jerk[j], std::abs(x.joints.q_ddot[j] - cycle_q_ddot[j]) / (t - cycle_t));
        }
        cycle_q_ddot[j] = x.joints.q_ddot[j];
      }
      cycle_t = t;
    }
    // The step that holds t, as the sampler finds it (a step starts at its start time).
    std::size_t step = 0;
    if (sequence != nullptr) {
      while (step + 1 < sequence->steps.size() && t >= sequence->start_times[step + 1]) ++step;
    }
    const double a_t = tangential(x);
    if (const std::size_t i = tool_rows[step].tangential; i != kNoRow) {
      rows[i].peak_rate = std::max(rows[i].peak_rate, x.tool.v_WT.norm());
      rows[i].peak_acceleration = std::max(rows[i].peak_acceleration, std::abs(a_t));
      if (k > 0 && step == previous_step) {
        rows[i].peak_jerk = std::max(rows[i].peak_jerk, std::abs(a_t - previous_tangential) / h);
      }
    }
    previous_tangential = a_t;
    previous_step = step;
    if (const std::size_t i = tool_rows[step].angular; i != kNoRow) {
      rows[i].peak_rate = std::max(rows[i].peak_rate, x.tool.omega_WT.norm());
      rows[i].peak_acceleration = std::max(rows[i].peak_acceleration, x.tool.alpha_WT.norm());
    }
  }
  // Between two check samples a rate can pass the larger of its two values by at most its
  // acceleration times h / 2. Accelerations are taken at the check rate as measured (a
  // plan's accelerations may step, so its jerk says nothing of them between samples), as
  // the planner's own sample check does.
  for (LiveRow& row : rows) row.peak_rate += row.peak_acceleration * h / 2.0;

  // Speed changes keep the jerk limits only if the plan does: one whose own jerk breaks a
  // limit (a trapezoid's steps, a timing without jerk limits) is refused.
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const LiveRow& row = rows[i];
    const double own = i < dof ? cycle_jerk[static_cast<Eigen::Index>(i)] : row.peak_jerk;
    if (std::isfinite(row.max_jerk) && own > row.max_jerk * (1.0 + options.jerk_tolerance)) {
      return tl::unexpected(Violations{
          {"motion", "the plan's own jerk reaches " + number(own, 4) + " " + row.unit + "/s^3 on the " +
                         row.name + ", beyond its limit of " + number(row.max_jerk, 6) + " " + row.unit +
                         "/s^3: execute a jerk-limited plan (optimize.timing.jerkLimited for a path, profile "
                         "PROFILE_SHAPE_S_CURVE for a move)"}});
    }
  }
  const FactorBounds worst = live.bounds(1.0);
  const StopPrediction stop = predict_stop(1.0, 0.0, worst);
  if (!(stop.time_s <= options.max_stop_time_s)) {
    GEOTRAJ_CHECK(!worst.acceleration_from_ramp);  // a ramp's stop is finite and short
    const LiveRow& row = rows[worst.acceleration_row];
    return tl::unexpected(Violations{
        {"motion", "at full speed the plan uses " + number(100.0 * row.peak_acceleration / row.max_acceleration, 4) +
                       " % of the " + row.name + " acceleration limit (" + number(row.max_acceleration, 6) + " " +
                       row.unit + "/s^2): a stop on the path would take " +
                       (std::isfinite(stop.time_s) ? number(stop.time_s, 4) + " s" : std::string("forever")) +
                       ", more than " + number(options.max_stop_time_s, 4) +
                       " s; leave room for speed changes (a lower motion.speedScale, a longer durationS, or a "
                       "larger execute reserve)"}});
  }
  return live;
}

FactorBounds LiveExecution::bounds(double r_high) const { return factor_bounds(rows_, r_high, ramp_s_); }

StopPrediction LiveExecution::stopping() const {
  // The bounds over the range a stop spans: from r (or where r_dot carries it first) to 0.
  FactorBounds b = bounds(r_);
  const double r_stop = r_ + r_dot_ * std::abs(r_dot_) / (2.0 * b.jerk);
  if (r_stop > r_) b = bounds(r_stop);
  return predict_stop(r_, r_dot_, b);
}

void LiveExecution::retarget(double target) {
  target_ = std::clamp(target, 0.0, 1.0);
  // Before the first sample the plan is at rest: the factor starts at its target.
  if (k_ == 0) r_ = target_;
}

void LiveExecution::set_override(double fraction) {
  override_ = std::clamp(fraction, 0.0, 1.0);
  if (state_ == LiveState::kRunning) retarget(override_);
}

void LiveExecution::pause() {
  if (state_ != LiveState::kRunning) return;
  state_ = LiveState::kPausing;
  retarget(0.0);
}

void LiveExecution::resume() {
  if (state_ != LiveState::kPausing && state_ != LiveState::kPaused) return;
  state_ = LiveState::kRunning;
  retarget(override_);
}

void LiveExecution::stop() {
  if (state_ == LiveState::kStopped || state_ == LiveState::kCompleted) return;
  state_ = LiveState::kStopping;
  retarget(0.0);
}

bool LiveExecution::next(LiveSample& out) {
  if (state_ == LiveState::kStopped || state_ == LiveState::kCompleted) return false;
  const double t = static_cast<double>(k_) * period_;
  double tau = tau_;
  if (k_ == 0) {
    // The plan starts at rest: the first speed factor is the override (a stop or pause
    // before the first sample starts at rest).
    r_ = state_ == LiveState::kRunning ? override_ : 0.0;
    target_ = r_;
    r_dot_ = 0.0;
  } else if (state_ != LiveState::kPaused) {
    const double h = t - t_;
    if (r_ != target_ || r_dot_ != 0.0) {
      // Replanned every cycle from the state of the last sample, with the bounds over the
      // range of r this change spans (they widen as r falls).
      FactorBounds b = bounds(std::max(r_, target_));
      const double r_stop = r_ + r_dot_ * std::abs(r_dot_) / (2.0 * b.jerk);
      if (r_stop > std::max(r_, target_)) b = bounds(r_stop);
      const RateProfile profile = RateProfile::plan(r_, r_dot_, target_, b.acceleration, b.jerk);
      if (profile.duration() <= h) {
        tau += profile.at(h).x;
        r_ = target_;
        r_dot_ = 0.0;
      } else {
        const RateState s = profile.at(h);
        tau += s.x;
        r_ = std::clamp(s.v, 0.0, 1.0);
        r_dot_ = s.a;
      }
    } else {
      tau += r_ * h;
    }
  }
  t_ = t;
  if (tau >= duration_) {
    tau = duration_;
    state_ = LiveState::kCompleted;
    r_ = r_dot_ = 0.0;  // at rest at the plan's end
  } else if (r_ == 0.0 && r_dot_ == 0.0 && target_ == 0.0) {
    if (state_ == LiveState::kPausing) state_ = LiveState::kPaused;
    if (state_ == LiveState::kStopping) state_ = LiveState::kStopped;
  }
  if (!have_plan_ || tau != tau_) {
    sampler_.at(tau, plan_);
    have_plan_ = true;
  }
  tau_ = tau;
  write(out);
  ++k_;
  return true;
}

void LiveExecution::write(LiveSample& out) {
  const bool at_rest = state_ == LiveState::kPaused || state_ == LiveState::kStopped || state_ == LiveState::kCompleted;
  const double r = at_rest ? 0.0 : r_, r_dot = at_rest ? 0.0 : r_dot_;
  TrajectorySample& x = out.sample;
  x = plan_;
  x.t = t_;
  x.tool.t = t_;
  // The chain rule (file comment): d/dt = r d/dtau.
  x.tool.v_WT = plan_.tool.v_WT * r;
  x.tool.a_WT = plan_.tool.a_WT * (r * r) + plan_.tool.v_WT * r_dot;
  x.tool.omega_WT = plan_.tool.omega_WT * r;
  x.tool.alpha_WT = plan_.tool.alpha_WT * (r * r) + plan_.tool.omega_WT * r_dot;
  x.speed = plan_.speed * r;
  if (x.has_joints) {
    x.joints.q_dot = plan_.joints.q_dot * r;
    x.joints.q_ddot = plan_.joints.q_ddot * (r * r) + plan_.joints.q_dot * r_dot;
    // The torques of the motion as it runs, at its speed factor (the sampler leaves them).
    if (dynamics_ != nullptr && x.joints.tau.size() == x.joints.q.size())
      inverse_dynamics(*dynamics_, x.joints.q, x.joints.q_dot, x.joints.q_ddot, dynamics_options(*dynamics_),
                       x.joints.tau);
  }
  out.plan_time = tau_;
  out.speed_factor = r;
  out.speed_factor_rate = r_dot;
  out.state = state_;
}

}  // namespace geotraj::core
