// The outcome of an optimiser: a report, not an exception (Ceres's Summary). Every optimiser
// returns its result together with one of these.
#pragma once

#include <string>

namespace geotraj::optim {

/// How an optimiser ended (proto OptimizerStatus).
enum class OptimizerStatus {
  kConverged,       ///< converged to the solver's tolerance
  kIterationLimit,  ///< stopped at the iteration limit; the best point found is returned
  kTimeLimit,       ///< stopped at the time budget or the deadline; the best point found is returned
  kNoImprovement,   ///< nothing better than the start was found: the start is returned
  kFailed,          ///< the solver failed (see `message`): the start is returned
};

/// What an optimiser did. Objectives in their own unit (documented per optimiser).
struct OptimizerReport {
  double objective_before = 0.0;
  double objective_after = 0.0;
  int iterations = 0;
  OptimizerStatus status = OptimizerStatus::kFailed;
  double seconds = 0.0;  ///< wall-clock time [s]
  std::string message;   ///< the solver's own words, when it has any
};

}  // namespace geotraj::optim

namespace geotraj::optim {

/// The status's name, for logs and messages ("converged", "iteration limit", ...).
const char* name(OptimizerStatus status);

}  // namespace geotraj::optim
