// Grids and limits shared by the jerk-limited timing tests (time_optimal_jerk_test.cpp,
// banded_ipm_test.cpp): a straight line, a two-joint path with smooth random q_s and q_ss,
// and limits for it. Lengths in m, joint units rad.
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>
#include <random>
#include <vector>

#include "core/planning/time_optimal.hpp"

namespace geotraj::optim::jerk_test {

inline constexpr double kInf = std::numeric_limits<double>::infinity();

/// n grid points evenly spread over a straight line of length L [m] (no joints).
inline std::vector<core::GridPoint> line_grid(std::size_t n, double L) {
  std::vector<core::GridPoint> g(n);
  for (std::size_t i = 0; i < n; ++i) g[i].s = L * static_cast<double>(i) / static_cast<double>(n - 1);
  return g;
}

/// The same line with two joints whose q_s, q_ss are smooth (seeded, deterministic) and a
/// curvature of 1 1/m.
inline std::vector<core::GridPoint> joint_grid(std::size_t n, double L) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::vector<core::GridPoint> g = line_grid(n, L);
  const double c[2][4] = {{U(rng), U(rng), U(rng), U(rng)}, {U(rng), U(rng), U(rng), U(rng)}};
  for (auto& p : g) {
    p.q_s.resize(2);
    p.q_ss.resize(2);
    for (int j = 0; j < 2; ++j) {
      const double w = 3.0 + c[j][2];
      p.q_s(j) = 1.2 * c[j][0] + 0.5 * std::sin(w * p.s + c[j][3]);
      p.q_ss(j) = 0.5 * w * std::cos(w * p.s + c[j][3]);
    }
    p.kappa = 1.0;
  }
  return g;
}

/// Limits for joint_grid: 1 rad/s, 2 rad/s^2, 1 m/s, 3 m/s^2 tangential and centripetal.
inline core::TimeOptimalLimits joint_limits() {
  core::TimeOptimalLimits lim;
  lim.joint_velocity = core::JointVector::Constant(2, 1.0);
  lim.joint_acceleration = core::JointVector::Constant(2, 2.0);
  lim.speed = 1.0;
  lim.tangential = 3.0;
  lim.centripetal = 3.0;
  return lim;
}

}  // namespace geotraj::optim::jerk_test
