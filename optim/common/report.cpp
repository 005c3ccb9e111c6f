#include "optim/common/report.hpp"

namespace geotraj::optim {

const char* name(OptimizerStatus status) {
  switch (status) {
    case OptimizerStatus::kConverged: return "converged";
    case OptimizerStatus::kIterationLimit: return "iteration limit";
    case OptimizerStatus::kTimeLimit: return "time limit";
    case OptimizerStatus::kNoImprovement: return "no improvement";
    case OptimizerStatus::kFailed: return "failed";
  }
  return "unknown";
}

}  // namespace geotraj::optim
