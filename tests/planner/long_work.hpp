// Requests whose planning takes seconds, one per kind of long work the planner runs under its
// budget: the breakpoint optimiser (Table B.1, 12,000 evaluations), the robot's joint-space
// pass (the PA-10 along demo path C, 600,000 samples of IK) and an analysis of 10^6 points.
// (The jerk-limited timing of the demonstration takes about 60 ms: the server's concurrency
// tests cancel it.) Shared by the planner's tests (a cancelled or expired budget stops each)
// and bench_planner (how soon).
#pragma once

#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "appendix_b_paths.hpp"
#include "core/robot/robot.hpp"
#include "planner/planner.hpp"
#include "thesis_paths.hpp"

namespace geotraj::testing {

enum class LongWork { kBreakpoints, kRobotPass, kAnalysis };

inline std::string name(LongWork work) {
  switch (work) {
    case LongWork::kBreakpoints: return "breakpoints";
    case LongWork::kRobotPass: return "robot_pass";
    case LongWork::kAnalysis: return "analysis";
  }
  return "unknown";
}

/// For GoogleTest's parameter names.
inline void PrintTo(LongWork work, std::ostream* os) { *os << name(work); }

inline const std::vector<LongWork> kLongWork = {LongWork::kBreakpoints, LongWork::kRobotPass, LongWork::kAnalysis};

/// Points of the long analysis.
inline constexpr std::size_t kLongAnalysisPoints = 1'000'000;

inline std::shared_ptr<const planner::Robot> pa10() {
  const core::RobotModel* model = core::find_builtin_robot("pa10");
  if (model == nullptr) return nullptr;
  auto robot = std::make_shared<planner::Robot>(core::ValidRobot::check(*model).value(), core::home_configuration(*model));
  robot->report_only = true;
  return robot;
}

inline planner::Request long_request(LongWork work) {
  planner::Request request;
  switch (work) {
    case LongWork::kBreakpoints: {
      request.geometry = table_b1_path();
      planner::Optimize optimize;
      optimize.breakpoints = optim::BreakpointOptions{};
      optimize.budget_s = 60.0;
      request.optimize = optimize;
      break;
    }
    case LongWork::kRobotPass: {
      request.geometry = thesis_demo_path('C', core::BlendMethod::kPolynomial, core::UnspecifiedConstraints::kSmoothest);
      core::MotionSpec motion;
      motion.duration_s = 600.0;
      motion.cycle_rate_hz = 1000.0;
      request.motion = motion;
      request.robot = pa10();
      break;
    }
    case LongWork::kAnalysis:
      request.geometry = thesis_demo_path('A', core::BlendMethod::kPolynomial, core::UnspecifiedConstraints::kSmoothest);
      break;
  }
  return request;
}

/// Runs `work` under `budget` and returns the planner's result (the plan's or the analysis's
/// error, if any).
inline std::optional<planner::Error> run_long_work(LongWork work, const planner::Request& request,
                                                   const planner::Budget& budget) {
  if (work == LongWork::kAnalysis) {
    auto analysis = planner::analyze(request, kLongAnalysisPoints, budget);
    if (!analysis) return analysis.error();
    return std::nullopt;
  }
  auto plan = planner::plan(request, budget, planner::Limits{});
  if (!plan) return plan.error();
  return std::nullopt;
}

}  // namespace geotraj::testing
