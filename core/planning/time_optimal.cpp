// The time-optimal plan around the sweep (time_optimal_sweep.cpp): the limits, the grids of
// the joint path's derivatives, the portions' motion, the check of its samples and the
// refinements. See time_optimal.hpp.
#include "core/planning/time_optimal.hpp"

#include <algorithm>
#include <optional>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "core/geometry/arc_length.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/format.hpp"
#include "core/planning/time_optimal_detail.hpp"
#include "core/robot/dynamics.hpp"

namespace geotraj::core {

using time_optimal_detail::sweep;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace


std::string describe(const BindingStretch& st) {
  std::string who = name(st.kind);
  if (is_joint_kind(st.kind))
    who = "joint " + std::to_string(st.joint) + (st.kind == BindingKind::kJointVelocity       ? " velocity"
                                                 : st.kind == BindingKind::kJointAcceleration ? " acceleration"
                                                 : st.kind == BindingKind::kJointJerk         ? " jerk"
                                                                                              : " torque");
  return who + " " + number(st.value, 6) + " of " + number(st.limit, 6) + " on s " + number(st.s_start, 6) + "-" + number(st.s_end, 6) +
         " m, t " + number(st.t_start, 6) + "-" + number(st.t_end, 6) + " s";
}

FieldViolation gravity_beyond(Eigen::Index joint, double gravity, double limit, double t, double s) {
  return unattainable("motion", "joint " + std::to_string(joint) + " needs " + number(std::abs(gravity), 6) +
                                    " N m against gravity (with the payload) at t = " + number(t, 6) + " s (s = " +
                                    number(s, 6) + "), beyond its maxTorque " + number(limit, 6) +
                                    kTorqueLimitSource + ": no timing holds that pose");
}

std::vector<std::size_t> every_second_point(std::size_t n) {
  std::vector<std::size_t> points;
  for (std::size_t i = 0; i < n; i += 2) points.push_back(i);
  if (n > 0 && points.back() != n - 1) points.push_back(n - 1);
  return points;
}

TimeOptimalLimits time_optimal_limits(const MotionSpec& spec, const RobotModel* robot) {
  TimeOptimalLimits lim;
  const double sc = spec.speed_scale;
  const double ac = sc * sc * spec.acceleration_scale;  // accelerations: the time scaling's s^2, the reserve
  if (robot) {
    const Eigen::Index n = static_cast<Eigen::Index>(robot->dof());
    lim.joint_velocity.resize(n);
    lim.joint_acceleration.resize(n);
    for (Eigen::Index j = 0; j < n; ++j) {
      lim.joint_velocity(j) = robot->limits[static_cast<std::size_t>(j)].max_velocity * sc;
      lim.joint_acceleration(j) = robot->limits[static_cast<std::size_t>(j)].max_acceleration * ac;
    }
  }
  if (robot && torque_limited(*robot)) {
    lim.joint_torque.setConstant(static_cast<Eigen::Index>(robot->dof()), kInf);
    for (std::size_t j = 0; j < robot->dof(); ++j)
      if (robot->limits[j].max_torque) lim.joint_torque(static_cast<Eigen::Index>(j)) = *robot->limits[j].max_torque;
    lim.torque_dynamic_scale = spec.acceleration_scale;
  }
  if (spec.max_speed) lim.speed = *spec.max_speed * sc;
  if (spec.max_acceleration) lim.tangential = lim.centripetal = *spec.max_acceleration * ac;
  if (spec.max_angular_speed) lim.angular_speed = *spec.max_angular_speed * sc;
  if (spec.max_angular_acceleration) lim.angular_acceleration = *spec.max_angular_acceleration * ac;
  return lim;
}

void set_torque_terms(const RobotModel& model, const JointVector& q, GridPoint& g) {
  path_torque_terms(model, q, g.q_s, g.q_ss, dynamics_options(model), g.tau_a, g.tau_b, g.tau_c);
}

bool torques_near_limits(const GridPoint& g0, const GridPoint& g1, double f, double s_ddot, double b,
                         const TimeOptimalLimits& limits, TorqueEstimate& estimate) {
  estimate = {};
  if (g0.tau_a.size() != limits.joint_torque.size() || g1.tau_a.size() != limits.joint_torque.size()) return true;
  for (Eigen::Index j = 0; j < limits.joint_torque.size(); ++j) {
    const double T = limits.joint_torque(j);
    if (!(T < kInf)) continue;
    const auto lerp = [f](double x0, double x1) { return x0 + f * (x1 - x0); };
    const double gravity = lerp(g0.tau_c(j), g1.tau_c(j));
    const double tau = lerp(g0.tau_a(j), g1.tau_a(j)) * s_ddot + lerp(g0.tau_b(j), g1.tau_b(j)) * b + gravity;
    if (std::abs(tau) > kTorqueScreen * T) return true;
    const double usage = dynamic_torque_usage(tau, gravity, T);
    if (usage > estimate.usage) estimate = {usage, std::abs(tau), T, j};
  }
  return false;
}

Expected<std::vector<std::vector<GridPoint>>> time_optimal_grids(const Path& path, const OrientationPlan& orientation,
                                                                 const std::vector<MotionPortion>& portions,
                                                                 const RobotModel* robot, const JointVector& seed,
                                                                 std::size_t grid_intervals, const IkOptions& ik,
                                                                 const JointReference* joints) {
  GEOTRAJ_CHECK(grid_intervals >= 2);
  GEOTRAJ_CHECK(joints == nullptr || joints->over() == ReferenceParameter::kArcLength);
  std::vector<std::vector<GridPoint>> grids;
  std::optional<JointTracker> tracker;
  if (robot) {
    tracker.emplace(*robot, seed, ik);
    tracker->set_reference(joints);
  }
  JointSample js;
  Jet jet{};
  // The joint torques' terms where the robot has them and a torque limit (time_optimal_limits).
  const bool torques = robot != nullptr && torque_limited(*robot);
  // The tool's angular rates need the orientation planned for this path (a Cartesian-only
  // caller may pass none: then omega_s = omega_ss = 0 and angular limits bind nothing).
  const bool oriented = orientation.segments.size() == path.segment_count();
  // The Cartesian state at arc length s_loc of portion p at the tracker's time t [s] (the arc
  // length travelled at s_dot = 1, s_ddot = 0), its u, and the curvature there. No allocation.
  CartesianState x;
  double u = 0.0, u_try = 0.0, kappa = 0.0;
  auto state_at = [&](std::size_t p, double s_loc, double t, bool end, CartesianState& out, double& u_out,
                      double& kappa_out) -> bool {
    const MotionPortion& por = portions[p];
    double uu = s_loc == 0.0 ? por.u_start : end ? por.u_end : parameter_at(path, por.s_start + s_loc);
    uu = std::clamp(uu, por.u_start, por.u_end);
    u_out = uu;
    const std::size_t seg =
        std::min(static_cast<std::size_t>(std::floor(uu)), static_cast<std::size_t>(por.u_end) - 1);
    evaluate(path.segments[seg], uu - static_cast<double>(seg), 2, jet);
    const double sp = jet[1].norm();
    if (!(sp > 0.0)) return false;
    const Eigen::Vector3d T = jet[1] / sp;
    const Eigen::Vector3d p_ss = (jet[2] - jet[2].dot(T) * T) / (sp * sp);  // d2p/ds2 = kappa N
    kappa_out = p_ss.norm();
    if (oriented || tracker) {
      MotionSample ms;
      ms.t = t;
      ms.u = uu;
      ms.s = por.s_start + s_loc;
      ms.segment = seg;
      ms.portion = p;
      ms.p_W = jet[0];
      ms.v_W = T;  // s_dot = 1
      ms.a_W = p_ss;
      ms.speed = 1.0;
      ms.s_ddot = 0.0;
      out = cartesian_state(path, orientation, ms);
    }
    return true;
  };
  auto no_tangent = [&](double uu) {
    return tl::make_unexpected(Violations{unattainable("motion", "the path has no tangent at u = " + number(uu, 6))});
  };
  auto ik_fails = [&](const MotionPortion& por, double s_loc, double uu) {
    return tl::make_unexpected(Violations{unattainable(
        "motion", "the IK fails at s = " + number(por.s_start + s_loc, 6) + " m (u = " + number(uu, 6) +
                      ") of the path: position error " + number(js.position_error, 6) + " m")});
  };
  double t_fake = 0.0;  // the tracker's time: arc length travelled at s_dot = 1 [s]
  for (std::size_t p = 0; p < portions.size(); ++p) {
    const MotionPortion& por = portions[p];
    const double h = por.length / static_cast<double>(grid_intervals);
    std::vector<GridPoint> grid(grid_intervals + 1);
    for (std::size_t k = 0; k <= grid_intervals; ++k) {
      const double s_loc = por.length * static_cast<double>(k) / static_cast<double>(grid_intervals);
      if (!state_at(p, s_loc, t_fake, k == grid_intervals, x, u, kappa)) return no_tangent(u);
      GridPoint& g = grid[k];
      g.s = s_loc;
      g.kappa = kappa;
      g.omega_s = x.omega_WT;   // at s_dot = 1 (zero when not oriented)
      g.omega_ss = x.alpha_WT;  // at s_ddot = 0
      if (tracker) {
        // The continuation of the samples (JointTracker::follow, ContinuationRule): the step
        // from the last grid point, walked in smaller steps where it does not converge or
        // leaves its branch, as a sampler slow enough to follow the path would have tracked
        // it. The first point of a portion is the rest where the last one ended (a tiny
        // step: the tangent may invert), tracked in one step. The tracker's time runs with
        // the arc length (t_fake): a state between is at s_loc - (t_fake - t).
        bool tangent = true;
        auto between = cartesian_source([&](double t, CartesianState& out) {
          double kappa_between = 0.0;
          tangent = state_at(p, s_loc - (t_fake - t), t, false, out, u_try, kappa_between);
          return tangent;
        });
        const FollowResult r = k == 0 ? FollowResult{tracker->track(x, js), 0, false, t_fake}
                                      : tracker->follow(x, between, js, kGridContinuation);
        if (!r.converged) {
          if (!tangent) return no_tangent(u_try);
          const bool at_point = !(r.t_failed < t_fake);
          return ik_fails(por, at_point ? s_loc : s_loc - (t_fake - r.t_failed), at_point ? u : u_try);
        }
        g.q_s = js.q_dot;    // dq/ds at s_dot = 1
        g.q_ss = js.q_ddot;  // d2q/ds2 at s_ddot = 0
        if (torques) set_torque_terms(*robot, js.q, g);
      }
      const double next = k < grid_intervals ? h : 1e-9;
      t_fake += next;  // a rest between portions: a tiny step (the tangent may invert)
    }
    grids.push_back(std::move(grid));
  }
  return grids;
}

Expected<MotionPlan> assemble_motion(const MotionSpec& spec, std::vector<MotionPortion> portions,
                                     const std::vector<SpeedProfile>& profiles) {
  GEOTRAJ_CHECK(portions.size() == profiles.size());
  MotionPlan plan;
  plan.spec = spec;
  double t = 0.0;
  for (std::size_t i = 0; i < portions.size(); ++i) {
    MotionPortion& por = portions[i];
    por.t_start = t;
    por.profile = profiles[i];
    t += por.profile.duration;
    plan.peak_speed = std::max(plan.peak_speed, peak_speed(por.profile));
    plan.peak_acceleration = std::max(plan.peak_acceleration, peak_acceleration(por.profile));
  }
  plan.portions = std::move(portions);
  plan.duration_s = t;
  if (!(t * spec.cycle_rate_hz < kMaxMotionSamples))
    return tl::make_unexpected(Violations{unattainable(
        "motion.durationS", "the time-optimal motion lasts " + number(t, 6) + " s, more samples than a stream may hold")});
  plan.sample_count = grid_sample_count(t, spec.cycle_rate_hz);
  return plan;
}

void SampleCheck::tighten(std::size_t portion, std::size_t k, double r, int order) {
  broken = true;
  auto& points = order == 3 ? jerk_shrink[portion] : shrink[portion];
  // A ratio r shrinks sigma by 1 / r^2 for a velocity, 1 / r for an acceleration (and a
  // torque's part beyond gravity), and the jerk limit by 1 / r^2: twice the correction that
  // would remove the excess where it was measured, since the limits of neighbouring samples
  // move too, and the loop settles in fewer rounds.
  const double f = (order == 2 || order == 4 ? 1.0 / r : 1.0 / (r * r)) * (1.0 - 1e-6);
  // A jerk comes from the acceleration's change across a grid point and the estimated third
  // derivative of the joint path there: the points around the interval tighten too.
  const std::size_t N = points.size() - 1;
  const std::size_t lo = order == 3 && k > 0 ? k - 1 : k, hi = order == 3 ? std::min(N, k + 2) : k + 1;
  for (std::size_t i = lo; i <= hi; ++i) points[i] = std::min(points[i], f);
}

Expected<SampleCheck> check_time_optimal_samples(const Path& path, const OrientationPlan& orientation,
                                                 const MotionPlan& motion,
                                                 const std::vector<std::vector<GridPoint>>& grids,
                                                 const TimeOptimalLimits& limits, const RobotModel* robot,
                                                 const JointVector& seed, const TimeOptimalOptions& options) {
  GEOTRAJ_CHECK(grids.size() == motion.portions.size());
  SampleCheck out;
  out.shrink.resize(grids.size());
  out.jerk_shrink.resize(grids.size());
  for (std::size_t p = 0; p < grids.size(); ++p) {
    out.shrink[p].assign(grids[p].size(), 1.0);
    out.jerk_shrink[p].assign(grids[p].size(), 1.0);
  }
  const bool joint_jerk = limits.joint_jerk.size() > 0 &&
                          (limits.joint_jerk.array() < kInf).any();
  const bool path_jerk = limits.jerk < kInf;
  const bool angular = limits.angular_speed < kInf || limits.angular_acceleration < kInf;
  std::optional<JointTracker> tracker;
  if (robot) {
    tracker.emplace(*robot, seed, options.ik);
    tracker->set_reference(options.joints.get());
  }
  MotionSample ms;
  JointSample js;
  JointVector q_ddot_prev;
  time_optimal_detail::TorqueScratch scratch;
  const bool torques = robot != nullptr && limits.joint_torque.size() == static_cast<Eigen::Index>(robot->dof()) &&
                       has_dynamics(*robot);
  // One pass over the samples of `plan` (the motion at one rate).
  auto pass = [&](const MotionPlan& plan) -> std::optional<Violations> {
    MotionSampler sampler(path, plan);
    PathMotionSource between(path, orientation, sampler);  // the sampler at the last good sample
    if (tracker) tracker->reset(seed);
    double t_prev = 0.0, s_ddot_prev = 0.0;
    bool first = true;
    for (std::size_t n = 0; sampler.next(ms); ++n) {
      if (n % 256 == 0 && options.stop.stop_requested()) return Violations{{"motion", "stopped: the call was cancelled"}};
      const MotionPortion& por = plan.portions[ms.portion];
      const std::size_t N = grids[ms.portion].size() - 1;
      const double h = por.length / static_cast<double>(N);
      const std::size_t k =
          h > 0.0 ? std::min(N - 1, static_cast<std::size_t>(std::max(0.0, (ms.s - por.s_start) / h))) : 0;
      // An excess tightens the grid around it (SampleCheck::tighten). `ratio` (where >= 0): the
      // usage, when it is not value / limit (a torque's: its part beyond gravity's,
      // dynamic_torque_usage, scales as an acceleration).
      auto note = [&](double value, double limit, int order, Eigen::Index joint = -1, const char* what = nullptr,
                      double ratio = -1.0) {
        if (!(limit < kInf)) return;
        const double r = ratio >= 0.0 ? ratio : value / limit;
        if (r > out.worst_usage) {
          static constexpr const char* kKind[] = {"", "velocity", "acceleration", "jerk", "torque"};
          static constexpr const char* kUnit[] = {"", "rad/s", "rad/s^2", "rad/s^3", "N m"};
          out.worst_usage = r;
          out.worst = (joint >= 0 ? "joint " + std::to_string(joint) + " " + kKind[order] + " " + number(value, 6) +
                                        " of " + number(limit, 6) + " " + kUnit[order]
                       : what != nullptr ? std::string(what) + " " + number(value, 6) + " of " + number(limit, 6)
                                  : std::string(order == 2 ? "centripetal acceleration " : "path jerk ") +
                                        number(value, 6) + " of " + number(limit, 6) + (order == 2 ? " m/s^2" : " m/s^3")) +
                      " at t = " + number(ms.t, 6) + " s (s = " + number(ms.s, 6) + " m, " +
                      number(plan.spec.cycle_rate_hz, 6) + " Hz)";
        }
        if (r > 1.0 + options.sample_tolerance) out.tighten(ms.portion, k, r, order);
      };
      const double dt = ms.t - t_prev;
      if (ms.speed > 0.0) {
        const Eigen::Vector3d T = ms.v_W / ms.speed;
        note((ms.a_W - ms.a_W.dot(T) * T).norm(), limits.centripetal, 2);
      }
      if (path_jerk && !first && dt > 0.0) note(std::abs(ms.s_ddot - s_ddot_prev) / dt, limits.jerk, 3);
      if (angular && orientation.segments.size() == path.segment_count()) {
        const CartesianState x = cartesian_state(path, orientation, ms);
        note(x.omega_WT.norm(), limits.angular_speed, 1, -1, "tool angular speed [rad/s]");
        note(x.alpha_WT.norm(), limits.angular_acceleration, 2, -1, "tool angular acceleration [rad/s^2]");
      }
      if (tracker) {
        const CartesianState x = cartesian_state(path, orientation, ms);
        // The continuation of the samples (JointTracker::follow), as they stream.
        if (const FollowResult r = tracker->follow(x, between, js, kSampleContinuation); !r.converged)
          return Violations{unattainable("motion", "the IK fails at t = " + number(r.t_failed, 6) +
                                                       " s (on the way to s = " + number(ms.s, 6) +
                                                       " m, u = " + number(ms.u, 6) + ")")};
        between.mark(sampler);
        for (Eigen::Index j = 0; j < js.q_dot.size(); ++j) {
          note(std::abs(js.q_dot(j)), limits.joint_velocity(j), 1, j);
          note(std::abs(js.q_ddot(j)), limits.joint_acceleration(j), 2, j);
          if (joint_jerk && !first && dt > 0.0)
            note(std::abs(js.q_ddot(j) - q_ddot_prev(j)) / dt, limits.joint_jerk(j), 3, j);
        }
        // Torques: screened by the grid's terms, exact near a limit.
        if (torques) {
          const std::vector<GridPoint>& grid = grids[ms.portion];
          const double within =
              h > 0.0 ? std::clamp((ms.s - por.s_start) / h - static_cast<double>(k), 0.0, 1.0) : 0.0;
          Eigen::Index joint = -1;
          double load = 0.0;
          const auto torque = [&](double value, double limit, Eigen::Index j, double ratio) {
            note(value, limit, 4, j, nullptr, ratio);
          };
          if (!time_optimal_detail::check_torques(*robot, js.q, js.q_dot, js.q_ddot, grid[k], grid[k + 1], within,
                                                  ms.s_ddot, ms.speed * ms.speed, limits, scratch, torque, joint, load))
            return Violations{gravity_beyond(joint, load, limits.joint_torque(joint), ms.t, ms.s)};
        }
        q_ddot_prev = js.q_ddot;
      }
      t_prev = ms.t, s_ddot_prev = ms.s_ddot, first = false;
    }
    return std::nullopt;
  };
  if (auto failed = pass(motion)) return tl::make_unexpected(std::move(*failed));
  out.check_rate_hz = motion.spec.cycle_rate_hz;
  if (out.broken) return out;
  // The check rate: a multiple of the cycle rate, within max_check_samples.
  const double f = motion.spec.cycle_rate_hz;
  double multiple = options.check_rate_hz > f ? std::ceil(options.check_rate_hz / f * (1.0 - 1e-12)) : 1.0;
  const double budget = static_cast<double>(options.max_check_samples) / std::max(1.0, motion.duration_s * f);
  multiple = std::min(multiple, std::max(1.0, std::floor(budget)));
  if (multiple > 1.0) {
    MotionPlan fine = motion;
    fine.spec.cycle_rate_hz = f * multiple;
    fine.sample_count = grid_sample_count(fine.duration_s, fine.spec.cycle_rate_hz);
    if (auto failed = pass(fine)) return tl::make_unexpected(std::move(*failed));
    out.check_rate_hz = fine.spec.cycle_rate_hz;
  }
  return out;
}

void tighten_limits(const SampleCheck& check, int round, int uniform_from, std::vector<std::vector<double>>& sigma,
                    std::vector<std::vector<double>>* jerk_sigma) {
  const double uniform = round >= uniform_from && check.worst_usage > 1.0 ? (1.0 / check.worst_usage) * (1.0 - 1e-6) : 1.0;
  for (std::size_t p = 0; p < sigma.size(); ++p) {
    for (std::size_t i = 0; i < sigma[p].size(); ++i) {
      sigma[p][i] *= check.shrink[p][i] * uniform;
      if (jerk_sigma != nullptr) (*jerk_sigma)[p][i] *= check.jerk_shrink[p][i] * uniform * uniform * uniform;
    }
  }
}

Expected<TimeOptimalPlan> plan_time_optimal(const Path& path, const OrientationPlan& orientation,
                                            const MotionSpec& spec, const RobotModel* robot,
                                            const JointVector& seed, const TimeOptimalOptions& options) {
  // The time is the result: durationS's rules do not apply.
  if (auto v = validate_motion(spec, MotionTiming::kLimits); !v.empty()) return tl::make_unexpected(v);
  if (!robot && !spec.max_acceleration)
    return tl::make_unexpected(
        Violations{{"motion.maxAcceleration", "is needed for a time-optimal motion without a robot"}});
  if (options.grid_intervals < 2)
    return tl::make_unexpected(Violations{{"motion", "a time-optimal grid needs at least 2 intervals"}});
  // The portions between rests, as a motion of any duration has them (its timing unused).
  MotionSpec any_time = spec;
  any_time.duration_s = 1.0;
  any_time.profile = ProfileShape::kTrapezoidal;
  any_time.ramp_time_s.reset();
  auto portions_plan = plan_motion(path, any_time);
  if (!portions_plan) return tl::make_unexpected(portions_plan.error());

  GEOTRAJ_CHECK(!options.joints || (robot != nullptr && options.joints->over() == ReferenceParameter::kArcLength &&
                                     options.joints->samples().front().size() == seed.size()));
  auto grids = time_optimal_grids(path, orientation, portions_plan->portions, robot, seed, options.grid_intervals,
                                  options.ik, options.joints.get());
  if (!grids) return tl::make_unexpected(grids.error());

  TimeOptimalPlan out;
  out.limits = time_optimal_limits(spec, robot);
  out.grids = std::move(*grids);
  const std::size_t P = out.grids.size();
  std::vector<std::vector<double>> sigma(P);
  for (std::size_t p = 0; p < P; ++p) sigma[p].assign(out.grids[p].size(), 1.0);

  MotionSpec timed = spec;
  for (int round = 0;; ++round) {
    if (options.stop.stop_requested()) return tl::unexpected(Violations{{"motion", "stopped: the call was cancelled"}});
    out.solutions.clear();
    std::vector<SpeedProfile> profiles;
    for (std::size_t p = 0; p < P; ++p) {
      const auto& por = portions_plan->portions[p];
      auto sol = sweep(out.grids[p], out.limits, &sigma[p]);
      if (!sol) {
        Violations v = sol.error();
        for (auto& fv : v)
          fv.description += " (portion " + std::to_string(p) + ", u " + number(por.u_start, 6) + " to " + number(por.u_end, 6) +
                            ", path s from " + number(por.s_start, 6) + " m)";
        return tl::make_unexpected(v);
      }
      profiles.push_back(sol->profile);
      out.solutions.push_back(std::move(*sol));
    }
    auto motion = assemble_motion(timed, portions_plan->portions, profiles);
    if (!motion) return tl::make_unexpected(motion.error());
    out.motion = std::move(*motion);
    out.motion.spec.duration_s = 0.0;
    out.refinements = round;
    if (!options.verify_samples) break;

    auto check =
        check_time_optimal_samples(path, orientation, out.motion, out.grids, out.limits, robot, seed, options);
    if (!check) return tl::make_unexpected(check.error());
    out.worst_sample_usage = check->worst_usage;
    out.check_rate_hz = check->check_rate_hz;
    if (!check->broken) break;
    if (round >= options.max_refinements)
      return tl::make_unexpected(Violations{
          unattainable("motion", "the sampled motion still exceeds a limit by " +
                                     number(100.0 * (out.worst_sample_usage - 1.0), 6) + " % after " +
                                     std::to_string(round) + " refinements (" + check->worst +
                                     "): use a finer grid")});
    tighten_limits(*check, round, options.uniform_refinement_from, sigma, nullptr);
  }

  // The grid error of the duration: the same limits on every second grid point.
  double half_duration = 0.0;
  for (std::size_t p = 0; p < P; ++p) {
    const std::vector<std::size_t> half = every_second_point(out.grids[p].size());
    auto sol = half.size() >= 3 ? sweep(out.grids[p], out.limits, &sigma[p], &half) : Expected<TimeOptimalSolution>();
    half_duration = half.size() >= 3 && sol ? half_duration + sol->duration : kInf;
  }
  out.duration_grid_error = std::isfinite(half_duration)
                                ? std::abs(half_duration - out.motion.duration_s)
                                : 0.0;
  for (std::size_t p = 0; p < P; ++p) {
    const MotionPortion& por = out.motion.portions[p];
    for (BindingStretch st : out.solutions[p].binding) {
      st.portion = p;
      st.s_start += por.s_start;
      st.s_end += por.s_start;
      st.t_start += por.t_start;
      st.t_end += por.t_start;
      out.binding.push_back(st);
    }
  }
  return out;
}

}  // namespace geotraj::core
