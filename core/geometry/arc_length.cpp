#include "core/geometry/arc_length.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace geotraj::core {

namespace {

// Gauss-Kronrod 7/15 nodes on [-1, 1] (positive half) and weights.
constexpr double kXgk[8] = {0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
                            0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
                            0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
                            0.207784955007898467600689403773245, 0.0};
constexpr double kWgk[8] = {0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
                            0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
                            0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
                            0.204432940075298892414161999234649, 0.209482141084727828012999174891714};
// Gauss 7-point weights for the Kronrod nodes 1, 3, 5 and 7.
constexpr double kWg[4] = {0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
                           0.381830050505118944950369775488975, 0.417959183673469387755102040816327};

struct Interval {
  double a, b, value, error;
};

// One G7-K15 panel. The error estimate is QUADPACK's (QK15): the Gauss-Kronrod difference
// scaled by resasc = integral of |f - mean| as resasc * min(1, (200 |K - G| / resasc)^1.5),
// which tracks the Kronrod result's true error far better than |K - G| alone.
template <class F>
Interval gk15(const F& f, double a, double b) {
  const double c = 0.5 * (a + b), h = 0.5 * (b - a);
  double fv[15];
  fv[7] = f(c);
  for (int i = 0; i < 7; ++i) {
    const double dx = h * kXgk[i];
    fv[i] = f(c - dx);
    fv[14 - i] = f(c + dx);
  }
  double k = kWgk[7] * fv[7], g = kWg[3] * fv[7];
  for (int i = 0; i < 7; ++i) {
    const double s = fv[i] + fv[14 - i];
    k += kWgk[i] * s;
    if (i % 2 == 1) g += kWg[i / 2] * s;
  }
  const double mean = 0.5 * k;
  double asc = kWgk[7] * std::abs(fv[7] - mean);
  for (int i = 0; i < 7; ++i) asc += kWgk[i] * (std::abs(fv[i] - mean) + std::abs(fv[14 - i] - mean));
  const double resasc = asc * std::abs(h);
  double err = std::abs((k - g) * h);
  if (resasc != 0.0 && err != 0.0) err = resasc * std::min(1.0, std::pow(200.0 * err / resasc, 1.5));
  // Never claim better than rounding allows.
  err = std::max(err, 50.0 * std::numeric_limits<double>::epsilon() * std::abs(k * h));
  return {a, b, k * h, err};
}

// Recursive bisection on QUADPACK's local error estimate: a panel whose estimate is within
// its share of the tolerance (proportional to its width) is accepted, otherwise its halves
// are refined. No heap: the recursion depth is bounded by 40 and by the panel budget.
template <class F>
double refine(const F& f, const Interval& panel, double tol_per_unit, int depth, int& budget, bool confirmed) {
  const double tol = tol_per_unit * (panel.b - panel.a);
  if ((confirmed && panel.error <= tol) || depth >= 40 || budget <= 0) return panel.value;
  const double mid = 0.5 * (panel.a + panel.b);
  if (!(mid > panel.a && mid < panel.b)) return panel.value;  // no room left in double precision
  budget -= 2;
  const Interval l = gk15(f, panel.a, mid), r = gk15(f, mid, panel.b);
  // A panel's own |K - G| can be small while K15 and G7 err alike: its halves may accept
  // themselves on their estimates only if together they confirm the panel's value.
  const bool agree = std::abs(l.value + r.value - panel.value) <= tol;
  return refine(f, l, tol_per_unit, depth + 1, budget, agree) + refine(f, r, tol_per_unit, depth + 1, budget, agree);
}

template <class F>
double adaptive(const F& f, double a, double b, double rel_tol, int max_intervals) {
  if (!(b > a)) return 0.0;
  const Interval whole = gk15(f, a, b);
  // The tolerance is relative to the integral; |whole.value| is a good enough scale for it
  // (the integrand |dp/du| is non-negative, so there is no cancellation).
  const double scale = std::max(std::abs(whole.value), std::numeric_limits<double>::min());
  // Below a hundred ulps the tolerance is unattainable (the panel error floor is 50 ulps).
  rel_tol = std::max(rel_tol, 100.0 * std::numeric_limits<double>::epsilon());
  int budget = max_intervals;
  return refine(f, whole, rel_tol * scale / (b - a), 0, budget, /*confirmed=*/false);
}

struct SpeedIntegrand {
  const Segment* segment;
  double operator()(double u) const {
    if (const auto* bez = std::get_if<BezierSegment>(segment))
      return bernstein_sum(bez->h[1].data(), bez->degree - 1, u).norm();  // |dp/du| [m]
    Jet jet;
    evaluate(*segment, u, 1, jet);
    return jet[1].norm();
  }
};

}  // namespace

double integrate_gk15(const std::function<double(double)>& f, double a, double b, double rel_tol,
                      int max_intervals) {
  return adaptive(f, a, b, rel_tol, max_intervals);
}

double segment_arc_length(const Segment& segment, double u0, double u1, double rel_tol) {
  if (!(u1 > u0)) return 0.0;
  if (const auto* nat = std::get_if<NaturalSegment>(&segment)) return natural_arc(*nat, u0, u1);  // exact
  const SpeedIntegrand f{&segment};
  const auto* trap = std::get_if<TrapezoidSegment>(&segment);
  if (!trap) return adaptive(f, u0, u1, rel_tol, 2000);
  // Split at the breakpoints, where derivative n + 1 jumps.
  std::array<double, 3 * (2 * kMaxTrapezoidOrder + 2) + 2> cuts;
  std::size_t count = 0;
  cuts[count++] = u0;
  for (const auto& axis : trap->axes)
    for (int k = 0; k <= 2 * axis.n + 1; ++k)
      if (axis.u[k] > u0 && axis.u[k] < u1) cuts[count++] = axis.u[k];
  cuts[count++] = u1;
  std::sort(cuts.begin(), cuts.begin() + count);
  double s = 0.0;
  for (std::size_t i = 0; i + 1 < count; ++i) s += adaptive(f, cuts[i], cuts[i + 1], rel_tol, 2000);
  return s;
}

double arc_length_at(const Path& path, double u) {
  const auto [i, ul] = locate(path, u);
  return path.cumulative_lengths[i] + segment_arc_length(path.segments[i], 0.0, ul);
}

double parameter_at(const Path& path, double s) {
  const double total = path.length();
  if (!(s > 0.0)) return 0.0;
  if (s >= total) return path.u_max();
  // Segment i with cumulative[i] <= s < cumulative[i + 1].
  const auto it = std::upper_bound(path.cumulative_lengths.begin(), path.cumulative_lengths.end(), s);
  std::size_t i = static_cast<std::size_t>(it - path.cumulative_lengths.begin()) - 1;
  i = std::min(i, path.segments.size() - 1);
  const Segment& seg = path.segments[i];
  const double target = s - path.cumulative_lengths[i];
  const double len = path.segment_lengths[i];
  const double tol = 1e-12 * std::max(total, std::numeric_limits<double>::min());
  double lo = 0.0, hi = 1.0;
  double u = len > 0.0 ? std::clamp(target / len, 0.0, 1.0) : 0.0;
  double su = segment_arc_length(seg, 0.0, u);
  for (int iter = 0; iter < 100; ++iter) {
    const double f = su - target;
    if (std::abs(f) <= tol) break;
    if (f > 0.0) hi = u; else lo = u;
    Jet jet;
    evaluate(seg, u, 1, jet);
    const double speed = jet[1].norm();
    double next = speed > 0.0 ? u - f / speed : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);  // safeguard: bisect
    su += next > u ? segment_arc_length(seg, u, next) : -segment_arc_length(seg, next, u);
    u = next;
    if (hi - lo <= 4 * std::numeric_limits<double>::epsilon()) break;
  }
  return static_cast<double>(i) + u;
}

}  // namespace geotraj::core
