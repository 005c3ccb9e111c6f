// What the tangent-scale optimiser's solvers (ipopt_solver.cpp, nlopt_solver.cpp) and its
// driver (tangent_scales.cpp) share: a solver's run and its entry points. Private to geotraj_optim.
#pragma once

#include <chrono>
#include <vector>

#include "optim/common/report.hpp"
#include "optim/tangent_scales/problem.hpp"
#include "optim/tangent_scales/tangent_scales.hpp"

namespace geotraj::optim::tangent_scales_detail {

using Clock = std::chrono::steady_clock;

// The smoothest reading's derivatives: central differences in y = ln(scale) with this step
// (GlobalSolver in nlopt_solver.cpp, tangent_scale_gradient).
inline constexpr double kDifferenceStep = 1e-5;

// A point a solver evaluated that meets the regularity rows, with its solver measure (the
// integral, or the largest peak row).
struct Candidate {
  std::vector<double> scales;
  double measure = 0.0;
};

// What a solver leaves for the driver's verification: its final point (empty if it has none)
// and the regular points it evaluated. The solver sets report.status, message and iterations.
struct SolverRun {
  std::vector<double> final_scales;
  std::vector<Candidate> candidates;
};

// Ipopt (ScaleNlp, ipopt_solver.cpp) from pb.start, on the readings whose segments depend on
// their two scales. The caller holds the Ipopt lock (optim/common/ipopt_lock.hpp). If Ipopt
// reports the grouped regularity rows infeasible, it solves again with one row per sample
// (pb.rows_per_segment, see kRegularityRows).
SolverRun solve_ipopt(Problem& pb, Clock::time_point stop_at, const TangentScaleOptions& options,
                      OptimizerReport& report);

// The smoothest reading on NLopt's SLSQP (GlobalSolver, nlopt_solver.cpp) from pb.start.
SolverRun solve_slsqp(const Problem& pb, Clock::time_point stop_at, const TangentScaleOptions& options,
                      OptimizerReport& report);

}  // namespace geotraj::optim::tangent_scales_detail
