// IK round trips (thesis 6.4; closed loop FK(IK(x)) = x): random reachable poses, the FK of
// configurations uniform within the joint limits (fixed seed; GEOTRAJ_PROPERTY_CASES sets
// the count, default 10,000 per arm and seed kind), solved by solve_ik
//  - from a perturbed seed (the true configuration, every joint moved by up to 0.1 rad:
//    what a warm start sees after a jump of the input), with up to 5 restarts;
//  - from a fixed seed (the model's home), with up to 20 restarts (a cold solve).
// Each run prints its success rate, also from the seed alone (no restarts), and asserts at
// least 99.9 %. Every converged result meets both tolerances when checked with the public
// forward_kinematics (1e-9 m, 1e-9 rad, plus 1e-14 for the two evaluations' rounding), and
// every result, converged or not, is within the joint limits. A failing case prints the
// configuration and the seed in full (17 digits).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "core/robot/robot.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::IkOptions;
using core::JointVector;
using core::RobotModel;

std::string vec(const JointVector& q) {
  std::string out = "[";
  char buf[32];
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s%.17g", i ? ", " : "", q(i));
    out += buf;
  }
  return out + "]";
}

enum class SeedKind { kPerturbed, kHome };

void round_trips(const char* robot, SeedKind kind) {
  const RobotModel& m = *core::find_builtin_robot(robot);
  const auto n = static_cast<Eigen::Index>(m.dof());
  const int cases = property_case_count(10000);
  std::mt19937_64 rng(kPropertySeed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  IkOptions alone;  // no restarts
  IkOptions with_restarts;
  with_restarts.restarts = kind == SeedKind::kPerturbed ? 5 : 20;
  int from_seed = 0, converged = 0, reported = 0;
  long iterations = 0;
  double worst_p = 0.0, worst_r = 0.0;
  for (int c = 0; c < cases; ++c) {
    JointVector q(n), seed(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto& lim = m.limits[static_cast<std::size_t>(i)];
      q(i) = lim.min_position + unit(rng) * (lim.max_position - lim.min_position);
      seed(i) = kind == SeedKind::kPerturbed ? q(i) + 0.1 * (2.0 * unit(rng) - 1.0) : 0.0;
    }
    if (kind == SeedKind::kHome) seed = core::home_configuration(m);
    const Eigen::Isometry3d target = core::forward_kinematics(m, q);
    core::IkResult r = core::solve_ik(m, target, seed, alone);
    from_seed += r.converged;
    if (!r.converged) r = core::solve_ik(m, target, seed, with_restarts);
    iterations += r.iterations;
    bool inside = r.within_limits && r.q.size() == n;
    for (Eigen::Index i = 0; i < n && inside; ++i) {
      const auto& lim = m.limits[static_cast<std::size_t>(i)];
      inside = r.q(i) >= lim.min_position && r.q(i) <= lim.max_position;
    }
    EXPECT_TRUE(inside) << robot << " case " << c << ": result outside the limits " << vec(r.q);
    if (!r.converged) {
      if (reported++ < 5) {
        std::printf("  %s: not converged (case %d): q %s seed %s, errors %.3g m %.3g rad\n", robot, c, vec(q).c_str(),
                    vec(seed).c_str(), r.position_error, r.orientation_error);
      }
      continue;
    }
    ++converged;
    const Eigen::Isometry3d X = core::forward_kinematics(m, r.q);
    const double e_p = (X.translation() - target.translation()).norm();
    const double e_r = Eigen::AngleAxisd(target.linear() * X.linear().transpose()).angle();
    worst_p = std::max(worst_p, e_p);
    worst_r = std::max(worst_r, e_r);
    EXPECT_LE(e_p, 1e-9 + 1e-14) << robot << " case " << c << ": q " << vec(q) << " seed " << vec(seed);
    EXPECT_LE(e_r, 1e-9 + 1e-14) << robot << " case " << c << ": q " << vec(q) << " seed " << vec(seed);
  }
  const double rate = 100.0 * converged / cases;
  std::printf("IK round trip %s, %s seed: %d of %d converged (%.2f %%; %.2f %% from the seed alone), %.1f iterations "
              "on average, worst residuals %.2g m %.2g rad\n",
              robot, kind == SeedKind::kPerturbed ? "perturbed (0.1 rad)" : "home", converged, cases, rate,
              100.0 * from_seed / cases, static_cast<double>(iterations) / cases, worst_p, worst_r);
  EXPECT_GE(rate, 99.9) << robot;
}

TEST(IkRoundTrip, Pa10PerturbedSeed) { round_trips("pa10", SeedKind::kPerturbed); }
TEST(IkRoundTrip, Pa10HomeSeed) { round_trips("pa10", SeedKind::kHome); }
TEST(IkRoundTrip, Ur5PerturbedSeed) { round_trips("ur5", SeedKind::kPerturbed); }
TEST(IkRoundTrip, Ur5HomeSeed) { round_trips("ur5", SeedKind::kHome); }

}  // namespace
}  // namespace geotraj::test
