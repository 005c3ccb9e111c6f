#include "core/geometry/geometry_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "core/geometry/differential_geometry.hpp"
#include "core/format.hpp"

namespace geotraj::core {

namespace {


double angle_between(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

/// The geometry at one local parameter t of a segment, with d|dp/du|/du = T . p''.
struct Probe {
  double t = 0.0;
  LocalGeometry g;
  double speed_du = 0.0;
};

Probe probe_at(const Path& path, std::size_t segment, double t) {
  Jet jet;
  evaluate(path.segments[segment], t, kMaxJetOrder, jet);
  Probe p{t, local_geometry(jet, path.p_uu_noise[segment]), 0.0};
  if (p.g.regular) p.speed_du = p.g.T.dot(jet[2]);
  return p;
}

// The three tracked quantities, each to be maximised, and their derivatives in u (5.15, 5.21).
struct Quantity {
  double (*value)(const Probe&);
  double (*slope)(const Probe&);
};
constexpr Quantity kCurvature{[](const Probe& p) { return p.g.kappa; },
                              [](const Probe& p) { return p.g.has_normal ? p.g.kappa_du : 0.0; }};
constexpr Quantity kTorsion{[](const Probe& p) { return p.g.has_normal ? std::abs(p.g.tau) : -1.0; },
                            [](const Probe& p) { return p.g.has_normal ? std::copysign(p.g.tau_du, p.g.tau) : 0.0; }};
constexpr Quantity kSlowness{[](const Probe& p) { return -p.g.speed; }, [](const Probe& p) { return -p.speed_du; }};

/// The largest value of `q` near sample k: where its slope changes sign between k and a
/// neighbour, the zero of the slope by the Illinois variant of regula falsi (superlinear,
/// always bracketed); the sample itself if that is larger or no sign change is there.
Probe refine(const Path& path, std::size_t segment, const std::vector<Probe>& samples, std::size_t k, Quantity q) {
  const Probe& at_k = samples[k];
  const double slope_k = q.slope(at_k);
  Probe lo, hi;  // slope(lo) > 0 > slope(hi)
  if (slope_k > 0.0 && k + 1 < samples.size() && q.slope(samples[k + 1]) < 0.0) {
    lo = at_k, hi = samples[k + 1];
  } else if (slope_k < 0.0 && k > 0 && q.slope(samples[k - 1]) > 0.0) {
    lo = samples[k - 1], hi = at_k;
  } else {
    return at_k;
  }
  double f_lo = q.slope(lo), f_hi = q.slope(hi);
  Probe best = at_k;
  int side = 0;
  for (int it = 0; it < 40 && hi.t - lo.t > 1e-13; ++it) {
    const double t = (lo.t * f_hi - hi.t * f_lo) / (f_hi - f_lo);
    if (!(t > lo.t && t < hi.t)) break;
    const Probe p = probe_at(path, segment, t);
    if (q.value(p) > q.value(best)) best = p;
    const double f = q.slope(p);
    if (f == 0.0) break;
    if (f > 0.0) {
      lo = p, f_lo = f;
      if (side == 1) f_hi *= 0.5;  // Illinois: halve the end that stays
      side = 1;
    } else {
      hi = p, f_hi = f;
      if (side == -1) f_lo *= 0.5;
      side = -1;
    }
  }
  return best;
}

/// Two-point Hermite rule for the integral of f over [0, h] from f and f' at both ends: exact
/// for cubics, error h^5 f^(4) / 720 (the arc length between samples, f = |dp/du|).
double hermite(double h, double f0, double df0, double f1, double df1) {
  return 0.5 * h * (f0 + f1) + h * h / 12.0 * (df0 - df1);
}

}  // namespace

GeometryReport geometry_report(const Path& path, std::size_t max_points) {
  GeometryReport report;
  const std::size_t m = path.segment_count();
  const std::size_t n = std::clamp<std::size_t>(max_points / std::max<std::size_t>(m, 1), 16, 64);
  const double h = 1.0 / static_cast<double>(n);
  report.segments.resize(m);
  std::vector<Probe> samples(n + 1);
  std::vector<double> s(n + 1);  // arc length from the segment start [m]
  for (std::size_t i = 0; i < m; ++i) {
    std::size_t peak_kappa = 0, peak_tau = 0, min_speed = 0;
    bool any_torsion = false, has_T = false;
    double turning = 0.0;
    Eigen::Vector3d first_T = Eigen::Vector3d::Zero(), last_T = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k <= n; ++k) {
      samples[k] = probe_at(path, i, static_cast<double>(k) * h);
      const Probe& p = samples[k];
      s[k] = k == 0 ? 0.0 : s[k - 1] + hermite(h, samples[k - 1].g.speed, samples[k - 1].speed_du, p.g.speed, p.speed_du);
      if (p.g.kappa > samples[peak_kappa].g.kappa) peak_kappa = k;
      if (p.g.has_normal && (!any_torsion || std::abs(p.g.tau) > std::abs(samples[peak_tau].g.tau))) {
        peak_tau = k, any_torsion = true;
      }
      if (p.g.speed < samples[min_speed].g.speed) min_speed = k;
      if (!p.g.regular) continue;
      // The turning as the polygon of sampled tangents on the unit sphere: a lower bound of
      // the integral of kappa ds that stays finite (pi per sample) through a near-cusp.
      if (has_T) turning += angle_between(last_T, p.g.T);
      else first_T = p.g.T;
      last_T = p.g.T;
      has_T = true;
    }
    // Anchored to the segment's adaptive arc length (1e-12): the rule's error spread evenly.
    const double length = path.segment_lengths[i];
    if (s[n] > 0.0) {
      for (double& v : s) v *= length / s[n];
    }
    const double u0 = static_cast<double>(i);
    // s at a refined point: the arc length at the sample below it plus the rule to it.
    const auto extremum = [&](const Probe& p, double value) {
      const auto k = std::min<std::size_t>(static_cast<std::size_t>(p.t / h), n);
      const Probe& below = samples[k];
      const double ds = p.t > below.t ? hermite(p.t - below.t, below.g.speed, below.speed_du, p.g.speed, p.speed_du) : 0.0;
      return Extremum{value, u0 + p.t, path.cumulative_lengths[i] + std::min(s[k] + ds, length)};
    };
    SegmentGeometry& out = report.segments[i];

    // The curvature peaks at its largest sample, or, at a kink narrower than the sampling,
    // next to the smallest |dp/du|: both are refined, the larger kept.
    Probe kappa = refine(path, i, samples, peak_kappa, kCurvature);
    if (min_speed != peak_kappa) {
      const Probe kink = refine(path, i, samples, min_speed, kCurvature);
      if (kink.g.kappa > kappa.g.kappa) kappa = kink;
    }
    out.peak_curvature = extremum(kappa, kappa.g.kappa);
    if (any_torsion) {
      const Probe tau = refine(path, i, samples, peak_tau, kTorsion);
      out.peak_torsion = extremum(tau, tau.g.tau);
    } else {
      out.peak_torsion = Extremum{0.0, u0, path.cumulative_lengths[i]};
    }
    const Probe slow = refine(path, i, samples, min_speed, kSlowness);
    out.min_speed = extremum(slow, slow.g.speed);
    out.turning = turning;

    // Warnings: what the frames did not ask for.
    const std::string seg = "segment " + std::to_string(i);
    if (slow.t > 1e-9 && slow.t < 1.0 - 1e-9 && out.min_speed.value < kNearCuspFraction * length) {
      const Extremum& e = out.min_speed;
      report.warnings.push_back(
          {PathWarningCode::kNearCusp, i, e.u, e.s, e.value,
           seg + " nearly stops: |dp/du| falls to " + number(e.value, 4) + " m at u = " + number(e.u, 4) + " (s = " + number(e.s, 4) +
               " m), " + number(100.0 * e.value / length, 4) + " % of its mean, and bends there to curvature " +
               number(out.peak_curvature.value, 4) +
               " 1/m; no frame asked for a cusp: give smaller tangent scales, or a frame there"});
    }
    if (path.spec.max_curvature && out.peak_curvature.value > *path.spec.max_curvature) {
      const Extremum& e = out.peak_curvature;
      report.warnings.push_back({PathWarningCode::kTightBend, i, e.u, e.s, e.value,
                                 seg + " bends to curvature " + number(e.value, 4) + " 1/m (radius " + number(1.0 / e.value, 4) +
                                     " m) at u = " + number(e.u, 4) + " (s = " + number(e.s, 4) + " m), above maxCurvature " +
                                     number(*path.spec.max_curvature, 4) + " 1/m"});
    }
    if (has_T) {
      const double excess = turning - angle_between(first_T, last_T);
      if (excess > kTurnsBackExcess) {
        const Extremum& e = out.peak_curvature;
        report.warnings.push_back({PathWarningCode::kTurnsBack, i, e.u, e.s, excess,
                                   seg + " turns back on itself: its tangent turns " + number(turning, 4) + " rad in all, " +
                                       number(excess, 4) + " rad more than the angle between its end tangents (sharpest at u = " +
                                       number(e.u, 4) + ")"});
      }
    }
  }
  return report;
}

}  // namespace geotraj::core
