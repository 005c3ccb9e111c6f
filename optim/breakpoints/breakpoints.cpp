#include "optim/breakpoints/breakpoints.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <nlopt.h>

#include "core/format.hpp"
#include "core/geometry/differential_geometry.hpp"
#include "core/geometry/trapezoid.hpp"

namespace geotraj::optim {

namespace {

using Clock = std::chrono::steady_clock;
using core::kMaxTrapezoidOrder;
using core::TrapezoidAxis;
using core::TrapezoidSegment;

// Softmax weights live in [-kWeightBound, kWeightBound]: a gap can shrink to e^-24 ~ 4e-11
// of the largest, i.e. to its minimum, and the box keeps Subplex's simplex bounded.
constexpr double kWeightBound = 12.0;
// Objective of breakpoints whose trapezoid cannot meet the end conditions (singular levels).
constexpr double kInfeasible = 1e30;
// Golden-section steps of the peak refinement: the bracket shrinks by 0.618^40 ~ 4e-9.
constexpr int kGoldenSteps = 40;
// Subplex tolerances: relative change of the weights and of the objective.
constexpr double kXtolRel = 1e-6;
constexpr double kFtolRel = 1e-9;

// ---- the peak of one segment ----------------------------------------------------------

// |tau| (where the curve has a normal) and kappa at local u of a trapezoid segment.
struct Sample {
  double target = 0.0;  // the objective's quantity: |tau| or kappa
  double kappa = 0.0;
};

Sample geometric_value(const TrapezoidSegment& seg, double noise, BreakpointObjective objective, double u) {
  core::Jet jet;
  for (auto& v : jet) v.setZero();
  const int order = objective == BreakpointObjective::kPeakTorsion ? 3 : 2;
  double d[core::kMaxJetOrder + 1];
  for (int a = 0; a < 3; ++a) {
    core::evaluate(seg.axes[a], u, order, d);
    for (int k = 0; k <= order; ++k) jet[k](a) = d[k];
  }
  const core::LocalGeometry g = core::local_geometry(jet, noise);
  if (objective == BreakpointObjective::kPeakCurvature) return {g.kappa, g.kappa};
  return {g.has_normal ? std::abs(g.tau) : 0.0, g.kappa};  // (5.11)
}

// Largest level |A_j| of the n-th derivative of one axis: it is piecewise linear between
// 0 at both ends and the levels A_j = c_1 + ... + c_j (App. B.2).
double level_peak(const TrapezoidAxis& axis) {
  double level = 0.0, peak = 0.0;
  for (int r = 0; r < axis.n; ++r) {
    level += axis.c[r];
    peak = std::max(peak, std::abs(level));
  }
  return peak;
}

// Golden-section maximum of the target (sign +1) or minimum of kappa (sign -1) over
// [lo, hi]: returns the argument and the target's value there.
std::pair<double, double> golden(const TrapezoidSegment& seg, double noise, BreakpointObjective objective, double lo,
                                 double hi, int sign) {
  constexpr double kInvPhi = 0.6180339887498949;
  const auto f = [&](double u) {
    const Sample s = geometric_value(seg, noise, objective, u);
    return sign > 0 ? s.target : -s.kappa;
  };
  double x1 = hi - kInvPhi * (hi - lo), x2 = lo + kInvPhi * (hi - lo);
  double f1 = f(x1), f2 = f(x2);
  for (int k = 0; k < kGoldenSteps; ++k) {
    if (f1 > f2) {
      hi = x2, x2 = x1, f2 = f1;
      x1 = hi - kInvPhi * (hi - lo);
      f1 = f(x1);
    } else {
      lo = x1, x1 = x2, f1 = f2;
      x2 = lo + kInvPhi * (hi - lo);
      f2 = f(x2);
    }
  }
  const double u = f1 > f2 ? x1 : x2;
  return {u, geometric_value(seg, noise, objective, u).target};
}

// Peak of |tau| or kappa over the segment, its frames included (their values are fixed by
// the constraints: no breakpoints go below them). `samples` midpoints u_i = (i + 1/2) /
// samples and the frames u = 0, 1; then golden section over the two intervals around each
//  - sample at least as large as both neighbours (a local maximum), and, for torsion,
//  - sample of locally smallest kappa: where |p' x p''| nearly vanishes, |tau| has a spike
//    far narrower than the sample spacing, next to a sign change of tau (seen on Table
//    B.1: without this the optimiser hides spikes of 1e3-1e4 between samples). The dip of
//    kappa is located by golden section, then |tau| is maximised within 1% of a spacing.
// The half spacings next to the frames are searched the same way.
double geometric_peak(const TrapezoidSegment& seg, BreakpointObjective objective, int samples) {
  const double noise = core::segment_noise(core::Segment{seg});
  const double h = 1.0 / samples;
  thread_local std::vector<Sample> v;
  v.resize(samples + 2);
  v[0] = geometric_value(seg, noise, objective, 0.0);
  for (int i = 0; i < samples; ++i) v[i + 1] = geometric_value(seg, noise, objective, (i + 0.5) * h);
  v[samples + 1] = geometric_value(seg, noise, objective, 1.0);
  const auto u_of = [&](int j) { return j == 0 ? 0.0 : j == samples + 1 ? 1.0 : (j - 0.5) * h; };
  double best = 0.0;
  for (int j = 1; j <= samples; ++j) {
    const double here = v[j].target, prev = v[j - 1].target, next = v[j + 1].target;
    if (!std::isfinite(here) || !std::isfinite(v[j].kappa)) return kInfeasible;
    const bool peak = here >= prev && here >= next && (here > prev || here > next);
    const bool kappa_dip = objective == BreakpointObjective::kPeakTorsion && v[j].kappa <= v[j - 1].kappa &&
                           v[j].kappa <= v[j + 1].kappa && v[j].kappa > 0.0;
    best = std::max({best, here, prev, next});
    if (!peak && !kappa_dip) continue;
    double refined = golden(seg, noise, objective, u_of(j - 1), u_of(j + 1), +1).second;
    if (kappa_dip) {
      // The spike of |tau| sits at the dip of kappa, within a small fraction of the spacing.
      const double dip = golden(seg, noise, objective, u_of(j - 1), u_of(j + 1), -1).first;
      const double near = 1e-2 * h;
      refined = std::max(refined, golden(seg, noise, objective, std::max(0.0, dip - near),
                                         std::min(1.0, dip + near), +1).second);
    }
    best = std::max(best, refined);
  }
  // Between the frames and their nearest samples: a peak there would hide from the samples.
  for (const auto& [lo, hi] : {std::pair{0.0, 0.5 * h}, std::pair{1.0 - 0.5 * h, 1.0}}) {
    best = std::max(best, golden(seg, noise, objective, lo, hi, +1).second);
  }
  return std::isfinite(best) ? best : kInfeasible;
}

// ---- the parameterisation ----------------------------------------------------------------

using Breakpoints = std::array<double, 2 * kMaxTrapezoidOrder + 2>;

// Minimum of gap k (u_{k+1} - u_k) of an order-n trapezoid: ramps are the even gaps.
double min_gap(int k, double min_ramp) { return k % 2 == 0 ? min_ramp : 0.0; }

// Weights -> breakpoints u_0 = 0 <= ... <= u_{2n+1} = 1, ordered by construction.
Breakpoints decode(const double* w, int n, double min_ramp) {
  const int gaps = 2 * n + 1;
  double top = w[0];
  for (int k = 1; k < gaps; ++k) top = std::max(top, w[k]);
  double e[2 * kMaxTrapezoidOrder + 1], sum = 0.0;
  for (int k = 0; k < gaps; ++k) sum += (e[k] = std::exp(w[k] - top));
  const double free = 1.0 - (n + 1) * min_ramp;
  Breakpoints u{};
  for (int k = 0; k < gaps; ++k) u[k + 1] = std::min(1.0, u[k] + min_gap(k, min_ramp) + free * e[k] / sum);
  u[gaps] = 1.0;  // exact, whatever the rounding of the sum
  return u;
}

// Breakpoints -> weights (the inverse of decode where gaps exceed their minimum; a gap at
// or below its minimum maps to the lower bound).
void encode(const double* u, int n, double min_ramp, double* w) {
  const int gaps = 2 * n + 1;
  const double floor = std::exp(-kWeightBound);
  double largest = 0.0;
  double excess[2 * kMaxTrapezoidOrder + 1];
  for (int k = 0; k < gaps; ++k) largest = std::max(largest, excess[k] = u[k + 1] - u[k] - min_gap(k, min_ramp));
  for (int k = 0; k < gaps; ++k) {
    w[k] = largest > 0.0 ? std::clamp(std::log(std::max(excess[k] / largest, floor)), -kWeightBound, kWeightBound)
                         : 0.0;
  }
}

// ---- blocks: the independent sub-problems ------------------------------------------------

// One sub-problem: some axes of one segment (all three for kappa and tau, one for the
// derivatives), each with 2n + 1 weights.
struct Block {
  std::size_t segment = 0;
  int axis_begin = 0, axis_end = 3;
  int n = 2;
  int dim() const { return (axis_end - axis_begin) * (2 * n + 1); }
};

struct Problem {
  const BreakpointOptions* options = nullptr;
  Clock::time_point stop_at;
  bool has_stop_at = false;
  TrapezoidSegment segment;  // the block's segment, its axes replaced per evaluation
  Block block;
  // Best of this run and overall bookkeeping.
  double best = kInfeasible;
  std::vector<double> best_w;
  long evaluations = 0;
  bool timed_out = false;
  nlopt_opt opt = nullptr;
};

bool out_of_time(const Problem& p) {
  return (p.has_stop_at && Clock::now() >= p.stop_at) || p.options->stop.stop_requested();
}

// Objective of a block at weights w: the block's axes rebuilt from their breakpoints.
double block_objective(Problem& p, const double* w) {
  TrapezoidSegment& seg = p.segment;
  const int n = p.block.n;
  for (int a = p.block.axis_begin; a < p.block.axis_end; ++a) {
    const Breakpoints u = decode(w + (a - p.block.axis_begin) * (2 * n + 1), n, p.options->min_ramp);
    const TrapezoidAxis& old = seg.axes[a];
    auto axis = core::make_trapezoid(n, std::span<const double>(u.data(), 2 * n + 2),
                                     std::span<const double>(old.start.data(), n),
                                     std::span<const double>(old.end.data(), n));
    if (!axis) return kInfeasible;
    seg.axes[a] = *axis;
  }
  if (p.options->objective == BreakpointObjective::kPeakDerivatives) {
    double peak = 0.0;
    for (int a = p.block.axis_begin; a < p.block.axis_end; ++a) peak = std::max(peak, level_peak(seg.axes[a]));
    return std::isfinite(peak) ? peak : kInfeasible;
  }
  return geometric_peak(seg, p.options->objective, p.options->samples_per_segment);
}

double nlopt_objective(unsigned dim, const double* w, double* /*grad: derivative-free*/, void* data) {
  auto& p = *static_cast<Problem*>(data);
  if (out_of_time(p)) {
    p.timed_out = true;
    nlopt_force_stop(p.opt);
    return kInfeasible;
  }
  ++p.evaluations;
  const double f = block_objective(p, w);
  if (f < p.best) {
    p.best = f;
    p.best_w.assign(w, w + dim);
  }
  return f;
}

// A deterministic uniform number in [0, 1) from a 64-bit state (splitmix64: the same on
// every platform, unlike std::uniform_real_distribution).
double next_uniform(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

// Explicit per-axis breakpoint lists of one trapezoid segment.
core::SegmentBreakpoints explicit_breakpoints(std::size_t index, const TrapezoidSegment& seg) {
  core::SegmentBreakpoints bp;
  bp.segment = static_cast<std::uint32_t>(index);
  std::vector<double>* lists[] = {&bp.x, &bp.y, &bp.z};
  for (int a = 0; a < 3; ++a) lists[a]->assign(seg.axes[a].u.begin(), seg.axes[a].u.begin() + 2 * seg.axes[a].n + 2);
  return bp;
}

// Field paths as in a PlanRequest (core/error.hpp): the options are optimize.breakpoints.
core::Violations check_options(const BreakpointOptions& o) {
  const std::string at = "optimize.breakpoints.";
  core::Violations v;
  if (o.max_evaluations <= 0) v.push_back({at + "maxEvaluations", "must be > 0, got " + std::to_string(o.max_evaluations)});
  if (o.restarts < 0) v.push_back({at + "restarts", "must be >= 0, got " + std::to_string(o.restarts)});
  if (o.samples_per_segment < 8) {
    v.push_back({at + "samplesPerSegment", "must be >= 8, got " + std::to_string(o.samples_per_segment)});
  }
  // Ramps of the highest order (n = 5) must fit: 6 min_ramp < 1.
  if (!(o.min_ramp > 0.0 && o.min_ramp < 1.0 / (kMaxTrapezoidOrder + 1))) {
    v.push_back({at + "minRamp", "must lie in (0, 1/6), got " + core::number(o.min_ramp)});
  }
  if (o.time_budget_s && !(*o.time_budget_s >= 0.0)) {
    v.push_back({"optimize.timeBudgetS", "must be >= 0 s, got " + core::number(*o.time_budget_s)});
  }
  return v;
}

}  // namespace

const char* name(BreakpointObjective objective) {
  switch (objective) {
    case BreakpointObjective::kPeakTorsion: return "peak torsion";
    case BreakpointObjective::kPeakCurvature: return "peak curvature";
    case BreakpointObjective::kPeakDerivatives: return "peak derivatives";
  }
  return "unknown";
}

double peak_objective(const core::Path& path, BreakpointObjective objective, int samples) {
  GEOTRAJ_CHECK(samples >= 2);
  double peak = 0.0;
  for (const auto& segment : path.segments) {
    const auto* seg = std::get_if<TrapezoidSegment>(&segment);
    GEOTRAJ_CHECK(seg != nullptr);  // callers pass TRAPEZOIDAL paths
    if (objective == BreakpointObjective::kPeakDerivatives) {
      for (const auto& axis : seg->axes) peak = std::max(peak, level_peak(axis));
    } else {
      peak = std::max(peak, geometric_peak(*seg, objective, samples));
    }
  }
  return peak;
}

core::Expected<BreakpointResult> optimize_breakpoints(const core::PathSpec& spec, const BreakpointOptions& options) {
  const auto started = Clock::now();
  if (spec.blend != core::BlendMethod::kTrapezoidal) {
    return tl::unexpected(core::Violations{
        {"path.blend", "the breakpoint optimiser needs the TRAPEZOIDAL blend; the path blends with POLYNOMIAL"}});
  }
  if (auto bad = check_options(options); !bad.empty()) return tl::unexpected(std::move(bad));
  auto built = core::build_path(spec);
  if (!built) return tl::unexpected(core::prefixed(std::move(built.error()), "path."));
  const core::Path& path = *built;

  Problem base;
  base.options = &options;
  if (options.deadline) base.stop_at = *options.deadline, base.has_stop_at = true;
  if (options.time_budget_s) {
    const auto budget = started + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
                                      std::min(*options.time_budget_s, 1e6)));
    base.stop_at = base.has_stop_at ? std::min(base.stop_at, budget) : budget;
    base.has_stop_at = true;
  }

  // The request's own segments: the start point, and the fallback.
  std::vector<TrapezoidSegment> best_segments;
  for (const auto& s : path.segments) best_segments.push_back(std::get<TrapezoidSegment>(s));

  BreakpointResult result;
  result.report.objective_before = peak_objective(path, options.objective, options.samples_per_segment);

  std::vector<Block> blocks;
  for (std::size_t i = 0; i < best_segments.size(); ++i) {
    const int n = best_segments[i].axes[0].n;
    if ((n + 1) * options.min_ramp >= 1.0) continue;  // no room: keep the request's breakpoints
    if (options.objective == BreakpointObjective::kPeakDerivatives) {
      for (int a = 0; a < 3; ++a) blocks.push_back({i, a, a + 1, n});
    } else {
      blocks.push_back({i, 0, 3, n});
    }
  }

  // Per block: the best weights and objective so far (from the request's breakpoints).
  std::vector<std::vector<double>> block_w(blocks.size());
  std::vector<double> block_f(blocks.size(), kInfeasible);
  const int runs = options.restarts + 1;
  const long per_run = std::max<long>(
      1, options.max_evaluations / std::max<long>(1, static_cast<long>(runs) * static_cast<long>(blocks.size())));
  long evaluations = 0;
  bool timed_out = out_of_time(base), hit_eval_limit = false, solver_failed = false;
  std::string message;

  for (std::size_t b = 0; b < blocks.size() && !timed_out; ++b) {
    const Block& blk = blocks[b];
    block_w[b].resize(blk.dim());
    for (int a = blk.axis_begin; a < blk.axis_end; ++a) {
      encode(best_segments[blk.segment].axes[a].u.data(), blk.n, options.min_ramp,
             block_w[b].data() + (a - blk.axis_begin) * (2 * blk.n + 1));
    }
  }

  // Rounds of runs over all blocks, so that a time limit leaves every block improved.
  for (int run = 0; run < runs && !timed_out; ++run) {
    for (std::size_t b = 0; b < blocks.size() && !timed_out; ++b) {
      const Block& blk = blocks[b];
      const int gaps = 2 * blk.n + 1;
      std::vector<double> x0 = block_w[b];
      if (run == 1) {
        // Narrow ramps, even holds: the pattern of (B.11), generalised to order n.
        for (int a = 0; a < blk.axis_end - blk.axis_begin; ++a) {
          Breakpoints u{};
          const double ramp = std::max(options.min_ramp, 0.02), hold = (1.0 - (blk.n + 1) * ramp) / blk.n;
          for (int k = 0; k < gaps; ++k) u[k + 1] = u[k] + (k % 2 == 0 ? ramp : hold);
          u[gaps] = 1.0;
          encode(u.data(), blk.n, options.min_ramp, x0.data() + a * gaps);
        }
      } else if (run >= 2) {
        // The best point, perturbed: deterministic in (seed, block, run).
        std::uint64_t state = options.seed * 0x100000001B3ull + b * 7919u + static_cast<std::uint64_t>(run);
        const double spread = 1.5;  // in log-gap units: gaps change by up to e^1.5 ~ 4.5x
        for (double& w : x0) w = std::clamp(w + spread * (2.0 * next_uniform(state) - 1.0), -kWeightBound, kWeightBound);
      }

      Problem p = base;
      p.segment = best_segments[blk.segment];
      p.block = blk;
      nlopt_opt opt = nlopt_create(NLOPT_LN_SBPLX, static_cast<unsigned>(blk.dim()));
      p.opt = opt;
      nlopt_set_lower_bounds1(opt, -kWeightBound);
      nlopt_set_upper_bounds1(opt, kWeightBound);
      nlopt_set_min_objective(opt, nlopt_objective, &p);
      nlopt_set_maxeval(opt, static_cast<int>(per_run));
      nlopt_set_xtol_rel(opt, kXtolRel);
      nlopt_set_ftol_rel(opt, kFtolRel);
      nlopt_set_initial_step1(opt, 1.0);
      double f = 0.0;
      const nlopt_result rc = nlopt_optimize(opt, x0.data(), &f);
      nlopt_destroy(opt);
      evaluations += p.evaluations;
      timed_out = timed_out || p.timed_out;
      if (rc == NLOPT_MAXEVAL_REACHED) hit_eval_limit = true;
      if (rc < 0 && rc != NLOPT_FORCED_STOP) {
        solver_failed = true;
        message = std::string("NLopt Subplex: ") + nlopt_result_to_string(rc);
      }
      if (p.best < block_f[b] && !p.best_w.empty()) {
        block_f[b] = p.best;
        block_w[b] = p.best_w;
        // Keep the block's best axes in the segment, so later blocks of the segment see them.
        Problem keep = base;
        keep.segment = best_segments[blk.segment];
        keep.block = blk;
        block_objective(keep, block_w[b].data());
        best_segments[blk.segment] = keep.segment;
      }
    }
  }

  // The candidate path: the best axes found; accepted only if it beats the request.
  core::PathSpec candidate = spec;
  candidate.breakpoints.clear();
  for (std::size_t i = 0; i < best_segments.size(); ++i) {
    candidate.breakpoints.push_back(explicit_breakpoints(i, best_segments[i]));
  }
  auto rebuilt = core::build_path(candidate);
  double after = kInfeasible;
  if (rebuilt) after = peak_objective(*rebuilt, options.objective, options.samples_per_segment);

  OptimizerReport& report = result.report;
  report.iterations = static_cast<int>(std::min<long>(evaluations, std::numeric_limits<int>::max()));
  const bool improved = rebuilt && after < report.objective_before;
  if (improved) {
    result.spec = std::move(candidate);
    result.breakpoints = result.spec.breakpoints;
    report.objective_after = after;
  } else {
    result.spec = spec;
    for (std::size_t i = 0; i < path.segments.size(); ++i) {
      result.breakpoints.push_back(explicit_breakpoints(i, std::get<TrapezoidSegment>(path.segments[i])));
    }
    report.objective_after = report.objective_before;
  }
  if (timed_out) {
    report.status = OptimizerStatus::kTimeLimit;
    if (message.empty()) {
      message = options.stop.stop_requested() ? "cancelled" : "stopped at the deadline or time budget";
    }
  } else if (!improved && solver_failed) {
    report.status = OptimizerStatus::kFailed;
  } else if (!improved) {
    report.status = OptimizerStatus::kNoImprovement;
  } else if (hit_eval_limit) {
    report.status = OptimizerStatus::kIterationLimit;
  } else {
    report.status = OptimizerStatus::kConverged;
  }
  report.message = message;
  report.seconds = std::chrono::duration<double>(Clock::now() - started).count();
  return result;
}

}  // namespace geotraj::optim
