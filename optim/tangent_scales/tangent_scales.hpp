// Tangent-scale optimisation (thesis 5.2, 6.3.2.1, 7.2.3): the tangent scale |dp/du| at a key
// frame is the one geometric constraint that the operator rarely cares about and that shapes
// the curve between the frames the most. This optimiser chooses the scales that minimise a
// shape measure of the polynomial blend, within bounds, while every given constraint at the
// frames (position, T, N, kappa, kappa', tau, tau') stays met exactly: the scales only enter
// through the Chapter 5 conversion, which meets the constraints for any scale > 0.
//
// Method. The variables are y = ln(scale) (layout below). Each segment depends on two scales
// (its start frame's leaving side, its end frame's approach side); its control points follow
// from the end derivatives (core::side_derivatives, core::hermite_control_points), evaluated
// with a second-order forward-mode number in the segment's two log-scales, so that the
// gradient, the constraint Jacobians and the Hessian of the Lagrangian are exact (automatic
// differentiation, no finite differences; control points once per segment and evaluation,
// Bernstein weights precomputed once per degree and process).
// Ipopt 3.11 (interior point, exact Hessian) solves:
//  - kBendingEnergy:  min  E + length_weight L,  E = int kappa^2 ds = sum over segments of
//                     int_0^1 |p' x p''|^2 / |p'|^5 du,  L = int |p'| du.
//                     Units: E [1/m], length_weight [1/m^2], so the objective is in [1/m].
//  - kArcLength:      min  L [m].
//  - kPeakCurvature:  min  max_j kappa(u_j) at kPeakSamples points u_j per segment [1/m], by
//                     a smooth log-sum-exp aggregate of kappa^2 (power 48: within ~5 % of the
//                     maximum; the reported value is the exact maximum on the fine samples).
//  - kPeakTorsion:    likewise for |tau|, tau = (p' x p'') . p''' / |p' x p''|^2, over the
//                     points where kappa >= kTorsionCurvatureFraction / chord (nearly
//                     straight points are left out: there tau is ill-conditioned and spikes;
//                     in the solver a C1 weight fades them out between half the floor and it).
// Well posed: subject to  |p'(u_j)| >= kMinSpeedFraction x chord  at kRegularitySamples
// points per segment, the curve cannot nearly stop inside a segment, so kappa stays bounded
// and smooth there and the fixed rules resolve it. The NLP imposes them as 8 rows per segment,
// each a conservative soft minimum of 4 consecutive samples (every sample still meets the
// floor; the floor rises by at most 1.1 %), or as one row per sample if Ipopt reports the
// grouped rows infeasible.
// The integrals use a fixed composite Gauss-Legendre rule (kQuadratureIntervals x 8 nodes
// per segment), not core's adaptive Gauss-Kronrod: a fixed rule keeps the objective a smooth
// function of the scales (adaptive subdivision switches with the scales, which a
// gradient-based solver sees as noise); on the thesis demo it agrees with core's arc length
// to ~2e-8 relative and, at the optimum, with core's densely sampled bending energy within
// 1 % (tests/optim/tangent_scales).
// Verification: only the returned point is checked, on rules 8 times finer, in double: it
// must be regular there (|p'| >= half the floor), the integral on the solver's rule must agree
// with the fine one to 1e-3, and it must beat the start by the fine measure. The solver's
// final point is tried first, then (at most 8 in all) the other regular points it evaluated,
// best first. The reported objectives (before and after) are the fine measures.
//
// Bounds (per scale) [m]: [min_scale, max_scale]. Defaults relative to the frame's largest
// chord c to a neighbouring frame: min 0.1 c (below it the blend turns the curve within a
// few percent of the segment next to the frame: practically a corner, whose curvature the
// fixed rules cannot resolve and no objective here wants), max 10 c (a cubic Hermite
// segment already loops at a scale of about 3 chords; 10 leaves room on higher-order blends).
// Both are clamped into core::PathLimits' [min_tangent_scale, max_tangent_scale].
//
// Readings (PathSpec::unspecified). Lowest degree and the thesis's zeros (every side of order
// 4, zeros above what the frame gives): each segment depends on its two scales, as above.
// The smoothest reading (the default): the free derivatives come from one solve over the
// whole path (core::fill_smoothest), so each segment depends on every scale. Each evaluation
// runs that solve, NLopt's SLSQP minimises with bounds and the regularity rows as
// inequality constraints, and the derivatives are central differences in y of the whole
// evaluation (step 1e-5), 2 n + 1 solves per gradient for n scales; iterations count
// evaluations with a gradient. The curve stays G4 at frames that nothing breaks, for any
// two scales (core/geometry/smoothest.hpp). The verification below is the same.
//
// Length. The bending energy alone is lowered by longer, gentler curves: the default length
// weight is E0 / L0 at the start (both terms weigh the same there). The peak objectives keep
// the arc length within kPeakLengthGrowth of their start (one more NLP row).
//
// Cusps: the thesis has one scale per frame. At a cusp (the tangent inverts, the curve is
// not C1 there) both sides are free separately: the approach side is KeyFrame::tangent_scale
// and the leaving side KeyFrame::leave_tangent_scale; so has a frame whose sides have scales
// of their own (given, or the chord-length defaults of validate_path). Elsewhere both sides
// share one scale. Every reading of unspecified constraints is modelled (see "Readings" above).
//
// Time: the solver stops at `deadline`, at `budget_seconds` after the call, or when `stop`
// is requested, whichever is first (checked every iteration), and returns the best verified
// point it evaluated with status kTimeLimit. Any scales within the bounds are feasible, so every
// returned spec is a valid path that meets its frames. Without a time stop the result is
// deterministic (same input, same output, bit for bit).
#pragma once

#include <chrono>
#include <optional>
#include <stop_token>
#include <vector>

#include "core/error.hpp"
#include "core/geometry/key_frame.hpp"
#include "optim/common/report.hpp"

namespace geotraj::optim {

/// What the tangent scales minimise (see the file comment for formulas and units).
enum class TangentScaleObjective {
  kBendingEnergy,   ///< int kappa^2 ds [1/m] + length_weight * arc length
  kPeakCurvature,   ///< max kappa at the sample points [1/m]
  kPeakTorsion,     ///< max |tau| at the sample points [1/m]
  kArcLength,       ///< total arc length [m]
};

/// Composite Gauss-Legendre rule of the integral objectives: this many sub-intervals of
/// 8 nodes per segment.
inline constexpr int kQuadratureIntervals = 8;
/// Sample points per segment of the peak objectives, uniform in u, both ends included.
inline constexpr int kPeakSamples = 33;
/// Regularity: |dp/du| >= kMinSpeedFraction x the segment's chord [m] at kRegularitySamples
/// midpoints (j + 1/2) / kRegularitySamples of every segment (NLP constraints, grouped).
inline constexpr int kRegularitySamples = 32;
inline constexpr double kMinSpeedFraction = 0.1;
/// kPeakTorsion leaves out the points of a segment where kappa < kTorsionCurvatureFraction /
/// chord [1/m] (nearly straight: the osculating plane, and so tau, is ill-conditioned).
inline constexpr double kTorsionCurvatureFraction = 0.5;
/// The peak objectives keep the arc length within kPeakLengthGrowth x its length at the
/// solve's start (an NLP row): a peak of curvature is lowered by ever larger loops, which the
/// operator did not ask for and which sampled peaks no longer resolve (thesis path B under
/// the smoothest reading without the row: 974 m of curve, a sampled peak of 14 1/m and a
/// true one of 38 1/m).
inline constexpr double kPeakLengthGrowth = 1.5;

struct TangentScaleOptions {
  TangentScaleObjective objective = TangentScaleObjective::kBendingEnergy;
  /// Smallest scale [m], > 0; default 10 % of each frame's largest chord to a neighbour.
  std::optional<double> min_scale;
  /// Largest scale [m], >= min_scale; default 10 x each frame's largest chord to a neighbour.
  std::optional<double> max_scale;
  /// Weight of the arc length in kBendingEnergy [1/m^2], >= 0. Absent: E0 / L0, the bending
  /// energy over the arc length at the start, so that both terms weigh the same there (the
  /// energy alone is lowered by ever longer, gentler curves); 0: the energy alone.
  std::optional<double> length_weight;
  /// The RPC's deadline: the solver returns its best point by then.
  std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max();
  /// Optional time budget from the call [s], >= 0.
  std::optional<double> budget_seconds;
  /// Cancellation (the RPC was cancelled): stops like the deadline.
  std::stop_token stop;
  /// Solver iterations, >= 1.
  int max_iterations = 100;
};

struct TangentScaleResult {
  /// The request with the chosen scales written into tangent_scale (and leave_tangent_scale
  /// where the sides have scales of their own); everything else as given.
  core::PathSpec spec;
  /// The scales [m] in variable order: for each frame i in order, its tangent scale, then,
  /// if frame i is a cusp or has a leaving scale of its own, that scale right after it.
  std::vector<double> scales;
  /// The length weight used [1/m^2] (kBendingEnergy: the given one or the default E0 / L0).
  double length_weight = 0.0;
  /// objective_before at the start (the request's scales, default 1, clamped into the
  /// bounds), objective_after at the result, both in the objective's unit.
  OptimizerReport report;
};

/// Chooses the tangent scales of `spec` (see the file comment). The start is the request's
/// scales clamped into the bounds. Errors (field paths relative to the request):
/// `path.*` for an invalid path (core::validate_path's fields under `path.`), `path.blend`
/// for the trapezoid blend (only the polynomial blend is optimised), and
/// `optimize.tangentScales.{minScale, maxScale, lengthWeight, budgetSeconds, maxIterations}`
/// for bad options. kFailed and kNoImprovement return the start.
core::Expected<TangentScaleResult> optimize_tangent_scales(const core::PathSpec& spec,
                                                           const TangentScaleOptions& options = {});

/// The objective of `options.objective` at the scales of `spec` (as the optimiser computes
/// it, in its unit), e.g. to compare candidates. Same errors as optimize_tangent_scales.
core::Expected<double> tangent_scale_objective(const core::PathSpec& spec, const TangentScaleOptions& options = {});

/// The objective and its gradient with respect to `scales` (layout of TangentScaleResult),
/// by automatic differentiation. For the peak objectives this is the smooth part only: the
/// gradient of the largest sample's kappa^2 or tau^2 (not of its square root). Exposed so
/// that tests can check it against finite differences.
struct ObjectiveGradient {
  double value = 0.0;  ///< for peaks: the largest kappa^2 or tau^2 [1/m^2]
  std::vector<double> gradient;
};
core::Expected<ObjectiveGradient> tangent_scale_gradient(const core::PathSpec& spec, const std::vector<double>& scales,
                                                         const TangentScaleOptions& options = {});

}  // namespace geotraj::optim
