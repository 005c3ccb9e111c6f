// PlanRequest.optimize on the wire (convert.hpp): the optimisers' options and reports.
#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include "core/format.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

// --- optimisation --------------------------------------------------------------------------

namespace {

v1::OptimizerStatus to_proto(optim::OptimizerStatus status) {
  switch (status) {
    case optim::OptimizerStatus::kConverged: return v1::OPTIMIZER_STATUS_CONVERGED;
    case optim::OptimizerStatus::kIterationLimit: return v1::OPTIMIZER_STATUS_ITERATION_LIMIT;
    case optim::OptimizerStatus::kTimeLimit: return v1::OPTIMIZER_STATUS_TIME_LIMIT;
    case optim::OptimizerStatus::kNoImprovement: return v1::OPTIMIZER_STATUS_NO_IMPROVEMENT;
    case optim::OptimizerStatus::kFailed: return v1::OPTIMIZER_STATUS_FAILED;
  }
  return v1::OPTIMIZER_STATUS_UNSPECIFIED;
}

// The fields every optimiser report has.
template <class Report>
void set_report(const optim::OptimizerReport& r, Report& out) {
  out.set_objective_before(r.objective_before);
  out.set_objective_after(r.objective_after);
  out.set_iterations(static_cast<std::uint32_t>(std::max(r.iterations, 0)));
  out.set_status(to_proto(r.status));
  out.set_seconds(r.seconds);
  out.set_message(r.message);
}

}  // namespace

core::Expected<double> optimize_budget(const v1::PlanRequest& request, double max_seconds) {
  const auto& o = request.optimize();
  if (!o.has_time_budget_s()) return std::min(kDefaultOptimizeBudgetS, max_seconds);
  if (!(std::isfinite(o.time_budget_s()) && o.time_budget_s() > 0.0)) {
    return tl::unexpected(
        core::Violations{{"optimize.timeBudgetS", "must be a finite time > 0 s when given, got " + core::number(o.time_budget_s(), 6)}});
  }
  if (o.time_budget_s() > max_seconds) {
    return tl::unexpected(core::Violations{{"optimize.timeBudgetS", "asks for " + core::number(o.time_budget_s(), 6) +
                                                                        " s; this server allows at most " +
                                                                        core::number(max_seconds, 6) +
                                                                        " s per call (geotrajd --max-optimize-seconds)"}});
  }
  return o.time_budget_s();
}

core::Expected<optim::TangentScaleOptions> tangent_scale_options(const v1::PlanRequest& request) {
  const auto& t = request.optimize().tangent_scales();
  WireCheck check;
  check_enum(check, "optimize.tangentScales.objective", t.objective(), v1::TangentScaleObjective_descriptor());
  if (!check.violations.empty()) return tl::unexpected(std::move(check.violations));
  optim::TangentScaleOptions options;
  switch (t.objective()) {
    case v1::TANGENT_SCALE_OBJECTIVE_PEAK_CURVATURE: options.objective = optim::TangentScaleObjective::kPeakCurvature; break;
    case v1::TANGENT_SCALE_OBJECTIVE_PEAK_TORSION: options.objective = optim::TangentScaleObjective::kPeakTorsion; break;
    case v1::TANGENT_SCALE_OBJECTIVE_ARC_LENGTH: options.objective = optim::TangentScaleObjective::kArcLength; break;
    default: options.objective = optim::TangentScaleObjective::kBendingEnergy; break;  // BENDING_ENERGY, UNSPECIFIED
  }
  if (t.has_min_scale()) options.min_scale = t.min_scale();
  if (t.has_max_scale()) options.max_scale = t.max_scale();
  if (t.has_length_weight()) options.length_weight = t.length_weight();
  return options;  // ranges: optim::optimize_tangent_scales names them
}

core::Expected<optim::BreakpointOptions> breakpoint_options(const v1::PlanRequest& request) {
  const auto& b = request.optimize().breakpoints();
  WireCheck check;
  check_enum(check, "optimize.breakpoints.objective", b.objective(), v1::BreakpointObjective_descriptor());
  if (!check.violations.empty()) return tl::unexpected(std::move(check.violations));
  optim::BreakpointOptions options;
  switch (b.objective()) {
    case v1::BREAKPOINT_OBJECTIVE_PEAK_CURVATURE: options.objective = optim::BreakpointObjective::kPeakCurvature; break;
    case v1::BREAKPOINT_OBJECTIVE_PEAK_DERIVATIVES: options.objective = optim::BreakpointObjective::kPeakDerivatives; break;
    default: options.objective = optim::BreakpointObjective::kPeakTorsion; break;  // PEAK_TORSION, UNSPECIFIED
  }
  return options;
}

planner::OptimizeInput wire_detail::optimize_input(const v1::PlanRequest& request, const ServiceLimits& limits,
                                                   core::Violations& out) {
  const auto& o = request.optimize();
  planner::OptimizeInput in;
  if (auto budget = optimize_budget(request, limits.max_optimize_seconds)) {
    in.values.budget_s = *budget;
  } else {
    out = joined(std::move(out), budget.error());
  }
  if (o.has_tangent_scales()) {
    in.tangent_scales = true;
    auto options = tangent_scale_options(request);
    if (options) in.values.tangent_scales = std::move(*options);
    else out = joined(std::move(out), options.error());
  }
  if (o.has_breakpoints()) {
    in.breakpoints = true;
    auto options = breakpoint_options(request);
    if (options) in.values.breakpoints = std::move(*options);
    else out = joined(std::move(out), options.error());
  }
  in.values.time_optimal = o.timing().time_optimal();
  in.values.jerk_limited = o.timing().jerk_limited();
  if (o.has_redundancy()) {  // checked by the planner (admit)
    const auto& r = o.redundancy();
    in.values.redundancy = optim::RedundancyWeights{r.joint_range_weight(), r.velocity_weight(),
                                                    r.acceleration_weight(), r.jerk_weight(),
                                                    r.manipulability_weight()};
  }
  return in;
}

void to_proto(const optim::OptimizerReport& report, v1::RedundancyReport& out) { set_report(report, out); }

void to_proto(const optim::TangentScaleResult& result, v1::TangentScaleReport& out) {
  set_report(result.report, out);
  for (double scale : result.scales) out.add_tangent_scales(scale);
  out.set_length_weight(result.length_weight);
}

void to_proto(const planner::TimingReport& report, v1::TimingReport& out) {
  set_report(report.report, out);
  for (const auto& b : report.binding) to_proto(b, *out.add_binding());
  out.set_check_rate_hz(report.check_rate_hz);
  out.set_worst_limit_usage(report.worst_limit_usage);
  out.set_refinements(static_cast<std::uint32_t>(std::max(0, report.refinements)));
  out.set_duration_grid_error_s(report.duration_grid_error_s);
}

void to_proto(const optim::BreakpointResult& result, v1::BreakpointReport& out) {
  set_report(result.report, out);
  for (const auto& b : result.breakpoints) {
    auto* seg = out.add_breakpoints();
    seg->set_segment(b.segment);
    for (double x : b.all) seg->add_all(x);
    for (double x : b.x) seg->add_x(x);
    for (double x : b.y) seg->add_y(x);
    for (double x : b.z) seg->add_z(x);
  }
}

}  // namespace geotraj::server
