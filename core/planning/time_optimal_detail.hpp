// What the time-optimal sweep (time_optimal_sweep.cpp) and the plan around it
// (time_optimal.cpp: the grids, the sample checks, the refinements) share. Private to
// geotraj_core; the interface is time_optimal.hpp.
#pragma once

#include <vector>

#include "core/error.hpp"
#include "core/planning/time_optimal.hpp"

namespace geotraj::core::time_optimal_detail {

/// solve_time_optimal with per-point limit scales `sigma` (null: all 1; indexed as `grid`):
/// the plan's refinements and its grid-error estimate (time_optimal.cpp). `points` (null:
/// every point) sweeps the grid's points of those indices, increasing, without copying them
/// (every_second_point: the grid-error estimate); their intervals ignore GridPoint's middles.
Expected<TimeOptimalSolution> sweep(const std::vector<GridPoint>& grid, const TimeOptimalLimits& lim,
                                    const std::vector<double>* sigma, const std::vector<std::size_t>* points = nullptr);

}  // namespace geotraj::core::time_optimal_detail
