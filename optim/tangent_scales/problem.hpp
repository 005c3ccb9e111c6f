// The tangent-scale problem (variables, bounds, segments) and its measures at a point: the
// solver's objective and rows with exact derivatives, the smoothest reading's, the verification.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <map>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "core/error.hpp"
#include "core/geometry/bezier.hpp"
#include "core/geometry/key_frame.hpp"
#include "optim/common/second_order.hpp"
#include "optim/tangent_scales/quadrature.hpp"
#include "optim/tangent_scales/tangent_scales.hpp"

namespace geotraj::optim::tangent_scales_detail {

using Eigen::Vector3d;
template <class S>
using Vec3 = Eigen::Matrix<S, 3, 1>;
// Each segment depends on two scales: second-order forward mode in its two variables
// y = ln(scale) (x0: the start frame's leaving side, x1: the end frame's approach side);
// the Hessian's lower triangle is (x0 x0, x1 x0, x1 x1).
using AD = detail::SecondOrder<2>;

template <class S>
using ControlPoints = std::array<Vec3<S>, core::kMaxBezierDegree + 1>;

// Regularity rows per segment, each over kRegularitySamples / rows consecutive samples: 8 rows
// of 4 samples keep the KKT system small (Ipopt's MUMPS solves cost per row) while leaving the
// restoration phase enough structure. If Ipopt still reports the rows infeasible (a local
// verdict of its restoration phase), the solve is repeated with one row per sample.
inline constexpr int kRegularityRows = 8;

struct SegmentVars {
  std::size_t from = 0, to = 0;  // frames
  int var0 = 0, var1 = 0;        // scale of `from`'s leaving side, of `to`'s approach side
  int n0 = 1, n1 = 1;            // orders fixed at the ends
  Vector3d T0, N0, T1, N1;       // the sides' Frenet vectors (after cusp / inflection flips)
  double speed_floor2 = 0.0;     // (kMinSpeedFraction chord)^2 [m^2]
  double kappa_floor2 = 0.0;     // (kTorsionCurvatureFraction / chord)^2 [1/m^2]
  const Tables* tables = nullptr;
};

struct Problem {
  core::PathSpec spec;  // validated, normalised
  // The smoothest reading: the free derivatives at every frame come from one solve over the
  // whole path (core::fill_smoothest), so a segment depends on every scale, not on its two.
  bool global = false;
  // Peak objectives: the longest curve a returned point may have [m] (see kPeakLengthGrowth).
  double max_length = std::numeric_limits<double>::infinity();
  TangentScaleObjective objective = TangentScaleObjective::kBendingEnergy;
  double length_weight = 0.0;
  int scale_count = 0;
  std::vector<int> approach_var, leave_var;  // per frame
  std::vector<double> lower, upper, start;   // per scale [m]
  std::vector<SegmentVars> segments;
  Rule rule, audit_rule;
  std::map<int, std::shared_ptr<const Tables>> tables;  // by degree (shared, see tables_for)

  bool peak() const {
    return objective == TangentScaleObjective::kPeakCurvature || objective == TangentScaleObjective::kPeakTorsion;
  }
  std::size_t peak_rows() const { return peak() ? segments.size() * kPeakSamples : 0; }
  int rows_per_segment = kRegularityRows;  // divides kRegularitySamples
  std::size_t regularity_count() const { return segments.size() * rows_per_segment; }
  // Peaks: one more row, 1 - L / max_length >= 0 (kPeakLengthGrowth), after the regularity rows.
  bool length_row() const { return peak() && std::isfinite(max_length); }
  std::size_t constraint_count() const { return regularity_count() + (length_row() ? 1 : 0); }
};

// Validates the path and the options and sets the problem up. Field paths relative to the request.
core::Expected<Problem> make_problem(const core::PathSpec& raw, const TangentScaleOptions& options);

// Writes `scales` (layout of TangentScaleResult) into the frames of `spec`: one scale per
// frame, and the leaving side's own where it has one (cusps; a leaving scale that differs).
void write_scales(core::PathSpec& spec, const std::vector<int>& approach_var, const std::vector<int>& leave_var,
                  const double* scales);

// Everything at one point (the scales): values and exact first and second derivatives with
// respect to the log-scales y = ln(scale).
struct Evaluation {
  double f = 0.0;              // the solver's objective (peaks: the aggregate F)
  std::vector<double> grad;    // d f / d y
  std::vector<double> hess;    // d2 f / dy_i dy_j at [i * n + j], i >= j (lower triangle)
  double largest = 0.0;        // peaks: the largest peak row [1/m^2]
  std::vector<AD> peak;        // peaks: the rows v_j [1/m^2], in their segment's two variables
  std::vector<AD> g;           // regularity rows G_r, rows_per_segment per segment (>= 0 when met)
  std::vector<AD> length;      // Problem::length_row: each segment's arc length [m], in its two variables
  double length_row = 0.0;     // Problem::length_row: 1 - L / max_length (>= 0 when met)
  std::vector<double> length_grad;  // d length_row / d y
  bool regular = false;        // every regularity sample met (and the length row, if any)
};

// The solver's objective and rows at `scales`, with exact first and second derivatives in
// y = ln(scale). Each segment's control points are computed once (second-order in its two
// variables) and shared by its rows. `v0` scales the aggregate (peaks; <= 0: the largest row
// here). No allocation once `ev` has its size.
void evaluate(const Problem& pb, const double* scales, Evaluation& ev, double v0 = 0.0);

// The solver's objective in its reported unit (square root of the peak rows).
double reported(const Problem& pb, const Evaluation& ev);

// Whether every value and derivative in `ev` is finite.
bool finite(const Evaluation& ev);

// The smoothest reading's objective and rows at one point, in double (no derivatives: the
// solver takes them by central differences, see GlobalSolver in nlopt_solver.cpp).
struct GlobalEvaluation {
  double f = 0.0;          // the solver's objective (peaks: the aggregate F of kAggregatePower)
  double largest = 0.0;    // peaks: the largest peak row [1/m^2]
  std::vector<double> g;   // regularity rows G_r (>= 0 when met)
  bool regular = false;    // every regularity sample met
  bool ok = false;         // the global solve succeeded and every value is finite
};

// At `scales`, `v0` as in evaluate; `points` holds the segments' control points (scratch).
void evaluate_global(const Problem& pb, const double* scales, GlobalEvaluation& ev, double v0,
                     std::vector<ControlPoints<double>>& points);

// The verification measure of one point, in double, on rules kAuditFactor times finer than
// the solver's: the objective in its reported unit (peak torsion with the hard curvature
// floor), and whether the curve stays regular (|p'| >= kAuditSpeedFraction x the floor at
// every fine point; for the peaks also no longer than Problem::max_length) and, for the
// integrals, whether the solver's rule agrees with the fine one to kRuleAgreement.
struct Audit {
  double value = 0.0;
  bool regular = true;
  bool resolved = true;
};

Audit audit(const Problem& pb, const double* scales);

}  // namespace geotraj::optim::tangent_scales_detail
