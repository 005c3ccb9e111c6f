// Trapezoid breakpoints chosen by optimisation (thesis App. B.3): the thesis tunes the
// breakpoints of Eqs. (B.11) and (B.13) by hand to lower the peak parametric derivatives and
// the peak torsion, and calls automating it "a useful area for future research" (B.4). This
// optimiser chooses the breakpoints of every segment and axis of a TRAPEZOIDAL path so as to
// minimise a peak along the path. The key frames' constraints do not depend on the
// breakpoints (an order-n trapezoid meets derivatives 0..n-1 at both ends for any ordered
// breakpoints), so they stay met exactly.
//
// Method (docs/optimisation.md, "Trapezoid breakpoints"): each segment's shape depends on its
// own breakpoints only, so a peak over the path is minimised segment by segment (for the
// peak derivatives, axis by axis). The breakpoints u_0 = 0 < u_1 <= ... <= u_{2n+1} = 1 are
// parameterised without constraints by their 2n + 1 gaps, gap_k = min_k + (1 - sum min) *
// softmax(w)_k, where min_k = min_ramp on the n + 1 ramps and 0 on the n holds; the weights w
// are bounded to [-12, 12]. NLopt's derivative-free Subplex
// (NLOPT_LN_SBPLX) minimises each block from deterministic starts: the request's
// breakpoints, narrow ramps (the pattern of B.11) and perturbations of the best point found.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <stop_token>
#include <vector>

#include "core/error.hpp"
#include "core/geometry/key_frame.hpp"
#include "core/geometry/path.hpp"
#include "optim/common/report.hpp"

namespace geotraj::optim {

/// What the breakpoint optimiser minimises (proto BreakpointObjective). Every objective is a
/// peak along the path (see peak_objective).
enum class BreakpointObjective {
  kPeakTorsion,      ///< largest |tau| [1/m] where the curve has a normal (kappa > 0)
  kPeakCurvature,    ///< largest kappa [1/m]
  kPeakDerivatives,  ///< largest |d^n x_a/du^n| [m] over segments and axes a, n the trapezoid's order
};

/// Options (Ceres style: a value with documented defaults).
struct BreakpointOptions {
  BreakpointObjective objective = BreakpointObjective::kPeakTorsion;
  /// The RPC's deadline: the optimiser stops by then with the best point found.
  std::optional<std::chrono::steady_clock::time_point> deadline;
  /// Wall-clock budget [s], >= 0, counted from the call; the earlier of it and the deadline holds.
  std::optional<double> time_budget_s;
  /// Cancellation (the RPC's): treated as a time limit.
  std::stop_token stop;
  /// Runs of the local method after the first, per block, from deterministic starts; >= 0.
  int restarts = 3;
  /// Objective evaluations of all runs together, > 0; shared evenly between the runs.
  int max_evaluations = 12000;
  /// Smallest width of every ramp of the n-th derivative (dimensionless, in (0, 1/(n+1)));
  /// (B.11) uses 0.02. Keeps the n-th derivative continuous and u_1 > u_0.
  double min_ramp = 0.01;
  /// Samples per segment of the peak search (>= 8), before local refinement.
  int samples_per_segment = 96;
  /// Seed of the deterministic perturbations of the restarts.
  std::uint64_t seed = 1;
};

/// The optimised path and what the optimiser did. Objective in the objective's unit.
struct BreakpointResult {
  core::PathSpec spec;  ///< the request with the chosen breakpoints (or the request's own, if no better)
  /// The chosen breakpoints: one entry per segment, with explicit x, y and z lists (local u in [0, 1]).
  std::vector<core::SegmentBreakpoints> breakpoints;
  OptimizerReport report;
};

/// Chooses the trapezoid breakpoints of every segment and axis of `spec` to minimise
/// `options.objective`. Deterministic for given inputs unless it stops at the time limit.
/// Never worse than the request's breakpoints: if nothing better is found, the request is
/// returned with status kNoImprovement (or kTimeLimit when time ran out).
/// Errors, named as in a PlanRequest (two values: core/error.hpp): `path.blend` when the path
/// is not TRAPEZOIDAL; `optimize.breakpoints.maxEvaluations`, `.restarts`, `.minRamp`,
/// `.samplesPerSegment` and `optimize.timeBudgetS` when out of range; every violation of an
/// invalid path under `path.`.
core::Expected<BreakpointResult> optimize_breakpoints(const core::PathSpec& spec, const BreakpointOptions& options);

/// The objective on a built TRAPEZOIDAL path, as the optimiser measures it: the largest
/// value over every segment, its frames included (where the constraints fix the value, no
/// breakpoints change it, so it bounds the objective from below). Per segment: `samples`
/// points at local u = (i + 1/2) / samples and the frames, then golden-section refinement
/// around each sampled local maximum, around each dip of kappa (where |tau| spikes, for
/// torsion) and next to the frames. kPeakDerivatives is exact: the n-th derivative is
/// piecewise linear, so its peak is the largest trapezoid level |A_j|.
double peak_objective(const core::Path& path, BreakpointObjective objective, int samples = 96);

/// The objective's name ("peak torsion", ...).
const char* name(BreakpointObjective objective);

}  // namespace geotraj::optim
