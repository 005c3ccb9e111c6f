// The jerk-limited timing's drivers (time_optimal_jerk.hpp): one portion's solve (the banded
// interior point method, Ipopt when it does not converge) and the plan with its sample check.
#include "optim/timing/time_optimal_jerk.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <IpIpoptApplication.hpp>
#include <IpSolveStatistics.hpp>

#include "core/format.hpp"
#include "optim/common/ipopt_lock.hpp"
#include "optim/timing/banded_ipm.hpp"
#include "optim/timing/jerk_timing_nlp.hpp"

namespace geotraj::optim {

namespace {

using detail::JerkTimingNlp;
constexpr double kInf = std::numeric_limits<double>::infinity();

/// The profile of b: one constant-acceleration piece per interval with its exact time.
core::SpeedProfile profile_of(const std::vector<core::GridPoint>& grid, const std::vector<double>& b,
                              std::vector<double>& u, std::vector<double>& dt) {
  core::SpeedProfile p;
  const std::size_t N = grid.size() - 1;
  u.assign(N, 0.0);
  dt.assign(N, 0.0);
  double t = 0.0;
  for (std::size_t i = 0; i < N; ++i) {
    const double ds = grid[i + 1].s - grid[i].s, v0 = std::sqrt(b[i]), v1 = std::sqrt(b[i + 1]);
    u[i] = (b[i + 1] - b[i]) / (2.0 * ds);
    dt[i] = 2.0 * ds / (v0 + v1);
    p.pieces.push_back({t, grid[i].s, v0, u[i], 0.0});
    t += dt[i];
  }
  p.duration = t;
  p.length = grid.back().s;
  return p;
}

}  // namespace

JerkTiming optimise_jerk_timing(const std::vector<core::GridPoint>& grid, const core::TimeOptimalLimits& limits,
                                const core::TimeOptimalSolution& start, const JerkTimingOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n_pts = grid.size(), N = n_pts - 1;
  GEOTRAJ_CHECK(n_pts >= 3 && start.b.size() == n_pts && start.u.size() == N);

  GEOTRAJ_CHECK(options.limit_scale.empty() || options.limit_scale.size() == n_pts);
  GEOTRAJ_CHECK(options.jerk_scale.empty() || options.jerk_scale.size() == n_pts);
  GEOTRAJ_CHECK(options.start_scale > 0.0 && options.start_scale <= 1.0);
  // The start: `start`'s b times start_scale, off zero (the sweep may stop at an interior
  // point, b_i = 0, where sqrt(b) has no derivative). The scaled profile is the same motion,
  // slower: its velocities scale by sqrt(c), accelerations by c and jerks by c^(3/2), so it is
  // strictly inside every limit the start meets, and an interior point method starts well
  // from there (from the sweep's b itself, on dozens of active limits, Ipopt needed 100
  // iterations of tiny steps).
  std::vector<double> x_start(start.b.begin() + 1, start.b.end() - 1);
  const double b_floor = 1e-8 * std::max(1e-300, *std::max_element(x_start.begin(), x_start.end()));
  for (double& b : x_start) b = std::max(b, b_floor);
  std::vector<double> x0 = x_start;
  for (double& b : x0) b *= options.start_scale;
  JerkTiming out;

  Ipopt::SmartPtr<JerkTimingNlp> nlp = new JerkTimingNlp(grid, limits, options);
  out.report.objective_before = nlp->objective(x_start.data());

  nlp->x0_ = x0;

  // The banded interior point method first (unless Ipopt is asked for), Ipopt when it does
  // not converge; the deadline is shared.
  const auto deadline = t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                 std::chrono::duration<double>(std::max(0.0, options.time_budget_s)));
  bool run_ipopt = options.solver == JerkSolver::kIpopt || options.derivative_test;
  std::string prefix;
  if (!run_ipopt) {
    detail::BandedIpmOptions bo;
    bo.tol = options.tolerance;
    bo.constr_viol_tol = 1e-9;  // as Ipopt's below
    bo.max_iterations = options.max_iterations;
    bo.deadline = deadline;
    bo.stop = options.stop;
    const detail::BandedIpmResult r = detail::solve_banded_ipm(*nlp, bo);
    out.report.iterations = r.iterations;
    switch (r.status) {
      case detail::BandedIpmResult::Status::kConverged: out.report.status = OptimizerStatus::kConverged; break;
      case detail::BandedIpmResult::Status::kIterationLimit: out.report.status = OptimizerStatus::kIterationLimit; break;
      case detail::BandedIpmResult::Status::kTimeLimit: out.report.status = OptimizerStatus::kTimeLimit; break;
      case detail::BandedIpmResult::Status::kFailed: out.report.status = OptimizerStatus::kFailed; break;
    }
    out.report.message = "banded interior point: " + r.message + " after " + std::to_string(r.iterations) +
                         " iterations";
    nlp->x_ = r.x;
    if (options.solver == JerkSolver::kAuto && n_pts <= kIpoptFallbackMaxPoints &&
        (out.report.status == OptimizerStatus::kFailed || out.report.status == OptimizerStatus::kIterationLimit)) {
      run_ipopt = true;
      prefix = out.report.message + "; then ";
    }
  }
  // Held until the application is destroyed, at the end of this block (ipopt_lock.hpp).
  std::unique_lock<std::timed_mutex> ipopt;
  if (run_ipopt) {
    ipopt = detail::lock_ipopt(deadline, options.stop);
    if (!ipopt.owns_lock()) {
      run_ipopt = false;
      nlp->x_.clear();
      out.report.status = OptimizerStatus::kTimeLimit;
      out.report.message = prefix + "the time ran out while another optimisation held Ipopt";
    }
  }
  if (run_ipopt) {
    nlp->x_.clear();
    Ipopt::SmartPtr<Ipopt::IpoptApplication> app = IpoptApplicationFactory();
    Ipopt::OptionsList& o = *app->Options();
    o.SetIntegerValue("print_level", options.derivative_test ? 5 : 0);
    if (!options.derivative_test) o.SetStringValue("sb", "yes");
    o.SetNumericValue("tol", options.tolerance);
    o.SetNumericValue("acceptable_tol", 1e3 * options.tolerance);
    // Adaptive barrier. Mehrotra's predictor-corrector was measured and not taken: half the
    // iterations on a synthetic grid, ten times as many on the PA-10 (the jerk rows are not
    // convex).
    o.SetStringValue("mu_strategy", "adaptive");
    // MUMPS (Debian's only solver) with AMD ordering: the KKT matrix is banded, and AMD's
    // ordering factors it fastest here (against METIS, PORD and MUMPS's automatic choice).
    o.SetIntegerValue("mumps_pivot_order", 0);
    o.SetNumericValue("constr_viol_tol", 1e-9);
    // Ipopt relaxes every bound by 1e-8 relative by default; the jerk rows then end up to
    // 2e-5 relative beyond their limits (the straight-line test). 1e-10 keeps them to 1e-6.
    o.SetNumericValue("bound_relax_factor", 1e-10);
    if (options.derivative_test) {
      o.SetStringValue("derivative_test", "second-order");
      o.SetNumericValue("derivative_test_perturbation", 1e-8);
      o.SetNumericValue("derivative_test_tol", 1e-4);
    }

    o.SetIntegerValue("max_iter", options.max_iterations);
    const double left = options.time_budget_s - std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    o.SetNumericValue("max_cpu_time", std::max(1e-6, left));

    // No options file: a stray ipopt.opt in the working directory must not change the result.
    Ipopt::ApplicationReturnStatus status = app->Initialize("");
    if (status == Ipopt::Solve_Succeeded) status = app->OptimizeTNLP(nlp);
    if (Ipopt::SmartPtr<Ipopt::SolveStatistics> stats = app->Statistics(); Ipopt::IsValid(stats))
      out.report.iterations += stats->IterationCount();

    switch (status) {
      case Ipopt::Solve_Succeeded:
      case Ipopt::Solved_To_Acceptable_Level: out.report.status = OptimizerStatus::kConverged; break;
      case Ipopt::Maximum_Iterations_Exceeded: out.report.status = OptimizerStatus::kIterationLimit; break;
      case Ipopt::User_Requested_Stop:  // cancelled
      case Ipopt::Maximum_CpuTime_Exceeded: out.report.status = OptimizerStatus::kTimeLimit; break;
      default: out.report.status = OptimizerStatus::kFailed; break;
    }
    out.report.message = prefix + "Ipopt return status " + std::to_string(static_cast<int>(status));
  }
  if (ipopt.owns_lock()) ipopt.unlock();  // the application is gone with its block
  out.report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const bool have_point = nlp->x_.size() == x0.size() && out.report.status != OptimizerStatus::kFailed &&
                          std::all_of(nlp->x_.begin(), nlp->x_.end(), [](double b) { return b > 0.0; });
  if (!have_point) out.report.status = OptimizerStatus::kFailed;
  const std::vector<double>& xs = have_point ? nlp->x_ : x_start;
  out.b.assign(n_pts, 0.0);
  std::copy(xs.begin(), xs.end(), out.b.begin() + 1);
  out.profile = profile_of(grid, out.b, out.u, out.dt);
  // The acceleration steps at the grid points ramped over the NLP's tau (zero at the rests).
  if (auto smooth = core::continuous_acceleration_profile(out.dt, out.u, grid.back().s)) {
    out.profile = std::move(*smooth);
  } else {
    out.report.status = OptimizerStatus::kFailed;
    out.report.message += "; " + smooth.error().front().description;
  }
  out.jerk = nlp->jerk(xs.data());
  out.duration = out.profile.duration;
  out.jerk_rows = nlp->n_jerk_rows();
  out.implied_jerk_rows = nlp->n_implied();
  out.max_constraint_violation = have_point ? nlp->full_violation(xs.data()) : 0.0;
  out.report.objective_after = have_point ? nlp->objective(xs.data()) : out.report.objective_before;
  if (have_point && out.report.status != OptimizerStatus::kConverged)
    out.report.message += ", largest constraint violation " + core::number(out.max_constraint_violation, 6);
  return out;
}

core::Expected<JerkRounds> jerk_limited_rounds(const std::vector<std::vector<core::GridPoint>>& grids,
                                               const std::vector<core::TimeOptimalSolution>& exact,
                                               const core::TimeOptimalLimits& exact_limits, JerkTimingOptions options,
                                               const std::stop_token& exact_stop, const JerkRoundHooks& hooks) {
  JerkRounds out;
  out.report.status = OptimizerStatus::kConverged;
  const double budget = options.time_budget_s;
  const auto t0 = std::chrono::steady_clock::now();
  // The NLP meets its limits to Ipopt's tolerance, not exactly: it works within limits
  // shrunk by kJerkLimitMargin, so that the samples stay within the real ones.
  core::TimeOptimalLimits limits = exact_limits;
  limits.joint_velocity *= 1.0 - kJerkLimitMargin;
  limits.joint_acceleration *= 1.0 - kJerkLimitMargin;
  limits.speed *= 1.0 - kJerkLimitMargin;
  limits.tangential *= 1.0 - kJerkLimitMargin;
  limits.centripetal *= 1.0 - kJerkLimitMargin;
  // The sample check is against the real jerk limits (`checked`, below).
  const core::JointVector joint_jerk = options.joint_jerk;
  const std::optional<double> max_jerk = options.max_jerk;
  options.joint_jerk *= 1.0 - kJerkLimitMargin;
  if (options.max_jerk) *options.max_jerk *= 1.0 - kJerkLimitMargin;
  const std::size_t P = grids.size();
  std::vector<std::vector<double>> sigma(P), jerk_sigma(P);
  for (std::size_t p = 0; p < P; ++p) {
    sigma[p].assign(grids[p].size(), 1.0);
    jerk_sigma[p].assign(grids[p].size(), 1.0);
  }
  // The samples are checked against every limit, the jerk included.
  core::TimeOptimalLimits checked = exact_limits;
  checked.joint_jerk = joint_jerk;
  if (max_jerk) checked.jerk = *max_jerk;
  // The starts: the exact sweep's b (within the margin), then each round's result.
  std::vector<core::TimeOptimalSolution> starts = exact;
  for (auto& st : starts)
    for (double& b : st.b) b *= (1.0 - kJerkLimitMargin) * (1.0 - kJerkLimitMargin);
  const double first_scale = options.start_scale;
  // The call's cancellation or deadline (the token) ends the work between any two steps: a
  // degenerate limit (maxJerk 1e-10 m/s^3) makes a motion of hours whose every sample the
  // check below visits, round after round.
  const auto cancelled = [&] { return options.stop.stop_requested() || exact_stop.stop_requested(); };
  const auto stopped = [] {
    return core::Violations{{"motion", "stopped: the call was cancelled (or its deadline passed) while the "
                                       "jerk-limited timing ran"}};
  };
  for (int round = 0;; ++round) {
    if (cancelled()) return tl::make_unexpected(stopped());
    out.portions.clear();
    std::vector<core::SpeedProfile> profiles;
    for (std::size_t p = 0; p < P; ++p) {
      options.time_budget_s =
          std::max(1e-3, budget - std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      options.limit_scale = sigma[p];
      options.jerk_scale = jerk_sigma[p];
      // A re-solve starts from the last result within the tightened limits: scaled by the
      // smallest sigma^2 of the portion (velocities by sigma, accelerations by sigma^2).
      options.start_scale =
          round == 0 ? first_scale : std::pow(*std::min_element(sigma[p].begin(), sigma[p].end()), 2) * first_scale;
      JerkTiming jt = optimise_jerk_timing(grids[p], limits, starts[p], options);
      if (round == 0) out.report.objective_before += jt.report.objective_before;
      out.report.iterations += jt.report.iterations;
      if (static_cast<int>(jt.report.status) > static_cast<int>(out.report.status)) {
        out.report.status = jt.report.status;
        out.report.message = "portion " + std::to_string(p) + ": " + jt.report.message;
      }
      if (jt.report.status != OptimizerStatus::kFailed) starts[p].b = jt.b, starts[p].u = jt.u;
      profiles.push_back(jt.profile);
      out.portions.push_back(std::move(jt));
    }
    if (auto assembled = hooks.assemble(profiles); !assembled) return tl::make_unexpected(assembled.error());
    out.refinements = round;
    // Every sample at the cycle rate against the real limits, as the exact timing checks
    // the sweep's; where one breaks a limit, that interval's limits tighten and the NLP runs
    // again from its last result.
    if (cancelled()) return tl::make_unexpected(stopped());
    auto check = hooks.check(checked);
    if (!check) return tl::make_unexpected(check.error());
    out.worst_sample_usage = check->worst_usage;
    out.check_rate_hz = check->check_rate_hz;
    if (!check->broken) break;
    if (round >= options.max_refinements) {
      // Not settled: the NLP meets its limits at the grid points, and a sample between them
      // still passes one. The last result c = r times slower (r the worst usage) has every
      // velocity 1 / c, acceleration 1 / c^2 and jerk 1 / c^3 of what was sampled: within
      // every limit whatever its order, for a duration c times longer. Checked again, at the
      // check rate too (a check that fails at the cycle rate does not go on to the finer
      // rate, whose worst usage may be larger): slowed again by what that finds, at most
      // kMaxSlowDowns times.
      constexpr int kMaxSlowDowns = 3;
      double slowed_by = 1.0;
      for (int k = 0; k < kMaxSlowDowns && check->broken; ++k) {
        const double c = check->worst_usage * (1.0 + 1e-9);
        slowed_by *= c;
        std::vector<core::SpeedProfile> slower;
        for (JerkTiming& jt : out.portions) {
          jt.profile = core::time_scaled(std::move(jt.profile), c);
          jt.duration *= c;
          for (double& b : jt.b) b /= c * c;
          for (double& u : jt.u) u /= c * c;
          for (double& dt : jt.dt) dt *= c;
          for (double& j : jt.jerk) j /= c * c * c;
          slower.push_back(jt.profile);
        }
        if (auto assembled = hooks.assemble(slower); !assembled) return tl::make_unexpected(assembled.error());
        if (cancelled()) return tl::make_unexpected(stopped());
        check = hooks.check(checked);
        if (!check) return tl::make_unexpected(check.error());
      }
      if (check->broken)
        return tl::make_unexpected(core::Violations{core::unattainable(
            "motion", "the sampled jerk-limited motion still exceeds a limit by " +
                          core::number(100.0 * (check->worst_usage - 1.0), 6) + " % after " + std::to_string(round) +
                          " refinements and slowing it by " + core::number(100.0 * (slowed_by - 1.0), 6) + " % (" +
                          check->worst + "): use a finer grid")});
      out.worst_sample_usage = check->worst_usage;
      out.check_rate_hz = check->check_rate_hz;
      out.slowed_by = slowed_by;
      out.report.message += (out.report.message.empty() ? "" : "; ") + std::string("slowed by ") +
                            core::number(100.0 * (slowed_by - 1.0), 3) + " % after " + std::to_string(round) +
                            " refinements that did not settle, so that every sample is within its limits";
      break;
    }
    core::tighten_limits(*check, round, options.uniform_refinement_from, sigma, &jerk_sigma);
  }
  out.report.objective_after = 0.0;
  for (const JerkTiming& jt : out.portions) out.report.objective_after += jt.report.objective_after;
  // The grid error of the duration: the same programme, limits and tightenings on every
  // second grid point (no sample check), against the result.
  double half_duration = 0.0, duration = 0.0;
  for (const JerkTiming& jt : out.portions) duration += jt.profile.duration;
  for (std::size_t p = 0; p < P && std::isfinite(half_duration); ++p) {
    if (cancelled()) return tl::make_unexpected(stopped());
    const auto& grid = grids[p];
    std::vector<core::GridPoint> half;
    JerkTimingOptions ho = options;
    ho.limit_scale.clear();
    ho.jerk_scale.clear();
    for (const std::size_t i : core::every_second_point(grid.size())) {
      half.push_back(grid[i]);
      ho.limit_scale.push_back(sigma[p][i]);
      ho.jerk_scale.push_back(jerk_sigma[p][i]);
    }
    auto start = half.size() >= 3 ? core::solve_time_optimal(half, limits) : core::Expected<core::TimeOptimalSolution>();
    if (half.size() < 3 || !start) {
      half_duration = kInf;
      break;
    }
    ho.start_scale = std::pow(*std::min_element(ho.limit_scale.begin(), ho.limit_scale.end()), 2) * first_scale;
    ho.time_budget_s =
        std::max(1e-3, budget - std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    const JerkTiming jt = optimise_jerk_timing(half, limits, *start, ho);
    half_duration = jt.report.status == OptimizerStatus::kConverged ? half_duration + jt.duration : kInf;
  }
  out.duration_grid_error = std::isfinite(half_duration) ? std::abs(half_duration - duration) : 0.0;
  out.report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

core::Expected<JerkLimitedPlan> plan_time_optimal_jerk(const core::Path& path,
                                                       const core::OrientationPlan& orientation,
                                                       const core::MotionSpec& spec, const core::RobotModel* robot,
                                                       const core::JointVector& seed,
                                                       const core::TimeOptimalOptions& exact_options,
                                                       JerkTimingOptions options) {
  core::TimeOptimalOptions exact_stoppable = exact_options;
  if (!exact_stoppable.stop.stop_possible()) exact_stoppable.stop = options.stop;
  auto exact = core::plan_time_optimal(path, orientation, spec, robot, seed, exact_stoppable);
  if (!exact) return tl::make_unexpected(exact.error());
  const double sc = spec.speed_scale, sc3 = sc * sc * sc * spec.acceleration_scale;  // and the reserve
  if (robot && options.joint_jerk.size() == 0) {
    const auto n = static_cast<Eigen::Index>(robot->dof());
    options.joint_jerk = core::JointVector::Constant(n, kInf);
    for (Eigen::Index j = 0; j < n; ++j)
      if (const auto& mj = robot->limits[static_cast<std::size_t>(j)].max_jerk) options.joint_jerk(j) = *mj * sc3;
  }
  if (!options.max_jerk && spec.max_jerk) options.max_jerk = *spec.max_jerk * sc3;

  JerkLimitedPlan out;
  JerkRoundHooks hooks;
  hooks.assemble = [&](const std::vector<core::SpeedProfile>& profiles) -> core::Expected<void> {
    auto motion = core::assemble_motion(spec, exact->motion.portions, profiles);
    if (!motion) return tl::make_unexpected(motion.error());
    out.motion = std::move(*motion);
    out.motion.spec.duration_s = 0.0;
    return {};
  };
  // With the call's token (exact_stoppable): the check stops within 256 samples of it.
  hooks.check = [&](const core::TimeOptimalLimits& checked) {
    return core::check_time_optimal_samples(path, orientation, out.motion, exact->grids, checked, robot, seed,
                                            exact_stoppable);
  };
  auto rounds = jerk_limited_rounds(exact->grids, exact->solutions, exact->limits, std::move(options),
                                    exact_stoppable.stop, hooks);
  if (!rounds) return tl::make_unexpected(rounds.error());
  out.portions = std::move(rounds->portions);
  out.report = std::move(rounds->report);
  out.refinements = rounds->refinements;
  out.slowed_by = rounds->slowed_by;
  out.worst_sample_usage = rounds->worst_sample_usage;
  out.check_rate_hz = rounds->check_rate_hz;
  out.duration_grid_error = rounds->duration_grid_error;
  out.exact = std::move(*exact);
  return out;
}

}  // namespace geotraj::optim
