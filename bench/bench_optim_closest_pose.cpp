// Where least squares fit outside optim/redundancy: the closest reachable pose of an
// out-of-reach target (ComputeInverseKinematics's answer when no joints reach it), by the
// hand-written Levenberg-Marquardt of core::closest_pose against the same problem on Ceres
// Solver (residual [p(q) - p_t; log(R(q) R_t^T)], the same exact Jacobian, the joint limits
// as Ceres's parameter bounds, Levenberg-Marquardt with a dense QR). The same starts and
// targets for both: 64 targets 1.3x beyond the arm's reach in random directions with random
// orientations, each from a random configuration within the limits (seeded). Counters: the
// mean |e|^2 [m^2 + rad^2] reached, and how often Ceres ends lower than the hand-written
// solver by more than 1e-9 (and the reverse).
// Run: build/bench/bench_optim_closest_pose --benchmark_repetitions=3
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <ceres/ceres.h>

#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"

namespace {

using namespace geotraj;
using core::JointVector;

struct Case {
  Eigen::Isometry3d target;
  JointVector start;
};

std::vector<Case> cases(const core::RobotModel& robot) {
  std::mt19937_64 random(20261206);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const auto n = static_cast<Eigen::Index>(robot.dof());
  // The reach: the farthest the tool gets from the base over random configurations.
  const Eigen::Vector3d base = robot.base.translation();
  const auto random_q = [&] {
    JointVector q(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const core::JointLimits& l = robot.limits[static_cast<std::size_t>(i)];
      q(i) = 0.5 * (l.min_position + l.max_position) + 0.5 * unit(random) * (l.max_position - l.min_position);
    }
    return q;
  };
  double reach = 0.0;
  for (int k = 0; k < 2000; ++k) reach = std::max(reach, (core::forward_kinematics(robot, random_q()).translation() - base).norm());
  std::vector<Case> out;
  for (int k = 0; k < 64; ++k) {
    const Eigen::Vector3d direction = Eigen::Vector3d(unit(random), unit(random), unit(random)).normalized();
    Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
    target.translation() = base + 1.3 * reach * direction;
    target.linear() = Eigen::Quaterniond(unit(random), unit(random), unit(random), unit(random)).normalized().toRotationMatrix();
    out.push_back({target, random_q()});
  }
  return out;
}

double merit(const core::RobotModel& robot, const JointVector& q, const Eigen::Isometry3d& target) {
  const Eigen::Isometry3d X = core::forward_kinematics(robot, q);
  const Eigen::AngleAxisd turn(X.linear() * target.linear().transpose());
  return (X.translation() - target.translation()).squaredNorm() + turn.angle() * turn.angle();
}

// r = [p(q) - p_t; log(R(q) R_t^T)], dr/dq the geometric Jacobian with its orientation rows
// mapped by SO(3)'s inverse right Jacobian (as core's solver).
class PoseCost final : public ceres::CostFunction {
 public:
  PoseCost(const core::RobotModel& robot, const Eigen::Isometry3d& target) : robot_(robot), target_(target) {
    set_num_residuals(6);
    mutable_parameter_block_sizes()->push_back(static_cast<int>(robot.dof()));
  }
  bool Evaluate(double const* const* q, double* r, double** jac) const override {
    const auto n = static_cast<Eigen::Index>(robot_.dof());
    Eigen::Isometry3d X;
    core::JointJacobian J;
    core::forward_kinematics(robot_, Eigen::Map<const Eigen::VectorXd>(q[0], n), X, J);
    const Eigen::AngleAxisd turn(X.linear() * target_.linear().transpose());
    Eigen::Map<Eigen::Matrix<double, 6, 1>> residual(r);
    residual.head<3>() = X.translation() - target_.translation();
    residual.tail<3>() = turn.angle() * turn.axis();
    if (jac && jac[0]) {
      // The orientation rows exact, as core's: d log(R R_t^T) = J_r^-1(phi) d omega, phi =
      // log(R_t R^T) = -r_rot (SO(3)'s inverse right Jacobian).
      const Eigen::Vector3d phi = -residual.tail<3>();
      const double theta = phi.norm();
      Eigen::Matrix3d hat;
      hat << 0.0, -phi.z(), phi.y(), phi.z(), 0.0, -phi.x(), -phi.y(), phi.x(), 0.0;
      const double c = theta < 1e-4 ? 1.0 / 12.0 + theta * theta / 720.0
                                    : 1.0 / (theta * theta) - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
      J.bottomRows<3>() = (Eigen::Matrix3d::Identity() + 0.5 * hat + c * hat * hat) * J.bottomRows<3>();
      Eigen::Map<Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::RowMajor>>(jac[0], 6, n) = J;
    }
    return true;
  }

 private:
  const core::RobotModel& robot_;
  Eigen::Isometry3d target_;
};

JointVector ceres_closest(const core::RobotModel& robot, const Case& c, int& iterations) {
  std::vector<double> x(c.start.data(), c.start.data() + c.start.size());
  ceres::Problem problem;
  problem.AddResidualBlock(new PoseCost(robot, c.target), nullptr, x.data());
  for (std::size_t i = 0; i < robot.dof(); ++i) {
    problem.SetParameterLowerBound(x.data(), static_cast<int>(i), robot.limits[i].min_position);
    problem.SetParameterUpperBound(x.data(), static_cast<int>(i), robot.limits[i].max_position);
  }
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_QR;
  o.max_num_iterations = 200;
  o.function_tolerance = 1e-14;
  o.parameter_tolerance = 1e-12;
  o.gradient_tolerance = 1e-14;
  o.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem, &summary);
  iterations = static_cast<int>(summary.iterations.size());
  return Eigen::Map<const Eigen::VectorXd>(x.data(), static_cast<Eigen::Index>(x.size()));
}

// range(0): 0 the hand-written LM (core::closest_pose), 1 Ceres; range(1): 0 the UR5, 1 the PA-10.
void BM_ClosestPose(benchmark::State& state) {
  const char* name = state.range(1) == 0 ? "ur5" : "pa10";
  const core::ValidRobot robot = *core::ValidRobot::check(*core::find_builtin_robot(name));
  const std::vector<Case> all = cases(robot);
  std::vector<JointVector> found(all.size());
  long iterations = 0;
  for (auto _ : state) {
    iterations = 0;
    for (std::size_t k = 0; k < all.size(); ++k) {
      int it = 0;
      if (state.range(0) == 0) {
        const core::IkResult r = core::closest_pose(robot, all[k].target, all[k].start);
        found[k] = r.q;
        it = r.iterations;
      } else {
        found[k] = ceres_closest(robot, all[k], it);
      }
      iterations += it;
    }
    benchmark::DoNotOptimize(found);
  }
  double sum = 0.0;
  int lower = 0, higher = 0;
  for (std::size_t k = 0; k < all.size(); ++k) {
    const double m = merit(robot, found[k], all[k].target);
    sum += m;
    int it = 0;
    const double other = state.range(0) == 0 ? merit(robot, ceres_closest(robot, all[k], it), all[k].target)
                                             : merit(robot, core::closest_pose(robot, all[k].target, all[k].start).q,
                                                     all[k].target);
    if (m < other - 1e-9) ++lower;
    if (m > other + 1e-9) ++higher;
  }
  state.SetLabel(std::string(name) + ", 64 out-of-reach targets, " + (state.range(0) == 0 ? "hand-written LM" : "Ceres LM"));
  state.counters["mean_merit"] = sum / static_cast<double>(all.size());
  state.counters["lower_than_other"] = lower;
  state.counters["higher_than_other"] = higher;
  state.counters["iterations_per_target"] = static_cast<double>(iterations) / static_cast<double>(all.size());
}
BENCHMARK(BM_ClosestPose)->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
