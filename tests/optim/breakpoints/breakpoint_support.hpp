// Independent measures for the breakpoint optimiser's tests: the objectives recomputed from
// core::analyze's dense profile (not from the optimiser's own sampling), and checks that a
// result's breakpoints are well formed.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "core/geometry/analysis.hpp"
#include "core/geometry/path.hpp"
#include "optim/breakpoints/breakpoints.hpp"

namespace geotraj::testing {

/// Largest |tau| or kappa over `per_segment` analyze points per segment, frames included.
/// Optionally restricted to global u in [u_lo, u_hi].
inline double dense_peak(const core::Path& path, optim::BreakpointObjective objective, int per_segment = 20000,
                         double u_lo = -1.0, double u_hi = 1e9) {
  const std::size_t m = path.segment_count();
  const auto profile = core::analyze(path, m * per_segment + 1);
  const auto value = [&](const core::ProfilePoint& p) {
    if (objective == optim::BreakpointObjective::kPeakCurvature) return p.geometry.kappa;
    return p.geometry.has_normal ? std::abs(p.geometry.tau) : 0.0;
  };
  double peak = 0.0;
  for (const auto& p : profile) {
    if (p.u >= u_lo && p.u <= u_hi) peak = std::max(peak, value(p));
  }
  return peak;
}

/// Largest |d^n x_a/du^n| over dense points of every segment and axis (n: the trapezoid's order).
inline double dense_derivative_peak(const core::Path& path, int per_segment = 20000) {
  double peak = 0.0;
  for (const auto& segment : path.segments) {
    const auto& trap = std::get<core::TrapezoidSegment>(segment);
    for (const auto& axis : trap.axes) {
      double d[core::kMaxJetOrder + 2];
      for (int i = 0; i <= per_segment; ++i) {
        core::evaluate(axis, static_cast<double>(i) / per_segment, axis.n, d);
        peak = std::max(peak, std::abs(d[axis.n]));
      }
    }
  }
  return peak;
}

inline double dense_objective(const core::Path& path, optim::BreakpointObjective objective) {
  return objective == optim::BreakpointObjective::kPeakDerivatives ? dense_derivative_peak(path)
                                                                   : dense_peak(path, objective);
}

/// "" when every segment has x, y, z lists of 2n + 2 values, 0 first, 1 last, ordered, with
/// u_1 > u_0; else what is wrong.
inline std::string breakpoint_problem(const core::Path& path, const std::vector<core::SegmentBreakpoints>& bps) {
  if (bps.size() != path.segment_count()) return "one entry per segment expected";
  for (std::size_t i = 0; i < bps.size(); ++i) {
    if (bps[i].segment != i) return "entry " + std::to_string(i) + " names segment " + std::to_string(bps[i].segment);
    const int n = std::get<core::TrapezoidSegment>(path.segments[i]).axes[0].n;
    for (const auto* list : {&bps[i].x, &bps[i].y, &bps[i].z}) {
      if (list->size() != static_cast<std::size_t>(2 * n + 2)) return "segment " + std::to_string(i) + ": wrong size";
      if (list->front() != 0.0 || list->back() != 1.0) return "segment " + std::to_string(i) + ": not from 0 to 1";
      if (!std::is_sorted(list->begin(), list->end())) return "segment " + std::to_string(i) + ": not ordered";
      if (!((*list)[1] > (*list)[0])) return "segment " + std::to_string(i) + ": first ramp without width";
    }
  }
  return {};
}

/// A random TRAPEZOIDAL path of 3 or 4 frames (per arc length), some with curvature and
/// torsion; printed by describe() for replay.
inline core::PathSpec random_trapezoid_path(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> ud(-1.0, 1.0);
  const auto unit = [&] {
    Eigen::Vector3d v;
    do v = {ud(rng), ud(rng), ud(rng)};
    while (v.norm() < 0.2 || v.norm() > 1.0);
    return Eigen::Vector3d(v.normalized());
  };
  core::PathSpec spec;
  spec.blend = core::BlendMethod::kTrapezoidal;
  const int frames = 3 + static_cast<int>(rng() % 2);
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int i = 0; i < frames; ++i) {
    core::KeyFrame f;
    f.p_W = p;
    f.T_W = unit();
    if (rng() % 3 != 0) {
      Eigen::Vector3d n = unit();
      n = (n - n.dot(f.T_W) * f.T_W).normalized();
      f.N_W = n;
      f.kappa = 0.5 + 1.5 * (ud(rng) + 1.0);
      if (rng() % 2 == 0) f.tau = 2.0 * ud(rng);
    }
    spec.frames.push_back(f);
    p += 0.6 * unit() + Eigen::Vector3d(0.8, 0.0, 0.0);
  }
  return spec;
}

/// The spec as text, to replay a failing random case.
inline std::string describe(const core::PathSpec& spec) {
  std::string s;
  char buf[512];
  for (const auto& f : spec.frames) {
    std::snprintf(buf, sizeof buf, "{p: [%.17g, %.17g, %.17g], T: [%.17g, %.17g, %.17g]", f.p_W.x(), f.p_W.y(), f.p_W.z(),
                  f.T_W.x(), f.T_W.y(), f.T_W.z());
    s += buf;
    if (f.N_W) {
      std::snprintf(buf, sizeof buf, ", N: [%.17g, %.17g, %.17g], kappa: %.17g", f.N_W->x(), f.N_W->y(), f.N_W->z(),
                    *f.kappa);
      s += buf;
    }
    if (f.tau) {
      std::snprintf(buf, sizeof buf, ", tau: %.17g", *f.tau);
      s += buf;
    }
    s += "}\n";
  }
  return s;
}

}  // namespace geotraj::testing
