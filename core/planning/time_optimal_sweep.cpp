// The sweep over one portion's grid (time_optimal.hpp, "Sweep"): each interval's polygon in
// (b, u) from the limits at both of its ends, the controllable sets backward (the polygon's
// projection by Newton's steps), the largest admissible u forward, the profile and what binds on each
// interval.
#include "core/planning/time_optimal_detail.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "core/format.hpp"

namespace geotraj::core {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Directions of the angular acceleration's support rows over a half turn (two-sided rows
// cover the other half): 16 over the full turn.
constexpr int kAngularRows = 8;
constexpr double kAngularInscribed = 0.98078528040323044913;  // cos(pi / 16)

/// Which constraint a bound comes from.
struct Source {
  BindingKind kind = BindingKind::kCartesianSpeed;
  std::size_t joint = 0;
  bool next = false;  ///< the next point's controllable set, not a limit
};

/// A bound on u linear in x = b: u >= c0 + c1 x (lower) or u <= c0 + c1 x (upper).
struct Line {
  double c0 = 0.0, c1 = 0.0;
  Source src;
};

/// Scratch of one interval's polygon (fixed capacity: no allocation in the sweep).
struct Polygon {
  static constexpr std::size_t kCap = 5 * kMaxJoints + 4 + 2 * kAngularRows;
  std::array<Line, kCap> lower, upper;
  std::size_t n_lower = 0, n_upper = 0;
  double x_max = kInf;  ///< bounds on x alone (joint acceleration with no u term)
  Source x_max_src;
  void clear() {
    n_lower = n_upper = 0;
    x_max = kInf;
  }
  void add_lower(double c0, double c1, Source s) { lower[n_lower++] = {c0, c1, s}; }
  void add_upper(double c0, double c1, Source s) { upper[n_upper++] = {c0, c1, s}; }
  void add_x_max(double x, Source s) {
    if (x < x_max) x_max = x, x_max_src = s;
  }
  /// -a <= A u + C x <= a.
  void add_two_sided(double A, double C, double a, Source s) {
    if (!(a < kInf)) return;
    const double scale = std::abs(C) + 1.0;
    if (std::abs(A) <= 1e-13 * scale) {
      if (C != 0.0) add_x_max(a / std::abs(C), s);
      return;
    }
    if (A > 0.0) {
      add_upper(a / A, -C / A, s);
      add_lower(-a / A, -C / A, s);
    } else {
      add_upper(-a / A, -C / A, s);
      add_lower(a / A, -C / A, s);
    }
  }
  /// lo <= A u + C x <= hi with lo <= 0 <= hi (a torque's range less its gravity part).
  void add_ranged(double A, double C, double lo, double hi, Source s) {
    if (std::abs(A) <= 1e-13 * (std::abs(C) + 1.0)) {
      if (C > 0.0) add_x_max(hi / C, s);
      if (C < 0.0) add_x_max(lo / C, s);
      return;
    }
    if (A > 0.0) {
      add_upper(hi / A, -C / A, s);
      add_lower(lo / A, -C / A, s);
    } else {
      add_upper(lo / A, -C / A, s);
      add_lower(hi / A, -C / A, s);
    }
  }
};

/// Per grid point: the largest b the point's own limits allow, and what sets it.
struct PointCap {
  double x = kInf;
  Source src;
};

PointCap point_cap(const GridPoint& g, const TimeOptimalLimits& lim, double sigma) {
  PointCap c;
  auto take = [&](double x, Source s) {
    if (x < c.x) c.x = x, c.src = s;
  };
  for (Eigen::Index j = 0; j < g.q_s.size(); ++j) {
    const double qs = std::abs(g.q_s(j)), v = lim.joint_velocity(j) * sigma;
    if (qs > 0.0 && v < kInf) take((v / qs) * (v / qs), {BindingKind::kJointVelocity, static_cast<std::size_t>(j)});
  }
  if (lim.speed < kInf) take(lim.speed * lim.speed, {BindingKind::kCartesianSpeed, 0});
  if (g.kappa > 0.0 && lim.centripetal < kInf)
    take(lim.centripetal * sigma * sigma / g.kappa, {BindingKind::kCentripetalAcceleration, 0});
  const double w = g.omega_s.norm();
  if (w > 0.0 && lim.angular_speed < kInf) {
    const double v = lim.angular_speed * sigma / w;
    take(v * v, {BindingKind::kAngularSpeed, 0});
  }
  return c;
}

/// The smallest upper bound on u at x = b_i of an interval's rows: what the forward pass
/// needs of the polygon, without building it.
struct UpperAt {
  double x = 0.0, u = kInf;
  void add_upper(double c0, double c1, Source) { u = std::min(u, c0 + c1 * x); }
  void add_lower(double, double, Source) {}
  void add_x_max(double, Source) {}
  void add_two_sided(double A, double C, double a, Source) {  // as Polygon's upper lines
    if (!(a < kInf) || std::abs(A) <= 1e-13 * (std::abs(C) + 1.0)) return;
    u = std::min(u, ((A > 0.0 ? a : -a) - C * x) / A);
  }
  void add_ranged(double A, double C, double lo, double hi, Source) {  // as Polygon's upper lines
    if (std::abs(A) <= 1e-13 * (std::abs(C) + 1.0)) return;
    u = std::min(u, ((A > 0.0 ? hi : lo) - C * x) / A);
  }
};

// |A u + C x| <= a for vectors A, C: support rows d . (A u + C x) <= a cos(pi / 16) over
// kAngularRows directions d of the plane of A and C (two-sided: both half turns).
template <class Rows>
void add_norm_rows(const Eigen::Vector3d& A, const Eigen::Vector3d& C, double a, Source src, Rows& p) {
  if (!(a < kInf)) return;
  const double nA = A.norm(), nC = C.norm();
  if (!(nA > 0.0 || nC > 0.0)) return;
  const Eigen::Vector3d e1 = nA >= nC ? Eigen::Vector3d(A / nA) : Eigen::Vector3d(C / nC);
  Eigen::Vector3d e2 = (nA >= nC ? C : A) - e1 * e1.dot(nA >= nC ? C : A);
  e2 = e2.norm() > 1e-12 * std::max(nA, nC) ? Eigen::Vector3d(e2.normalized()) : Eigen::Vector3d(e1.unitOrthogonal());
  for (int k = 0; k < kAngularRows; ++k) {
    const double th = 3.14159265358979323846 * k / kAngularRows;
    const Eigen::Vector3d d = std::cos(th) * e1 + std::sin(th) * e2;
    p.add_two_sided(d.dot(A), d.dot(C), a * kAngularInscribed, src);
  }
}

/// Whether the grid point carries torque terms and the limits limit torques.
bool has_torques(const GridPoint& g, const TimeOptimalLimits& lim) {
  return lim.joint_torque.size() == g.q_s.size() && g.tau_a.size() == g.q_s.size() && g.q_s.size() > 0;
}

/// The rows of interval i's polygon (points g0 = s_i, g1 = s_{i+1}, ds = s_{i+1} - s_i),
/// given to `p` (a Polygon, or UpperAt): the joint accelerations at both ends (and the middle
/// where `middle` and the point carries it) and the tangential limit; the next set is added
/// by the caller.
template <class Rows>
void interval_rows(const GridPoint& g0, const GridPoint& g1, double ds, const TimeOptimalLimits& lim, double sig0,
                   double sig1, bool middle, Rows& p) {
  for (Eigen::Index j = 0; j < g0.q_s.size(); ++j) {
    const Source src{BindingKind::kJointAcceleration, static_cast<std::size_t>(j)};
    const double a0 = lim.joint_acceleration(j) * sig0 * sig0, a1 = lim.joint_acceleration(j) * sig1 * sig1;
    p.add_two_sided(g0.q_s(j), g0.q_ss(j), a0, src);  // q_ddot at s_i
    // q_ddot at s_{i+1} with b_{i+1} = b_i + 2 ds u: (q_s + 2 ds q_ss) u + q_ss b_i.
    p.add_two_sided(g1.q_s(j) + 2.0 * ds * g1.q_ss(j), g1.q_ss(j), a1, src);
  }
  if (middle && g0.q_s_mid.size() == g0.q_s.size() && g0.q_ss_mid.size() == g0.q_s.size()) {
    // At the middle, b = b_i + ds u: q_ddot = (q_s + ds q_ss) u + q_ss b_i, and the velocity
    // limit b_i + ds u <= (v / |q_s|)^2, under the smaller of the ends' scales.
    const double sig = std::min(sig0, sig1);
    for (Eigen::Index j = 0; j < g0.q_s.size(); ++j) {
      p.add_two_sided(g0.q_s_mid(j) + ds * g0.q_ss_mid(j), g0.q_ss_mid(j), lim.joint_acceleration(j) * sig * sig,
                      {BindingKind::kJointAcceleration, static_cast<std::size_t>(j)});
      const double qs = std::abs(g0.q_s_mid(j)), v = lim.joint_velocity(j) * sig;
      if (qs > 0.0 && v < kInf && ds > 0.0) {
        const double cap = (v / qs) * (v / qs);
        p.add_upper(cap / ds, -1.0 / ds, {BindingKind::kJointVelocity, static_cast<std::size_t>(j)});
      }
    }
  }
  if (has_torques(g0, lim)) {
    // tau = tau_a u + tau_b b + tau_c at both ends (b_{i+1} = b_i + 2 ds u), the part beyond
    // gravity's within the limit's range less tau_c, scaled as the accelerations.
    for (Eigen::Index j = 0; j < g0.q_s.size(); ++j) {
      const double T = lim.joint_torque(j);
      if (!(T < kInf)) continue;
      const Source src{BindingKind::kJointTorque, static_cast<std::size_t>(j)};
      const double f0 = sig0 * sig0 * lim.torque_dynamic_scale, f1 = sig1 * sig1 * lim.torque_dynamic_scale;
      p.add_ranged(g0.tau_a(j), g0.tau_b(j), (-T - g0.tau_c(j)) * f0, (T - g0.tau_c(j)) * f0, src);
      p.add_ranged(g1.tau_a(j) + 2.0 * ds * g1.tau_b(j), g1.tau_b(j), (-T - g1.tau_c(j)) * f1, (T - g1.tau_c(j)) * f1,
                   src);
    }
  }
  if (lim.tangential < kInf) {
    p.add_upper(lim.tangential, 0.0, {BindingKind::kTangentialAcceleration, 0});
    p.add_lower(-lim.tangential, 0.0, {BindingKind::kTangentialAcceleration, 0});
  }
  if (lim.angular_acceleration < kInf) {  // alpha at both ends, as the joints' accelerations
    const Source src{BindingKind::kAngularAcceleration, 0};
    add_norm_rows(g0.omega_s, g0.omega_ss, lim.angular_acceleration * sig0 * sig0, src, p);
    add_norm_rows(g1.omega_s + 2.0 * ds * g1.omega_ss, g1.omega_ss, lim.angular_acceleration * sig1 * sig1, src, p);
  }
}

// The range [x_lo, x_hi] of x = b_i over which some u satisfies every lower and upper line
// of `p` (max_l l(x) <= min_u u(x)), x_lo from 0 and x_hi from the point's own cap, as given.
// F(x) = max_l l(x) - min_u u(x) is convex and piecewise linear: Newton's steps from the
// cap leftwards (and from 0 rightwards) reach the range's ends from outside, each landing on
// the intersection of the pair of lines active where it starts (a subgradient step never
// passes the root), so that a few evaluations of the lines replace the pairwise
// Fourier-Motzkin elimination of every (lower, upper) pair: one to three on the joint paths'
// and Cartesian paths' grids, against some 600 pairs per interval. False: not settled in
// kNewtonSteps (the caller falls back to the pairs).
struct Active {
  double F = 0.0, slope = 0.0, scale = 0.0;
  const Line* lower = nullptr;
  const Line* upper = nullptr;
};

/// F at x with the pair active there; `leftwards`: the pair that stays active just left of
/// x (the left derivative), else just right of it.
Active active_at(const Polygon& p, double x, bool leftwards) {
  Active a;
  double lv = -kInf, uv = kInf;
  for (std::size_t i = 0; i < p.n_lower; ++i) {
    const Line& l = p.lower[i];
    const double v = l.c0 + l.c1 * x;
    if (v > lv || (v == lv && (leftwards ? l.c1 < a.lower->c1 : l.c1 > a.lower->c1))) lv = v, a.lower = &l;
  }
  for (std::size_t i = 0; i < p.n_upper; ++i) {
    const Line& u = p.upper[i];
    const double v = u.c0 + u.c1 * x;
    if (v < uv || (v == uv && (leftwards ? u.c1 > a.upper->c1 : u.c1 < a.upper->c1))) uv = v, a.upper = &u;
  }
  a.F = lv - uv;
  a.slope = a.lower->c1 - a.upper->c1;
  // The rounding of l(x) and u(x): of the order of their terms' magnitudes.
  a.scale = std::abs(a.lower->c0) + std::abs(a.lower->c1 * x) + std::abs(a.upper->c0) + std::abs(a.upper->c1 * x);
  return a;
}

constexpr int kNewtonSteps = 64;

bool feasible_range(const Polygon& p, double& x_lo, double& x_hi, Source& hi_src, bool& empty) {
  if (p.n_lower == 0 || p.n_upper == 0 || !std::isfinite(x_hi)) return false;
  double x = x_hi;
  for (int step = 0;; ++step) {
    if (step == kNewtonSteps) return false;
    const Active a = active_at(p, x, true);
    if (!(std::isfinite(a.F) && std::isfinite(a.slope))) return false;
    if (a.F <= 1e-12 * a.scale) break;
    if (!(a.slope > 0.0)) {  // positive and not decreasing leftwards: no x at or below x_hi
      empty = true;
      return true;
    }
    const double next = x - a.F / a.slope;
    if (!(next < x)) break;  // the root within rounding of x
    x = next;
    hi_src = a.upper->src.next ? a.lower->src : a.upper->src;
  }
  x_hi = x;
  x = x_lo;
  for (int step = 0;; ++step) {
    if (step == kNewtonSteps) return false;
    const Active a = active_at(p, x, false);
    if (!(std::isfinite(a.F) && std::isfinite(a.slope))) return false;
    if (a.F <= 1e-12 * a.scale) break;
    if (!(a.slope < 0.0)) {  // positive and not decreasing rightwards: no x at or above x_lo
      empty = true;
      return true;
    }
    const double next = x - a.F / a.slope;
    if (!(next > x)) break;
    x = next;
    if (x > x_hi) break;  // past the upper end: the caller finds the range empty
  }
  x_lo = x;
  return true;
}

/// The same range by Fourier-Motzkin over every (lower, upper) pair: l(x) <= u(x).
void pairwise_range(const Polygon& p, double& x_lo, double& x_hi, Source& hi_src, bool& empty) {
  for (std::size_t a = 0; a < p.n_lower; ++a) {
    const Line& l = p.lower[a];
    for (std::size_t c = 0; c < p.n_upper; ++c) {
      const Line& up = p.upper[c];
      const double slope = l.c1 - up.c1, rhs = up.c0 - l.c0;  // slope x <= rhs
      const double tol = 1e-14 * (std::abs(l.c1) + std::abs(up.c1));
      if (slope > tol) {
        const double x = rhs / slope;
        if (x < x_hi) x_hi = x, hi_src = up.src.next ? l.src : up.src;
      } else if (slope < -tol) {
        x_lo = std::max(x_lo, rhs / slope);
      } else if (rhs < -1e-12 * (std::abs(up.c0) + std::abs(l.c0))) {
        empty = true;
      }
    }
  }
}

/// Usage of every constraint on interval i at the solution; the largest.
struct Usage {
  Source src;
  double value = 0.0, limit = 0.0, ratio = -1.0;
};

Usage interval_usage(const GridPoint& g0, const GridPoint& g1, double x0, double x1, double u,
                     const TimeOptimalLimits& lim) {
  Usage best;
  auto take = [&](Source s, double value, double limit) {
    if (!(limit < kInf)) return;
    const double r = value / limit;
    if (r > best.ratio) best = {s, value, limit, r};
  };
  const double v0 = std::sqrt(x0), v1 = std::sqrt(x1);
  for (Eigen::Index j = 0; j < g0.q_s.size(); ++j) {
    const std::size_t jj = static_cast<std::size_t>(j);
    take({BindingKind::kJointVelocity, jj}, std::max(std::abs(g0.q_s(j)) * v0, std::abs(g1.q_s(j)) * v1),
         lim.joint_velocity(j));
    take({BindingKind::kJointAcceleration, jj},
         std::max(std::abs(g0.q_s(j) * u + g0.q_ss(j) * x0), std::abs(g1.q_s(j) * u + g1.q_ss(j) * x1)),
         lim.joint_acceleration(j));
  }
  if (has_torques(g0, lim) && has_torques(g1, lim)) {
    for (Eigen::Index j = 0; j < g0.q_s.size(); ++j) {
      take({BindingKind::kJointTorque, static_cast<std::size_t>(j)},
           std::max(std::abs(g0.tau_a(j) * u + g0.tau_b(j) * x0 + g0.tau_c(j)),
                    std::abs(g1.tau_a(j) * u + g1.tau_b(j) * x1 + g1.tau_c(j))),
           lim.joint_torque(j));
    }
  }
  take({BindingKind::kCartesianSpeed, 0}, std::max(v0, v1), lim.speed);
  take({BindingKind::kTangentialAcceleration, 0}, std::abs(u), lim.tangential);
  take({BindingKind::kCentripetalAcceleration, 0}, std::max(g0.kappa * x0, g1.kappa * x1), lim.centripetal);
  take({BindingKind::kAngularSpeed, 0}, std::max(g0.omega_s.norm() * v0, g1.omega_s.norm() * v1), lim.angular_speed);
  take({BindingKind::kAngularAcceleration, 0},
       std::max((g0.omega_s * u + g0.omega_ss * x0).norm(), (g1.omega_s * u + g1.omega_ss * x1).norm()),
       lim.angular_acceleration);
  return best;
}

std::string source_words(const Source& s) {
  switch (s.kind) {
    case BindingKind::kJointVelocity: return "the velocity limit of joint " + std::to_string(s.joint);
    case BindingKind::kJointAcceleration: return "the acceleration limit of joint " + std::to_string(s.joint);
    case BindingKind::kJointJerk: return "the jerk limit of joint " + std::to_string(s.joint);
    case BindingKind::kCartesianSpeed: return "maxSpeed";
    case BindingKind::kTangentialAcceleration: return "maxAcceleration (tangential)";
    case BindingKind::kCentripetalAcceleration: return "maxAcceleration (centripetal)";
    case BindingKind::kAngularSpeed: return "maxAngularSpeed";
    case BindingKind::kAngularAcceleration: return "maxAngularAcceleration";
    case BindingKind::kJointTorque: return "the torque limit of joint " + std::to_string(s.joint);
  }
  return "?";
}

}  // namespace

namespace time_optimal_detail {

/// The sweep with per-point limit scales sigma (joint limits and the centripetal limit at
/// point i are multiplied by sigma_i, accelerations by sigma_i^2); sigma null: all 1.
Expected<TimeOptimalSolution> sweep(const std::vector<GridPoint>& all, const TimeOptimalLimits& lim,
                                    const std::vector<double>* sigma, const std::vector<std::size_t>* points) {
  const std::size_t n_pts = points ? points->size() : all.size();
  GEOTRAJ_CHECK(n_pts >= 3);
  GEOTRAJ_CHECK(lim.joint_velocity.size() == lim.joint_acceleration.size());
  const std::size_t N = n_pts - 1;
  auto index = [&](std::size_t i) { return points ? (*points)[i] : i; };
  auto point = [&](std::size_t i) -> const GridPoint& { return all[index(i)]; };
  auto sig = [&](std::size_t i) { return sigma ? (*sigma)[index(i)] : 1.0; };
  const bool middle = points == nullptr;  // a subset's intervals are not the grid's: no middles
  auto fail = [&](std::size_t i, const std::string& why) {
    return tl::make_unexpected(Violations{unattainable(
        "motion", "no positive speed is admissible at s = " + number(point(i).s, 6) + " m from the portion's start: " + why)});
  };

  // At rest a joint's torque is its gravity load: where that passes the limit, no motion
  // passes the point.
  for (std::size_t i = 0; i < n_pts; ++i) {
    const GridPoint& g = point(i);
    if (!has_torques(g, lim)) continue;
    for (Eigen::Index j = 0; j < g.q_s.size(); ++j) {
      if (std::abs(g.tau_c(j)) > lim.joint_torque(j))
        return fail(i, "joint " + std::to_string(j) + " needs " + number(std::abs(g.tau_c(j)), 6) +
                           " N m against gravity (with the payload) there, beyond its maxTorque " +
                           number(lim.joint_torque(j), 6) + kTorqueLimitSource);
    }
  }

  std::vector<double> lo(n_pts, 0.0), hi(n_pts, 0.0);
  Polygon poly;
  // Backward: controllable sets. K_N = {0} (rest).
  for (std::size_t k = N; k-- > 0;) {
    const GridPoint &g0 = point(k), &g1 = point(k + 1);
    const double ds = g1.s - g0.s;
    GEOTRAJ_CHECK(ds > 0.0);
    poly.clear();
    interval_rows(g0, g1, ds, lim, sig(k), sig(k + 1), middle, poly);
    // x + 2 ds u in [lo_{k+1}, hi_{k+1}].
    poly.add_lower(lo[k + 1] / (2.0 * ds), -1.0 / (2.0 * ds), {BindingKind::kCartesianSpeed, 0, true});
    poly.add_upper(hi[k + 1] / (2.0 * ds), -1.0 / (2.0 * ds), {BindingKind::kCartesianSpeed, 0, true});
    const PointCap cap = point_cap(g0, lim, sig(k));
    double x_lo = 0.0, x_hi = std::min(cap.x, poly.x_max);
    Source hi_src = cap.x <= poly.x_max ? cap.src : poly.x_max_src;
    bool empty = false;
    if (!feasible_range(poly, x_lo, x_hi, hi_src, empty)) pairwise_range(poly, x_lo, x_hi, hi_src, empty);
    if (empty || x_hi < x_lo - 1e-12 * std::max(1.0, std::abs(x_hi)))
      return fail(k, "the rest at the end of the portion cannot be reached within " + source_words(hi_src));
    if (x_hi < x_lo) x_lo = x_hi;
    if (k > 0 && !(x_hi > 0.0)) return fail(k, source_words(hi_src) + " admits only zero speed there");
    lo[k] = x_lo;
    hi[k] = x_hi;
  }
  if (lo[0] > 1e-12 * std::max(1.0, hi[0]))
    return fail(0, "the motion cannot start from rest within the acceleration limits");

  // Forward: the largest admissible u that stays controllable.
  TimeOptimalSolution sol;
  sol.b.assign(n_pts, 0.0);
  sol.u.assign(N, 0.0);
  for (std::size_t k = 0; k < N; ++k) {
    const GridPoint &g0 = point(k), &g1 = point(k + 1);
    const double ds = g1.s - g0.s, x = sol.b[k];
    UpperAt upper{x, (hi[k + 1] - x) / (2.0 * ds)};
    interval_rows(g0, g1, ds, lim, sig(k), sig(k + 1), middle, upper);
    const double u = upper.u;
    const double x1 = std::clamp(x + 2.0 * ds * u, lo[k + 1], hi[k + 1]);
    sol.b[k + 1] = k + 1 == N ? 0.0 : x1;
    sol.u[k] = (sol.b[k + 1] - x) / (2.0 * ds);
  }

  // The profile: constant acceleration per interval, dt = 2 ds / (sqrt(b_i) + sqrt(b_{i+1})).
  double t = 0.0;
  sol.profile.length = point(N).s;
  sol.profile.pieces.reserve(N);
  for (std::size_t k = 0; k < N; ++k) {
    const double ds = point(k + 1).s - point(k).s;
    const double v0 = std::sqrt(sol.b[k]), v1 = std::sqrt(sol.b[k + 1]);
    if (!(v0 + v1 > 0.0)) return fail(k, "the speed stays zero over an interval (grid too coarse)");
    const double dt = 2.0 * ds / (v0 + v1);
    sol.profile.pieces.push_back({t, point(k).s, v0, sol.u[k], 0.0});
    const Usage us = interval_usage(point(k), point(k + 1), sol.b[k], sol.b[k + 1], sol.u[k], lim);
    BindingStretch st;
    st.kind = us.src.kind;
    st.joint = us.src.joint;
    st.s_start = point(k).s;
    st.s_end = point(k + 1).s;
    st.t_start = t;
    st.t_end = t + dt;
    st.value = us.value;
    st.limit = us.limit;
    st.usage = us.ratio;
    if (!sol.binding.empty() && sol.binding.back().kind == st.kind && sol.binding.back().joint == st.joint) {
      BindingStretch& last = sol.binding.back();
      last.s_end = st.s_end;
      last.t_end = st.t_end;
      if (st.value > last.value) last.value = st.value, last.usage = st.usage;
    } else {
      sol.binding.push_back(st);
    }
    t += dt;
  }
  sol.profile.duration = t;
  sol.duration = t;
  return sol;
}

}  // namespace time_optimal_detail

Expected<TimeOptimalSolution> solve_time_optimal(const std::vector<GridPoint>& grid, const TimeOptimalLimits& limits) {
  return time_optimal_detail::sweep(grid, limits, nullptr, nullptr);
}

}  // namespace geotraj::core
