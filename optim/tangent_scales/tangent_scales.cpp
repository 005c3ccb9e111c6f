// The tangent-scale optimiser's driver (tangent_scales.hpp): the problem, the solver of its
// reading, the verification of the solver's points; the objective and its gradient at a point.
#include "optim/tangent_scales/tangent_scales.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/geometry/constraints.hpp"
#include "optim/common/ipopt_lock.hpp"
#include "optim/tangent_scales/tangent_scales_detail.hpp"

namespace geotraj::optim {

using namespace tangent_scales_detail;

namespace {

// At most this many evaluated points are verified at the end (best first).
constexpr int kMaxVerifications = 8;

TangentScaleResult make_result(const core::PathSpec& raw, const Problem& pb, const std::vector<double>& scales) {
  TangentScaleResult r;
  r.spec = raw;
  r.scales = scales;
  r.length_weight = pb.length_weight;
  // One scale per frame but at cusps: a leaving scale the request gave elsewhere is replaced.
  write_scales(r.spec, pb.approach_var, pb.leave_var, scales.data());
  return r;
}

// The point to return: the solver's final point, then the other regular points it evaluated
// from the best solver objective up (ties in evaluation order), the first that passes the
// verification (regular and resolved on the fine rules) and beats the start by the fine
// measure. At most kMaxVerifications points are measured. Empty when none qualifies.
std::optional<std::pair<std::vector<double>, double>> verified_best(const Problem& pb,
                                                                    const std::vector<double>& final_scales,
                                                                    const std::vector<Candidate>& candidates,
                                                                    double start_value) {
  std::vector<const std::vector<double>*> order;
  if (!final_scales.empty()) order.push_back(&final_scales);
  std::vector<std::size_t> idx(candidates.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  std::stable_sort(idx.begin(), idx.end(),
                   [&](std::size_t a, std::size_t b) { return candidates[a].measure < candidates[b].measure; });
  for (std::size_t i : idx) order.push_back(&candidates[i].scales);
  int measured = 0;
  std::vector<const std::vector<double>*> seen;
  for (const auto* scales : order) {
    if (measured >= kMaxVerifications) break;
    if (std::any_of(seen.begin(), seen.end(), [&](const auto* s) { return *s == *scales; })) continue;
    seen.push_back(scales);
    ++measured;
    const Audit a = audit(pb, scales->data());
    if (a.regular && a.resolved && a.value < start_value) return std::make_pair(*scales, a.value);
  }
  return std::nullopt;
}

// One Ipopt solve of `options.objective` from the scales of `spec` (SLSQP on the smoothest reading).
core::Expected<TangentScaleResult> optimize_from(const core::PathSpec& spec, const TangentScaleOptions& options) {
  const auto t0 = Clock::now();
  auto problem = make_problem(spec, options);
  if (!problem) return tl::unexpected(std::move(problem.error()));
  const Problem& pb = *problem;

  Clock::time_point stop_at = options.deadline;
  if (options.budget_seconds) {
    const auto budget = std::chrono::duration<double>(std::min(*options.budget_seconds, 1e9));
    stop_at = std::min(stop_at, t0 + std::chrono::duration_cast<Clock::duration>(budget));
  }

  OptimizerReport report;
  report.objective_before = audit(pb, pb.start.data()).value;
  const auto finish = [&](const std::vector<double>& scales, double objective) {
    report.objective_after = objective;
    report.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    TangentScaleResult r = make_result(spec, pb, scales);
    r.report = report;
    return r;
  };
  // The solver's run: its final point or the best regular point it evaluated that passes the
  // verification (verified_best), else the start.
  const auto conclude = [&](const SolverRun& run) {
    if (report.status == OptimizerStatus::kFailed) return finish(pb.start, report.objective_before);
    const auto best = verified_best(pb, run.final_scales, run.candidates, report.objective_before);
    if (!best) {
      if (report.status != OptimizerStatus::kTimeLimit) report.status = OptimizerStatus::kNoImprovement;
      report.message += "; no regular point beats the start by the fine measure";
      return finish(pb.start, report.objective_before);
    }
    return finish(best->first, best->second);
  };

  if (!std::isfinite(report.objective_before)) {
    report.status = OptimizerStatus::kFailed;
    report.message = "the objective is not finite at the start";
    return finish(pb.start, report.objective_before);
  }
  if (Clock::now() >= stop_at || options.stop.stop_requested()) {
    report.status = OptimizerStatus::kTimeLimit;
    report.message = "no time left before the first iteration";
    return finish(pb.start, report.objective_before);
  }

  if (pb.global) return conclude(solve_slsqp(pb, stop_at, options, report));

  // Taken before solve_ipopt creates the application, so released after it is destroyed and
  // the run verified (ipopt_lock.hpp).
  const auto ipopt = detail::lock_ipopt(stop_at, options.stop);
  if (!ipopt.owns_lock()) {
    report.status = OptimizerStatus::kTimeLimit;
    report.message = "the time ran out while another optimisation held the solver";
    return finish(pb.start, report.objective_before);
  }
  return conclude(solve_ipopt(*problem, stop_at, options, report));
}

}  // namespace

core::Expected<TangentScaleResult> optimize_tangent_scales(const core::PathSpec& spec,
                                                           const TangentScaleOptions& options) {
  const bool peak = options.objective == TangentScaleObjective::kPeakCurvature ||
                    options.objective == TangentScaleObjective::kPeakTorsion;
  if (!peak) return optimize_from(spec, options);
  // The peak objectives are rugged (a soft maximum over samples): from the request's scales
  // Ipopt may stop in a poor local optimum (thesis path C, peak curvature: 188 1/m). The
  // bending-energy optimum, a smooth and well-conditioned problem, is a far better start
  // (path C: 20.0 1/m). Both solves share the deadline; the result is never worse than the
  // request, and when the warm start does not beat it, the direct solve runs as before.
  const auto t0 = Clock::now();
  TangentScaleOptions smooth = options;
  smooth.objective = TangentScaleObjective::kBendingEnergy;  // with the request's length weight, or the default
  auto first = optimize_from(spec, smooth);
  if (!first) return first;
  const auto before = tangent_scale_objective(spec, options);
  if (!before) return tl::unexpected(before.error());
  if (first->report.status == OptimizerStatus::kConverged) {
    auto second = optimize_from(first->spec, options);
    if (!second) return second;
    if (second->report.objective_after < *before) {
      second->report.objective_before = *before;
      second->report.iterations += first->report.iterations;
      second->report.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      if (second->report.status == OptimizerStatus::kNoImprovement) {
        second->report.status = OptimizerStatus::kConverged;  // the bending optimum itself is the answer
      }
      second->report.message = "from the bending-energy optimum (" + std::to_string(first->report.iterations) +
                               " iterations); " + second->report.message;
      return second;
    }
  }
  auto direct = optimize_from(spec, options);
  if (direct) direct->report.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return direct;
}

core::Expected<double> tangent_scale_objective(const core::PathSpec& spec, const TangentScaleOptions& options) {
  auto problem = make_problem(spec, options);
  if (!problem) return tl::unexpected(std::move(problem.error()));
  std::vector<double> scales;
  for (std::size_t i = 0; i < problem->spec.frames.size(); ++i) {
    const auto& f = problem->spec.frames[i];
    scales.push_back(core::side_scale(f, false));
    if (problem->leave_var[i] != problem->approach_var[i]) scales.push_back(core::side_scale(f, true));
  }
  if (problem->global) {
    GlobalEvaluation ev;
    std::vector<ControlPoints<double>> points;
    evaluate_global(*problem, scales.data(), ev, 0.0, points);
    if (!ev.ok) {
      return tl::unexpected(core::Violations{{"path", "the smoothest solve at these tangent scales is singular"}});
    }
    return problem->peak() ? std::sqrt(ev.largest) : ev.f;
  }
  Evaluation ev;
  evaluate(*problem, scales.data(), ev);
  return reported(*problem, ev);
}

core::Expected<ObjectiveGradient> tangent_scale_gradient(const core::PathSpec& spec, const std::vector<double>& scales,
                                                         const TangentScaleOptions& options) {
  auto problem = make_problem(spec, options);
  if (!problem) return tl::unexpected(std::move(problem.error()));
  const Problem& pb = *problem;
  if (scales.size() != static_cast<std::size_t>(pb.scale_count)) {
    return tl::unexpected(core::Violations{{"scales", "expected " + std::to_string(pb.scale_count) + " scales, got " +
                                                          std::to_string(scales.size())}});
  }
  if (pb.global) {
    // Central differences in ln(scale) of the value (see GlobalSolver).
    const auto value_at = [&](const std::vector<double>& at, double& v) {
      GlobalEvaluation ev;
      std::vector<ControlPoints<double>> points;
      evaluate_global(pb, at.data(), ev, 0.0, points);
      v = pb.peak() ? ev.largest : ev.f;
      return ev.ok;
    };
    ObjectiveGradient out;
    if (!value_at(scales, out.value)) {
      return tl::unexpected(core::Violations{{"path", "the smoothest solve at these tangent scales is singular"}});
    }
    out.gradient.assign(pb.scale_count, 0.0);
    std::vector<double> probe = scales;
    for (int k = 0; k < pb.scale_count; ++k) {
      double plus = 0.0, minus = 0.0;
      probe[k] = scales[k] * std::exp(kDifferenceStep);
      const bool a = value_at(probe, plus);
      probe[k] = scales[k] * std::exp(-kDifferenceStep);
      const bool b = value_at(probe, minus);
      probe[k] = scales[k];
      if (a && b) out.gradient[k] = (plus - minus) / (2.0 * kDifferenceStep) / scales[k];
    }
    return out;
  }
  Evaluation ev;
  evaluate(pb, scales.data(), ev);
  ObjectiveGradient out;
  out.value = ev.f;
  out.gradient = ev.grad;
  if (pb.peak()) {
    const auto it = std::max_element(ev.peak.begin(), ev.peak.end());  // first of equal maxima
    const std::size_t row = static_cast<std::size_t>(it - ev.peak.begin());
    const auto& sg = pb.segments[row / kPeakSamples];
    out.value = ev.largest;
    out.gradient.assign(pb.scale_count, 0.0);
    out.gradient[sg.var0] = ev.peak[row].g[0];
    out.gradient[sg.var1] = ev.peak[row].g[1];
  }
  for (int i = 0; i < pb.scale_count; ++i) out.gradient[i] /= scales[i];  // d/ds = (d/dy) / s
  return out;
}

}  // namespace geotraj::optim
