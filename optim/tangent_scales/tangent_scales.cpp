#include "optim/tangent_scales/tangent_scales.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <utility>

#include <Eigen/Core>
#include <coin/IpIpoptApplication.hpp>
#include <coin/IpTNLP.hpp>
#include <nlopt.h>

#include "core/geometry/bezier.hpp"
#include "core/geometry/constraints.hpp"
#include "core/geometry/differential_geometry.hpp"
#include "core/geometry/smoothest.hpp"
#include "core/geometry/validate.hpp"
#include "optim/common/ipopt_lock.hpp"
#include "optim/common/second_order.hpp"
#include "core/format.hpp"

namespace geotraj::optim {
namespace {

using Clock = std::chrono::steady_clock;
using Eigen::Vector3d;
template <class S>
using Vec3 = Eigen::Matrix<S, 3, 1>;
// Each segment depends on two scales: second-order forward mode in its two variables
// y = ln(scale) (x0: the start frame's leaving side, x1: the end frame's approach side);
// the Hessian's lower triangle is (x0 x0, x1 x0, x1 x1).
using AD = detail::SecondOrder<2>;

double value_of(double x) { return x; }
double value_of(const AD& x) { return x.f; }

// The scale s = exp(y) as a function of its log-scale y, variable k of the segment:
// ds/dy = d2s/dy2 = s.
AD log_scale_variable(double s, int k) {
  AD r(s);
  r.g[k] = s;
  r.h[k == 0 ? 0 : 2] = s;
  return r;
}

constexpr int kGaussNodes = 8;
// The final verification measures on rules this many times finer than the solver's.
constexpr int kAuditFactor = 8;
// At the verification, |p'| may dip between the regularity samples to this fraction of the
// floor (a polynomial of degree <= 16 between samples 1/32 apart moves little).
constexpr double kAuditSpeedFraction = 0.5;
// The integral objectives on the solver's rule and on the 8 times finer rule must agree to
// this (relative) for a point to be returned: the solver's rule resolved the curve.
constexpr double kRuleAgreement = 1e-3;
// At most this many evaluated points are verified at the end (best first).
constexpr int kMaxVerifications = 8;
// A regularity sample counts as met down to this (relative, in |p'|^2).
constexpr double kFeasibilityTolerance = 1e-6;
// A regularity row is a soft minimum of its samples' ln(|p'|^2 / floor^2) with this power (see
// regularity_rows): it lies at most ln(4) / 64 = 0.022 below the smallest of its 4 samples, so
// it is conservative (row >= 0 implies every sample meets the floor) and raises the floor by
// at most 1.1 % in |p'| (all 4 samples equally close), less when only one approaches it.
constexpr double kRegularityAggregatePower = 64.0;
// Regularity rows per segment, each over kRegularitySamples / rows consecutive samples: 8 rows
// of 4 samples keep the KKT system small (Ipopt's MUMPS solves cost per row) while leaving the
// restoration phase enough structure. If Ipopt still reports the rows infeasible (a local
// verdict of its restoration phase), the solve is repeated with one row per sample.
constexpr int kRegularityRows = 8;
// The peak objectives minimise a smooth aggregate of the peak rows v_j (kappa^2 or weighted
// tau^2 at the samples), the log-sum-exp (Kreisselmeier-Steinhauser) function
//   F = ln( sum_j ((v_j + eps) / v_0)^q ) / q,  v_0 the largest row at the start,
// an upper bound of ln(max_j v_j / v_0) within ln(rows) / q: the minimax problem without an
// epigraph row per sample (which an interior-point method holds back with its barrier). q =
// kAggregatePower; eps = kPeakEps v_0 keeps straight points finite.
constexpr double kAggregatePower = 48.0;
constexpr double kPeakEps = 1e-12;

constexpr const char* kOptionsField = "optimize.tangentScales.";
// Ipopt, with the exact Hessian (see evaluate). tol 1e-6 on Ipopt's scaled KKT error; Ipopt stops earlier at the acceptable level (KKT
// error 1e-3) once the objective changes by less than 1e-4 relative on 2 successive
// iterations: below the fixed rules' own accuracy (kRuleAgreement) there is nothing to gain.
constexpr double kIpoptTol = 1e-6;
constexpr double kIpoptAcceptableTol = 1e-3;
constexpr int kIpoptAcceptableIter = 2;
constexpr double kIpoptAcceptableObjChange = 1e-4;

// ---------------------------------------------------------------------------------------------
// Fixed rules in u.

// Gauss-Legendre nodes and weights on [-1, 1] by Newton's method on P_n (deterministic, to
// rounding).
std::pair<std::array<double, kGaussNodes>, std::array<double, kGaussNodes>> gauss_legendre() {
  std::array<double, kGaussNodes> x{}, w{};
  const int n = kGaussNodes;
  for (int i = 0; i < n; ++i) {
    double z = std::cos(M_PI * (i + 0.75) / (n + 0.5));
    double dp = 0.0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (z * p1 - p0) / (z * z - 1.0);
      const double dz = p1 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    x[i] = z;
    w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
  }
  return {x, w};
}

struct Rule {
  std::vector<double> u, w;  // nodes in [0, 1] and weights summing to 1
};

Rule composite_rule(int intervals) {
  const auto [x, w] = gauss_legendre();
  Rule r;
  const double h = 1.0 / intervals;
  for (int j = 0; j < intervals; ++j) {
    for (int i = 0; i < kGaussNodes; ++i) {
      r.u.push_back(h * (j + 0.5 * (x[i] + 1.0)));
      r.w.push_back(0.5 * h * w[i]);
    }
  }
  return r;
}

// `count` points uniform in [0, 1], both ends included.
std::vector<double> uniform_points(int count) {
  std::vector<double> u;
  for (int j = 0; j < count; ++j) u.push_back(static_cast<double>(j) / (count - 1));
  return u;
}

// `count` midpoints of `count` equal parts of [0, 1]: (j + 1/2) / count.
std::vector<double> midpoints(int count) {
  std::vector<double> u;
  for (int j = 0; j < count; ++j) u.push_back((j + 0.5) / count);
  return u;
}

// d^k/du^k of the Bernstein polynomial B_{i,d}(u) = C(d, i) u^i (1-u)^(d-i):
//   d!/(d-k)! sum_j (-1)^(k-j) C(k, j) B_{i-j, d-k}(u).
// Integer powers by repeated multiplication (std::pow dominated the set-up).
double int_pow(double x, int e) {
  double r = 1.0;
  for (int i = 0; i < e; ++i) r *= x;
  return r;
}

double bernstein_derivative(int d, int i, int k, double u) {
  if (k > d) return 0.0;
  double sum = 0.0;
  for (int j = 0; j <= k; ++j) {
    const int m = i - j, n = d - k;
    if (m < 0 || m > n) continue;
    const double b = core::binomial(n, m) * int_pow(u, m) * int_pow(1.0 - u, n - m);
    sum += ((k - j) % 2 ? -1.0 : 1.0) * core::binomial(k, j) * b;
  }
  return core::falling_factorial(d, k) * sum;
}

// Weights of the control points in d^k p/du^k at fixed u's, for one degree:
// w[k][j * (d + 1) + i] for k = 1..3. Precomputed once per degree and point set, so that
// an evaluation is a short weighted sum of the control points per point and order.
struct BasisTable {
  int degree = 0;
  std::size_t points = 0;
  std::array<std::vector<double>, 4> w;
};

BasisTable basis_table(int d, const std::vector<double>& u) {
  BasisTable t;
  t.degree = d;
  t.points = u.size();
  for (int k = 1; k <= 3; ++k) {
    t.w[k].resize(u.size() * (d + 1));
    for (std::size_t j = 0; j < u.size(); ++j)
      for (int i = 0; i <= d; ++i) t.w[k][j * (d + 1) + i] = bernstein_derivative(d, i, k, u[j]);
  }
  return t;
}

// The point sets of one degree: the solver's and the verification's.
struct Tables {
  BasisTable quad, peak, regular;           // solver
  BasisTable audit_quad, audit_points;      // verification (8 times finer)
};

// The tables of degree d, built once per process and shared (immutable once built; the
// set-up of the finer verification tables cost as much as a whole solve).
std::shared_ptr<const Tables> tables_for(int d);

// ---------------------------------------------------------------------------------------------
// The problem: segments, variables, bounds.

struct SegmentVars {
  std::size_t from = 0, to = 0;  // frames
  int var0 = 0, var1 = 0;        // scale of `from`'s leaving side, of `to`'s approach side
  int n0 = 1, n1 = 1;            // orders fixed at the ends
  Vector3d T0, N0, T1, N1;       // the sides' Frenet vectors (after cusp / inflection flips)
  double speed_floor2 = 0.0;     // (kMinSpeedFraction chord)^2 [m^2]
  double kappa_floor2 = 0.0;     // (kTorsionCurvatureFraction / chord)^2 [1/m^2]
  const Tables* tables = nullptr;
};

struct Problem {
  core::PathSpec spec;  // validated, normalised
  // The smoothest reading: the free derivatives at every frame come from one solve over the
  // whole path (core::fill_smoothest), so a segment depends on every scale, not on its two.
  bool global = false;
  // Peak objectives: the longest curve a returned point may have [m] (see kPeakLengthGrowth).
  double max_length = std::numeric_limits<double>::infinity();
  TangentScaleObjective objective = TangentScaleObjective::kBendingEnergy;
  double length_weight = 0.0;
  int scale_count = 0;
  std::vector<int> approach_var, leave_var;  // per frame
  std::vector<double> lower, upper, start;   // per scale [m]
  std::vector<SegmentVars> segments;
  Rule rule, audit_rule;
  std::map<int, std::shared_ptr<const Tables>> tables;  // by degree (shared, see tables_for)

  bool peak() const {
    return objective == TangentScaleObjective::kPeakCurvature || objective == TangentScaleObjective::kPeakTorsion;
  }
  std::size_t peak_rows() const { return peak() ? segments.size() * kPeakSamples : 0; }
  int rows_per_segment = kRegularityRows;  // divides kRegularitySamples
  std::size_t regularity_count() const { return segments.size() * rows_per_segment; }
  // Peaks: one more row, 1 - L / max_length >= 0 (kPeakLengthGrowth), after the regularity rows.
  bool length_row() const { return peak() && std::isfinite(max_length); }
  std::size_t constraint_count() const { return regularity_count() + (length_row() ? 1 : 0); }
};

// Control points of one segment at scales (s0, s1), generic in the scalar: the end
// derivatives by the Chapter 5 conversion (core::side_derivatives), then the Hermite
// control points (core::hermite_control_points, linear in the end derivatives).
template <class S>
void control_points(const Problem& pb, const SegmentVars& sg, const S& s0, const S& s1,
                    std::array<Vec3<S>, core::kMaxBezierDegree + 1>& b) {
  const auto& f0 = pb.spec.frames[sg.from];
  const auto& f1 = pb.spec.frames[sg.to];
  std::array<Vec3<S>, core::kMaxJetOrder + 1> start, end;
  std::array<Vec3<S>, 4> d;
  for (auto& v : d) v = Vec3<S>::Zero();  // the thesis's zeros above what the frame gives
  start[0] = f0.p_W.cast<S>();
  core::side_derivatives<S>(f0, pb.spec.convention, sg.T0, sg.N0, s0, d);
  for (int k = 1; k <= sg.n0; ++k) start[k] = d[k - 1];
  end[0] = f1.p_W.cast<S>();
  for (auto& v : d) v = Vec3<S>::Zero();
  core::side_derivatives<S>(f1, pb.spec.convention, sg.T1, sg.N1, s1, d);
  for (int k = 1; k <= sg.n1; ++k) end[k] = d[k - 1];
  core::hermite_control_points(start, sg.n0, end, sg.n1, b);
}

template <class S>
using ControlPoints = std::array<Vec3<S>, core::kMaxBezierDegree + 1>;

template <class S>
Vec3<S> combine(const double* w, const ControlPoints<S>& b, int d) {
  Vec3<S> r = b[0] * w[0];
  for (int i = 1; i <= d; ++i) r += b[i] * w[i];
  return r;
}

// Bending energy int kappa^2 ds [1/m] and arc length [m] of one segment (composite
// Gauss-Legendre): int_0^1 |p' x p''|^2 / |p'|^5 du and int_0^1 |p'| du.
template <class S>
void segment_integrals(const Problem& pb, const ControlPoints<S>& b, const BasisTable& t, const Rule& rule, S& energy,
                       S& length) {
  using std::sqrt;
  const int d = t.degree;
  energy = S(0.0);
  length = S(0.0);
  for (std::size_t j = 0; j < t.points; ++j) {
    const Vec3<S> p_u = combine(&t.w[1][j * (d + 1)], b, d);
    const S speed2 = p_u.squaredNorm();
    const S speed = sqrt(speed2);
    length += speed * rule.w[j];
    if (pb.objective == TangentScaleObjective::kBendingEnergy) {
      const Vec3<S> p_uu = combine(&t.w[2][j * (d + 1)], b, d);
      const Vec3<S> C = p_u.cross(p_uu);
      energy += C.squaredNorm() / (speed2 * speed2 * speed) * rule.w[j];  // kappa^2 |p'|
    }
  }
}

// The peak rows of one segment [1/m^2]: kappa^2 (5.4), or tau^2 (5.11) weighted by
//   w = smoothstep((kappa^2 / kappa_floor^2 - 1/4) / (3/4)),
// which is 0 where kappa <= kappa_floor / 2 (there the osculating plane, and so tau, is
// ill-conditioned), 1 where kappa >= kappa_floor, and C1 in the scales in between, so the
// rows stay smooth when a point crosses the floor. `hard` (the verification): w is 1 where
// kappa >= kappa_floor and 0 elsewhere, the reported measure.
template <class S>
void segment_peaks(const Problem& pb, const SegmentVars& sg, const ControlPoints<S>& b, const BasisTable& t,
                   bool hard, S* out) {
  const int d = t.degree;
  for (std::size_t j = 0; j < t.points; ++j) {
    const Vec3<S> p_u = combine(&t.w[1][j * (d + 1)], b, d);
    const Vec3<S> p_uu = combine(&t.w[2][j * (d + 1)], b, d);
    const Vec3<S> C = p_u.cross(p_uu);
    const S C2 = C.squaredNorm();
    const S speed2 = p_u.squaredNorm();
    const S kappa2 = C2 / (speed2 * speed2 * speed2);  // (5.4)
    if (pb.objective == TangentScaleObjective::kPeakCurvature) {
      out[j] = kappa2;
      continue;
    }
    const S x = kappa2 / sg.kappa_floor2;
    if (!(value_of(x) > (hard ? 1.0 : 0.25)) || !(value_of(C2) > 0.0)) {
      out[j] = S(0.0);
      continue;
    }
    const Vec3<S> p_uuu = combine(&t.w[3][j * (d + 1)], b, d);
    const S tau = C.dot(p_uuu) / C2;  // (5.11)
    out[j] = tau * tau;
    if (!hard && value_of(x) < 1.0) {
      const S z = (x - 0.25) / 0.75;
      out[j] *= z * z * (3.0 - 2.0 * z);
    }
  }
}

// The regularity samples of one segment: |p'|^2 / speed_floor^2 (>= 1 when met).
template <class S>
void segment_speeds(const SegmentVars& sg, const ControlPoints<S>& b, const BasisTable& t, S* out) {
  const int d = t.degree;
  for (std::size_t j = 0; j < t.points; ++j) {
    out[j] = combine(&t.w[1][j * (d + 1)], b, d).squaredNorm() / sg.speed_floor2;
  }
}

// Everything at one point (the scales): values and exact first and second derivatives with
// respect to the log-scales y = ln(scale).
struct Evaluation {
  double f = 0.0;              // the solver's objective (peaks: the aggregate F)
  std::vector<double> grad;    // d f / d y
  std::vector<double> hess;    // d2 f / dy_i dy_j at [i * n + j], i >= j (lower triangle)
  double largest = 0.0;        // peaks: the largest peak row [1/m^2]
  std::vector<AD> peak;        // peaks: the rows v_j [1/m^2], in their segment's two variables
  std::vector<AD> g;           // regularity rows G_r, rows_per_segment per segment (>= 0 when met)
  std::vector<AD> length;      // Problem::length_row: each segment's arc length [m], in its two variables
  double length_row = 0.0;     // Problem::length_row: 1 - L / max_length (>= 0 when met)
  std::vector<double> length_grad;  // d length_row / d y
  bool regular = false;        // every regularity sample met (and the length row, if any)
};

// Adds w x the local Hessian of `t` (in the segment's variables var0, var1) to the lower
// triangle of `hess` (n x n).
void add_hessian(std::vector<double>& hess, int n, const SegmentVars& sg, const AD& t, double w) {
  hess[sg.var0 * n + sg.var0] += w * t.h[0];
  hess[sg.var1 * n + sg.var1] += w * t.h[2];
  hess[std::max(sg.var0, sg.var1) * n + std::min(sg.var0, sg.var1)] += w * t.h[1];
}

// The regularity rows of one segment: row r is the soft minimum (Kreisselmeier-Steinhauser)
// of its group J_r of consecutive samples,
//   G_r = -ln( sum_{j in J_r} (|p'(u_j)|^2 / speed_floor^2)^(-rho) ) / rho,  rho = kRegularityAggregatePower,
// a smooth lower bound of the group's smallest ln(|p'|^2 / speed_floor^2): G_r >= 0 implies
// every sample of the group meets the floor, and all of them at ln(...) >= ln(|J_r|) / rho
// imply G_r >= 0. With one sample per group G_r is that sample's ln. `min_ln` returns the
// smallest sample's ln(|p'|^2 / speed_floor^2), or 0 if that is larger.
template <class S>
void regularity_rows(const SegmentVars& sg, const ControlPoints<S>& b, int rows_per_segment, S* out, double& min_ln) {
  using std::exp;
  using std::log;
  std::array<S, kRegularitySamples> rows;
  segment_speeds(sg, b, sg.tables->regular, rows.data());
  min_ln = 0.0;
  const int per = kRegularitySamples / rows_per_segment;
  for (int r = 0; r < rows_per_segment; ++r) {
    double lo = std::numeric_limits<double>::infinity();
    for (int j = r * per; j < (r + 1) * per; ++j) {
      rows[j] = log(rows[j]);
      lo = std::min(lo, value_of(rows[j]));
    }
    min_ln = std::min(min_ln, lo);
    S sum(0.0);
    for (int j = r * per; j < (r + 1) * per; ++j) sum += exp((rows[j] - lo) * -kRegularityAggregatePower);
    out[r] = S(lo) - log(sum) / kRegularityAggregatePower;
  }
}

// The solver's objective and rows at `scales`, with exact first and second derivatives in
// y = ln(scale). Each segment's control points are computed once (second-order in its two
// variables) and shared by its rows. `v0` scales the aggregate (peaks; <= 0: the largest row
// here). No allocation once `ev` has its size.
void evaluate(const Problem& pb, const double* scales, Evaluation& ev, double v0 = 0.0) {
  const int n = pb.scale_count;
  ev.grad.assign(n, 0.0);
  ev.hess.assign(static_cast<std::size_t>(n) * n, 0.0);
  ev.peak.resize(pb.peak_rows());
  ev.g.resize(pb.regularity_count());
  ev.length.resize(pb.length_row() ? pb.segments.size() : 0);
  ev.length_grad.assign(pb.length_row() ? n : 0, 0.0);
  std::array<AD, kPeakSamples> rows;
  double value = 0.0;
  ev.largest = 0.0;
  ev.regular = true;
  for (std::size_t i = 0; i < pb.segments.size(); ++i) {
    const auto& sg = pb.segments[i];
    ControlPoints<AD> b;
    control_points(pb, sg, log_scale_variable(scales[sg.var0], 0), log_scale_variable(scales[sg.var1], 1), b);
    if (pb.peak()) {
      segment_peaks(pb, sg, b, sg.tables->peak, false, rows.data());
      for (int j = 0; j < kPeakSamples; ++j) {
        ev.peak[i * kPeakSamples + j] = rows[j];
        ev.largest = std::max(ev.largest, rows[j].f);
      }
      if (pb.length_row()) {
        AD e;
        segment_integrals(pb, b, sg.tables->quad, pb.rule, e, ev.length[i]);  // the length only
        ev.length_grad[sg.var0] -= ev.length[i].g[0] / pb.max_length;
        ev.length_grad[sg.var1] -= ev.length[i].g[1] / pb.max_length;
      }
    } else {
      AD e, l;
      segment_integrals(pb, b, sg.tables->quad, pb.rule, e, l);
      const AD f = pb.objective == TangentScaleObjective::kArcLength ? l : e + l * pb.length_weight;
      value += f.f;
      ev.grad[sg.var0] += f.g[0];
      ev.grad[sg.var1] += f.g[1];
      add_hessian(ev.hess, n, sg, f, 1.0);
    }
    double min_ln = 0.0;
    regularity_rows(sg, b, pb.rows_per_segment, &ev.g[i * pb.rows_per_segment], min_ln);
    if (!(min_ln >= std::log1p(-kFeasibilityTolerance))) ev.regular = false;
  }
  if (!pb.peak()) {
    ev.f = value;
    return;
  }
  if (pb.length_row()) {
    double total = 0.0;
    for (const AD& l : ev.length) total += l.f;
    ev.length_row = 1.0 - total / pb.max_length;
    if (!(ev.length_row >= 0.0)) ev.regular = false;
  }
  // The aggregate F (see kAggregatePower) by log-sum-exp, shifted by its largest term. With
  // c_j = v_j + eps and the softmax weights p_j:
  //   dF = sum_j p_j dv_j / c_j,
  //   d2F = sum_j p_j (d2v_j / c_j + (q - 1) dv_j dv_j^T / c_j^2) - q dF dF^T.
  if (!(v0 > 0.0)) v0 = ev.largest > 0.0 ? ev.largest : 1.0;
  const double q = kAggregatePower;
  const double eps = kPeakEps * v0;
  const double top = q * std::log((ev.largest + eps) / v0);
  double sum = 0.0;
  for (std::size_t row = 0; row < ev.peak.size(); ++row) sum += std::exp(q * std::log((ev.peak[row].f + eps) / v0) - top);
  for (std::size_t row = 0; row < ev.peak.size(); ++row) {
    const AD& v = ev.peak[row];
    const double c = v.f + eps;
    const double p = std::exp(q * std::log(c / v0) - top) / sum;
    if (p == 0.0) continue;
    const auto& sg = pb.segments[row / kPeakSamples];
    ev.grad[sg.var0] += p * v.g[0] / c;
    ev.grad[sg.var1] += p * v.g[1] / c;
    AD local;  // p (d2v / c + (q - 1) dv dv^T / c^2) in the segment's variables
    const double k = (q - 1.0) / (c * c);
    local.h = {v.h[0] / c + k * v.g[0] * v.g[0], v.h[1] / c + k * v.g[0] * v.g[1], v.h[2] / c + k * v.g[1] * v.g[1]};
    add_hessian(ev.hess, n, sg, local, p);
  }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j <= i; ++j) ev.hess[i * n + j] -= q * ev.grad[i] * ev.grad[j];
  ev.f = (top + std::log(sum)) / q;
}

// The solver's objective in its reported unit (square root of the peak rows).
double reported(const Problem& pb, const Evaluation& ev) { return pb.peak() ? std::sqrt(ev.largest) : ev.f; }

bool finite(const AD& x) {
  return std::isfinite(x.f) && std::isfinite(x.g[0]) && std::isfinite(x.g[1]) && std::isfinite(x.h[0]) &&
         std::isfinite(x.h[1]) && std::isfinite(x.h[2]);
}

bool finite(const Evaluation& ev) {
  if (!std::isfinite(ev.f)) return false;
  for (const AD& v : ev.peak)
    if (!std::isfinite(v.f)) return false;
  for (double v : ev.grad)
    if (!std::isfinite(v)) return false;
  for (double v : ev.hess)
    if (!std::isfinite(v)) return false;
  for (const AD& v : ev.g)
    if (!finite(v)) return false;
  for (const AD& v : ev.length)
    if (!finite(v)) return false;
  return std::isfinite(ev.length_row);
}

// Writes `scales` (layout of TangentScaleResult) into the frames of `spec`: one scale per
// frame, and the leaving side's own where it has one (cusps; a leaving scale that differs).
void write_scales(core::PathSpec& spec, const std::vector<int>& approach_var, const std::vector<int>& leave_var,
                  const double* scales) {
  for (std::size_t i = 0; i < spec.frames.size(); ++i) {
    auto& f = spec.frames[i];
    f.tangent_scale = scales[approach_var[i]];
    if (leave_var[i] != approach_var[i]) {
      f.leave_tangent_scale = scales[leave_var[i]];
    } else {
      f.leave_tangent_scale.reset();
    }
  }
}

// The control points of every segment under the smoothest reading at `scales`: the Chapter 5
// conversion at those scales, the one solve over the whole path of core::fill_smoothest
// (5.7's rows with the jerk energy, core/geometry/smoothest.hpp), then the degree 9 Hermite control
// points. False if that solve is singular or its result is not finite.
bool global_control_points(const Problem& pb, const double* scales, std::vector<ControlPoints<double>>& out) {
  core::PathSpec spec = pb.spec;
  write_scales(spec, pb.approach_var, pb.leave_var, scales);
  std::vector<core::FrameConstraints> frames;
  frames.reserve(spec.frames.size());
  for (const auto& f : spec.frames) frames.push_back(core::convert_frame(f, spec.convention));
  if (!core::fill_smoothest(spec, frames)) return false;
  out.resize(pb.segments.size());
  for (std::size_t i = 0; i < pb.segments.size(); ++i) {
    const auto& sg = pb.segments[i];
    std::array<Vector3d, core::kMaxJetOrder + 1> start, end;
    start[0] = spec.frames[sg.from].p_W;
    end[0] = spec.frames[sg.to].p_W;
    for (int k = 1; k <= 4; ++k) {
      start[k] = frames[sg.from].leave.d[k - 1];
      end[k] = frames[sg.to].approach.d[k - 1];
    }
    core::hermite_control_points(start, 4, end, 4, out[i]);
    for (const auto& c : out[i])
      if (!c.allFinite()) return false;
  }
  return true;
}

// The control points of every segment at `scales`, under the problem's reading.
bool all_control_points(const Problem& pb, const double* scales, std::vector<ControlPoints<double>>& out) {
  if (pb.global) return global_control_points(pb, scales, out);
  out.resize(pb.segments.size());
  for (std::size_t i = 0; i < pb.segments.size(); ++i) {
    const auto& sg = pb.segments[i];
    control_points(pb, sg, scales[sg.var0], scales[sg.var1], out[i]);
  }
  return true;
}

// The smoothest reading's objective and rows at one point, in double (no derivatives: the
// solver takes them by central differences, see GlobalSolver).
struct GlobalEvaluation {
  double f = 0.0;          // the solver's objective (peaks: the aggregate F of kAggregatePower)
  double largest = 0.0;    // peaks: the largest peak row [1/m^2]
  std::vector<double> g;   // regularity rows G_r (>= 0 when met)
  bool regular = false;    // every regularity sample met
  bool ok = false;         // the global solve succeeded and every value is finite
};

void evaluate_global(const Problem& pb, const double* scales, GlobalEvaluation& ev, double v0,
                     std::vector<ControlPoints<double>>& points) {
  ev.ok = false;
  ev.regular = true;
  ev.largest = 0.0;
  ev.g.assign(pb.constraint_count(), 0.0);
  if (!all_control_points(pb, scales, points)) return;
  std::vector<double> peaks(pb.peak_rows());
  double value = 0.0, length = 0.0;
  for (std::size_t i = 0; i < pb.segments.size(); ++i) {
    const auto& sg = pb.segments[i];
    if (pb.peak()) {
      segment_peaks(pb, sg, points[i], sg.tables->peak, false, &peaks[i * kPeakSamples]);
      if (pb.length_row()) {
        double e = 0.0, l = 0.0;
        segment_integrals(pb, points[i], sg.tables->quad, pb.rule, e, l);  // the length only
        length += l;
      }
    } else {
      double e = 0.0, l = 0.0;
      segment_integrals(pb, points[i], sg.tables->quad, pb.rule, e, l);
      value += pb.objective == TangentScaleObjective::kArcLength ? l : e + l * pb.length_weight;
    }
    double min_ln = 0.0;
    regularity_rows(sg, points[i], pb.rows_per_segment, &ev.g[i * pb.rows_per_segment], min_ln);
    if (!(min_ln >= std::log1p(-kFeasibilityTolerance))) ev.regular = false;
  }
  if (pb.length_row()) {
    ev.g.back() = 1.0 - length / pb.max_length;
    if (!(ev.g.back() >= 0.0)) ev.regular = false;
  }
  if (pb.peak()) {
    for (double v : peaks) ev.largest = std::max(ev.largest, v);
    if (!(v0 > 0.0)) v0 = ev.largest > 0.0 ? ev.largest : 1.0;
    const double q = kAggregatePower;
    const double eps = kPeakEps * v0;
    const double top = q * std::log((ev.largest + eps) / v0);
    double sum = 0.0;
    for (double v : peaks) sum += std::exp(q * std::log((v + eps) / v0) - top);
    value = (top + std::log(sum)) / q;
  }
  ev.f = value;
  ev.ok = std::isfinite(value) && std::isfinite(ev.largest) &&
          std::all_of(ev.g.begin(), ev.g.end(), [](double x) { return std::isfinite(x); });
}

// The verification measure of one point, in double, on rules kAuditFactor times finer than
// the solver's: the objective in its reported unit (peak torsion with the hard curvature
// floor), and whether the curve stays regular (|p'| >= kAuditSpeedFraction x the floor at
// every fine point; for the peaks also no longer than Problem::max_length) and, for the
// integrals, whether the solver's rule agrees with the fine one to kRuleAgreement.
struct Audit {
  double value = 0.0;
  bool regular = true;
  bool resolved = true;
};

Audit audit(const Problem& pb, const double* scales) {
  Audit a;
  double energy = 0.0, length = 0.0, coarse_energy = 0.0, coarse_length = 0.0, largest = 0.0;
  std::vector<double> values;
  std::vector<ControlPoints<double>> points;
  if (!all_control_points(pb, scales, points)) {
    a.value = std::numeric_limits<double>::infinity();
    a.regular = false;
    return a;
  }
  for (std::size_t i = 0; i < pb.segments.size(); ++i) {
    const auto& sg = pb.segments[i];
    const ControlPoints<double>& b = points[i];
    const Tables& t = *sg.tables;
    values.resize(t.audit_points.points);
    segment_speeds(sg, b, t.audit_points, values.data());
    for (double v : values) {
      if (!(v >= kAuditSpeedFraction * kAuditSpeedFraction)) a.regular = false;
    }
    if (pb.peak()) {
      segment_peaks(pb, sg, b, t.audit_points, true, values.data());
      for (double v : values) largest = std::max(largest, v);
      double e = 0.0, l = 0.0;
      segment_integrals(pb, b, t.audit_quad, pb.audit_rule, e, l);  // the length only
      length += l;
      continue;
    }
    double e = 0.0, l = 0.0;
    segment_integrals(pb, b, t.audit_quad, pb.audit_rule, e, l);
    energy += e;
    length += l;
    segment_integrals(pb, b, t.quad, pb.rule, e, l);
    coarse_energy += e;
    coarse_length += l;
  }
  if (pb.peak()) {
    a.value = std::sqrt(largest);
    if (!(length <= pb.max_length)) a.regular = false;
    return a;
  }
  const bool arc = pb.objective == TangentScaleObjective::kArcLength;
  a.value = arc ? length : energy + pb.length_weight * length;
  const double coarse = arc ? coarse_length : coarse_energy + pb.length_weight * coarse_length;
  a.resolved = std::abs(coarse - a.value) <= kRuleAgreement * std::abs(a.value);
  if (!std::isfinite(a.value)) a.regular = false;
  return a;
}


// Validates the path and the options and sets the problem up. Field paths relative to the request.
bool side_scale_differs(const core::KeyFrame& f) {
  return f.leave_tangent_scale && core::side_scale(f, true) != core::side_scale(f, false);
}

core::Expected<Problem> make_problem(const core::PathSpec& raw, const TangentScaleOptions& options) {
  core::Violations violations;
  auto valid = core::validate_path(raw);
  if (!valid) violations = core::prefixed(std::move(valid.error()), "path.");
  if (valid && valid->blend != core::BlendMethod::kPolynomial) {
    violations.push_back({"path.blend", "tangent scales are optimised for the polynomial blend only"});
  }
  const std::string at = kOptionsField;
  const core::PathLimits limits;
  const auto scale_ok = [&](double v) {
    return std::isfinite(v) && v >= limits.min_tangent_scale && v <= limits.max_tangent_scale;
  };
  const std::string range = "[" + core::number(limits.min_tangent_scale) + ", " + core::number(limits.max_tangent_scale) + "] m";
  if (options.min_scale && !scale_ok(*options.min_scale)) {
    violations.push_back({at + "minScale", "must be a tangent scale in " + range + ", got " + core::number(*options.min_scale)});
  }
  if (options.max_scale && !scale_ok(*options.max_scale)) {
    violations.push_back({at + "maxScale", "must be a tangent scale in " + range + ", got " + core::number(*options.max_scale)});
  } else if (options.min_scale && options.max_scale && *options.max_scale < *options.min_scale) {
    violations.push_back({at + "maxScale", "must be >= minScale (" + core::number(*options.min_scale) + " m), got " +
                                               core::number(*options.max_scale)});
  }
  if (options.length_weight && !(std::isfinite(*options.length_weight) && *options.length_weight >= 0.0)) {
    violations.push_back({at + "lengthWeight", "must be >= 0 [1/m^2], got " + core::number(*options.length_weight)});
  }
  if (options.budget_seconds && !(*options.budget_seconds >= 0.0)) {
    violations.push_back({at + "budgetSeconds", "must be >= 0 s, got " + core::number(*options.budget_seconds)});
  }
  if (options.max_iterations < 1) {
    violations.push_back({at + "maxIterations", "must be >= 1, got " + std::to_string(options.max_iterations)});
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));

  Problem pb;
  pb.spec = std::move(*valid);
  pb.global = pb.spec.unspecified == core::UnspecifiedConstraints::kSmoothest;
  const bool full_order = pb.spec.unspecified != core::UnspecifiedConstraints::kLowestDegree;
  pb.objective = options.objective;
  pb.length_weight = options.length_weight.value_or(0.0);
  const auto& frames = pb.spec.frames;
  const std::size_t count = frames.size();
  const bool closed = pb.spec.closed;

  // Variables and bounds.
  pb.approach_var.resize(count);
  pb.leave_var.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const auto& f = frames[i];
    const std::size_t segments = core::segment_count(count, closed);
    double chord = 0.0;
    if (closed || i > 0) chord = std::max(chord, core::segment_chord(pb.spec, (i + segments - 1) % segments));
    if (closed || i + 1 < count) chord = std::max(chord, core::segment_chord(pb.spec, i));
    const double reference = chord > 0.0 ? chord : f.tangent_scale.value_or(1.0);
    double hi = options.max_scale.value_or(10.0 * reference);
    double lo = options.min_scale.value_or(0.1 * reference);
    hi = std::clamp(hi, limits.min_tangent_scale, limits.max_tangent_scale);
    lo = std::clamp(lo, limits.min_tangent_scale, limits.max_tangent_scale);
    if (!options.min_scale) lo = std::min(lo, hi);
    if (!options.max_scale) hi = std::max(hi, lo);
    // Two variables where the sides may differ: a cusp, or a leaving scale of its own (given,
    // or the chord default of validate_path), so that the start point is the request's curve.
    const int sides = (f.cusp || side_scale_differs(f)) ? 2 : 1;
    for (int s = 0; s < sides; ++s) {
      const double scale = core::side_scale(f, s == 1);
      pb.lower.push_back(lo);
      pb.upper.push_back(hi);
      pb.start.push_back(std::clamp(scale, lo, hi));
    }
    pb.approach_var[i] = pb.scale_count;
    pb.leave_var[i] = pb.scale_count + sides - 1;
    pb.scale_count += sides;
  }

    // Segments and their tables.
  pb.rule = composite_rule(kQuadratureIntervals);
  pb.audit_rule = composite_rule(kAuditFactor * kQuadratureIntervals);
  const std::size_t m = core::segment_count(count, closed);
  for (std::size_t i = 0; i < m; ++i) {
    SegmentVars sg;
    sg.from = i;
    sg.to = (i + 1) % count;
    const core::FrameConstraints c0 = core::convert_frame(frames[sg.from], pb.spec.convention);
    const core::FrameConstraints c1 = core::convert_frame(frames[sg.to], pb.spec.convention);
    sg.var0 = pb.leave_var[sg.from];
    sg.var1 = pb.approach_var[sg.to];
    GEOTRAJ_CHECK(sg.var0 != sg.var1);
    // Under the thesis's and the smoothest readings every side has order 4 (degree 9).
    sg.n0 = full_order ? 4 : c0.leave.order;
    sg.n1 = full_order ? 4 : c1.approach.order;
    sg.T0 = c0.leave.T;
    sg.N0 = c0.leave.N;
    sg.T1 = c1.approach.T;
    sg.N1 = c1.approach.N;
    // Coincident frames (chord 0): the floors follow the smaller starting scale instead.
    double chord = core::segment_chord(pb.spec, i);
    if (!(chord > 0.0)) chord = std::min(pb.start[sg.var0], pb.start[sg.var1]);
    sg.speed_floor2 = std::pow(kMinSpeedFraction * chord, 2);
    sg.kappa_floor2 = std::pow(kTorsionCurvatureFraction / chord, 2);
    const int d = sg.n0 + sg.n1 + 1;
    if (!pb.tables.count(d)) pb.tables.emplace(d, tables_for(d));
    sg.tables = pb.tables.at(d).get();
    pb.segments.push_back(sg);
  }
  // The default length weight: E0 / L0 at the start (the request's scales, clamped), so that
  // both terms weigh the same there and a gentler curve cannot be bought by length alone. It
  // scales with the geometry (E in 1/m, L in m, the weight in 1/m^2), so it is the same for
  // the same shape in millimetres or metres.
  // The peak objectives may lengthen the curve by at most kPeakLengthGrowth over the start
  // (see Audit).
  const bool auto_weight = pb.objective == TangentScaleObjective::kBendingEnergy && !options.length_weight;
  if (auto_weight || pb.peak()) {
    std::vector<ControlPoints<double>> points;
    double energy = 0.0, length = 0.0;
    if (all_control_points(pb, pb.start.data(), points)) {
      for (std::size_t i = 0; i < pb.segments.size(); ++i) {
        double e = 0.0, l = 0.0;
        segment_integrals(pb, points[i], pb.segments[i].tables->quad, pb.rule, e, l);
        energy += e;
        length += l;
      }
    }
    if (auto_weight) {
      const double weight = energy / length;
      pb.length_weight = std::isfinite(weight) && weight > 0.0 ? weight : 0.0;
    }
    if (pb.peak() && std::isfinite(length) && length > 0.0) pb.max_length = kPeakLengthGrowth * length;
  }
  return pb;
}

std::shared_ptr<const Tables> tables_for(int d) {
  static std::mutex mutex;
  static std::map<int, std::shared_ptr<const Tables>> cache;
  const std::lock_guard<std::mutex> lock(mutex);
  auto& entry = cache[d];
  if (!entry) {
    auto t = std::make_shared<Tables>();
    t->quad = basis_table(d, composite_rule(kQuadratureIntervals).u);
    t->peak = basis_table(d, uniform_points(kPeakSamples));
    t->regular = basis_table(d, midpoints(kRegularitySamples));
    t->audit_quad = basis_table(d, composite_rule(kAuditFactor * kQuadratureIntervals).u);
    t->audit_points = basis_table(d, uniform_points(kAuditFactor * (kPeakSamples - 1) + 1));
    entry = std::move(t);
  }
  return entry;
}

// ---------------------------------------------------------------------------------------------
// Ipopt.

// Variables: y_i = ln(scale_i) (the scales span two decades and the objectives vary like
// powers of them: in logarithms Newton's quadratic model is far better conditioned).
// Objective: the integral, or the peaks' aggregate F (kAggregatePower). Rows: the regularity
// rows G_r >= 0 (regularity_rows), each depending on its segment's two scales. Hessian: exact,
// the lower triangle (dense for the peaks, whose aggregate couples every segment).
// A point a solver evaluated that meets the regularity rows, with its solver measure (the
// integral, or the largest peak row).
struct Candidate {
  std::vector<double> scales;
  double measure = 0.0;
};

class ScaleNlp : public Ipopt::TNLP {
 public:
  ScaleNlp(const Problem& pb, Clock::time_point stop_at, std::stop_token stop)
      : pb_(pb), stop_at_(stop_at), stop_(std::move(stop)), n_(pb.scale_count),
        m_(static_cast<int>(pb.constraint_count())) {
    evaluate(pb_, pb_.start.data(), ev_);
    v0_ = ev_.largest;  // the aggregate's unit: the largest peak row at the start
    candidates_.reserve(256);
    // The Hessian's lower triangle: every pair for the peaks (the aggregate couples all
    // segments), else the diagonal and each segment's pair (its integral and its row).
    hess_index_.assign(static_cast<std::size_t>(n_) * n_, -1);
    const auto add = [&](int i, int j) {
      if (i < j) std::swap(i, j);
      if (hess_index_[i * n_ + j] >= 0) return;
      hess_index_[i * n_ + j] = static_cast<int>(hess_rows_.size());
      hess_rows_.push_back(i);
      hess_cols_.push_back(j);
    };
    for (int i = 0; i < n_; ++i)
      for (int j = 0; j <= i; ++j)
        if (i == j || pb_.peak()) add(i, j);
    for (const auto& sg : pb_.segments) add(sg.var0, sg.var1);
  }

  const std::vector<Candidate>& candidates() const { return candidates_; }
  const std::vector<double>& final_scales() const { return final_; }
  bool timed_out() const { return timed_out_; }
  int iterations() const { return iterations_; }

  bool get_nlp_info(Ipopt::Index& n, Ipopt::Index& m, Ipopt::Index& nnz_jac_g, Ipopt::Index& nnz_h_lag,
                    IndexStyleEnum& index_style) override {
    n = n_;
    m = m_;
    nnz_jac_g = 2 * static_cast<int>(pb_.regularity_count()) + (pb_.length_row() ? n_ : 0);
    nnz_h_lag = static_cast<Ipopt::Index>(hess_rows_.size());
    index_style = C_STYLE;
    return true;
  }

  bool get_bounds_info(Ipopt::Index, Ipopt::Number* x_l, Ipopt::Number* x_u, Ipopt::Index m, Ipopt::Number* g_l,
                       Ipopt::Number* g_u) override {
    for (int i = 0; i < pb_.scale_count; ++i) {
      x_l[i] = std::log(pb_.lower[i]);
      x_u[i] = std::log(pb_.upper[i]);
    }
    for (int j = 0; j < m; ++j) {
      g_l[j] = 0.0;
      g_u[j] = 2e19;  // unbounded for Ipopt (nlp_upper_bound_inf = 1e19)
    }
    return true;
  }

  bool get_starting_point(Ipopt::Index, bool init_x, Ipopt::Number* x, bool, Ipopt::Number*, Ipopt::Number*,
                          Ipopt::Index, bool, Ipopt::Number*) override {
    if (!init_x) return false;
    for (int i = 0; i < pb_.scale_count; ++i) x[i] = std::log(pb_.start[i]);  // the request's scales
    return true;
  }

  bool eval_f(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Number& obj) override {
    if (!update(x)) return false;
    obj = ev_.f;
    return true;
  }

  bool eval_grad_f(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Number* grad) override {
    if (!update(x)) return false;
    std::copy(ev_.grad.begin(), ev_.grad.end(), grad);
    return true;
  }

  bool eval_g(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Index m, Ipopt::Number* g) override {
    if (!update(x)) return false;
    const int reg = static_cast<int>(pb_.regularity_count());
    for (int j = 0; j < reg; ++j) g[j] = ev_.g[j].f;
    if (m > reg) g[reg] = ev_.length_row;
    return true;
  }

  bool eval_jac_g(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Index m, Ipopt::Index, Ipopt::Index* rows,
                  Ipopt::Index* cols, Ipopt::Number* values) override {
    const int reg = static_cast<int>(pb_.regularity_count());
    if (values == nullptr) {
      for (int j = 0; j < reg; ++j) {
        const auto& sg = pb_.segments[j / pb_.rows_per_segment];
        rows[2 * j] = rows[2 * j + 1] = j;
        cols[2 * j] = sg.var0;
        cols[2 * j + 1] = sg.var1;
      }
      for (int k = 0; m > reg && k < n_; ++k) {
        rows[2 * reg + k] = reg;
        cols[2 * reg + k] = k;
      }
      return true;
    }
    if (!update(x)) return false;
    for (int j = 0; j < reg; ++j) {
      values[2 * j] = ev_.g[j].g[0];
      values[2 * j + 1] = ev_.g[j].g[1];
    }
    for (int k = 0; m > reg && k < n_; ++k) values[2 * reg + k] = ev_.length_grad[k];
    return true;
  }

  // The exact Hessian of the Lagrangian obj_factor f + sum_j lambda_j G_j (lower triangle).
  bool eval_h(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Number obj_factor, Ipopt::Index m,
              const Ipopt::Number* lambda, bool, Ipopt::Index, Ipopt::Index* rows, Ipopt::Index* cols,
              Ipopt::Number* values) override {
    if (values == nullptr) {
      std::copy(hess_rows_.begin(), hess_rows_.end(), rows);
      std::copy(hess_cols_.begin(), hess_cols_.end(), cols);
      return true;
    }
    if (!update(x)) return false;
    for (std::size_t k = 0; k < hess_rows_.size(); ++k) values[k] = obj_factor * ev_.hess[hess_rows_[k] * n_ + hess_cols_[k]];
    const int reg = static_cast<int>(pb_.regularity_count());
    for (int j = 0; j < reg; ++j) {
      const auto& sg = pb_.segments[j / pb_.rows_per_segment];
      const AD& G = ev_.g[j];
      values[hess_index_[sg.var0 * n_ + sg.var0]] += lambda[j] * G.h[0];
      values[hess_index_[sg.var1 * n_ + sg.var1]] += lambda[j] * G.h[2];
      values[hess_index_[std::max(sg.var0, sg.var1) * n_ + std::min(sg.var0, sg.var1)]] += lambda[j] * G.h[1];
    }
    if (m > reg) {  // the length row: -sum of the segments' lengths / max_length
      const double w = -lambda[reg] / pb_.max_length;
      for (std::size_t i = 0; i < pb_.segments.size(); ++i) {
        const auto& sg = pb_.segments[i];
        const AD& L = ev_.length[i];
        values[hess_index_[sg.var0 * n_ + sg.var0]] += w * L.h[0];
        values[hess_index_[sg.var1 * n_ + sg.var1]] += w * L.h[2];
        values[hess_index_[std::max(sg.var0, sg.var1) * n_ + std::min(sg.var0, sg.var1)]] += w * L.h[1];
      }
    }
    return true;
  }

  bool intermediate_callback(Ipopt::AlgorithmMode, Ipopt::Index iter, Ipopt::Number, Ipopt::Number, Ipopt::Number,
                             Ipopt::Number, Ipopt::Number, Ipopt::Number, Ipopt::Number, Ipopt::Number, Ipopt::Index,
                             const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override {
    iterations_ = iter;
    if (Clock::now() >= stop_at_ || stop_.stop_requested()) {
      timed_out_ = true;
      return false;  // User_Requested_Stop
    }
    return true;
  }

  void finalize_solution(Ipopt::SolverReturn, Ipopt::Index, const Ipopt::Number* x, const Ipopt::Number*,
                         const Ipopt::Number*, Ipopt::Index, const Ipopt::Number*, const Ipopt::Number*, Ipopt::Number,
                         const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override {
    final_.resize(pb_.scale_count);
    for (int i = 0; i < pb_.scale_count; ++i) final_[i] = std::clamp(std::exp(x[i]), pb_.lower[i], pb_.upper[i]);
  }

 private:
  // Evaluates at x (its scales exp(y) clamped into the bounds, which Ipopt may leave by its
  // bound relaxation) unless x is the last point, and records it as a candidate if it is regular.
  bool update(const Ipopt::Number* x) {
    if (have_ && std::equal(x, x + pb_.scale_count, x_.begin())) return ev_ok_;
    x_.assign(x, x + pb_.scale_count);
    scales_.resize(pb_.scale_count);
    for (int i = 0; i < pb_.scale_count; ++i) scales_[i] = std::clamp(std::exp(x_[i]), pb_.lower[i], pb_.upper[i]);
    evaluate(pb_, scales_.data(), ev_, v0_);
    have_ = true;
    ev_ok_ = finite(ev_);
    if (ev_ok_ && ev_.regular) candidates_.push_back({scales_, pb_.peak() ? ev_.largest : ev_.f});
    return ev_ok_;
  }

  const Problem& pb_;
  Clock::time_point stop_at_;
  std::stop_token stop_;
  int n_, m_;
  Evaluation ev_;
  double v0_ = 0.0;
  std::vector<double> x_, scales_, final_;
  std::vector<int> hess_index_;                // n x n -> entry of the Hessian's lower triangle, or -1
  std::vector<Ipopt::Index> hess_rows_, hess_cols_;
  bool have_ = false, ev_ok_ = false;
  std::vector<Candidate> candidates_;
  bool timed_out_ = false;
  int iterations_ = 0;
};

const char* ipopt_status_name(Ipopt::ApplicationReturnStatus s) {
  switch (s) {
    case Ipopt::Solve_Succeeded: return "Ipopt: solve succeeded";
    case Ipopt::Solved_To_Acceptable_Level: return "Ipopt: solved to acceptable level";
    case Ipopt::Infeasible_Problem_Detected: return "Ipopt: infeasible problem detected";
    case Ipopt::Search_Direction_Becomes_Too_Small: return "Ipopt: search direction becomes too small";
    case Ipopt::Diverging_Iterates: return "Ipopt: diverging iterates";
    case Ipopt::User_Requested_Stop: return "Ipopt: stopped at the time limit";
    case Ipopt::Feasible_Point_Found: return "Ipopt: feasible point found";
    case Ipopt::Maximum_Iterations_Exceeded: return "Ipopt: maximum iterations exceeded";
    case Ipopt::Restoration_Failed: return "Ipopt: restoration failed";
    case Ipopt::Error_In_Step_Computation: return "Ipopt: error in step computation";
    case Ipopt::Maximum_CpuTime_Exceeded: return "Ipopt: maximum CPU time exceeded";
    case Ipopt::Invalid_Number_Detected: return "Ipopt: invalid number detected";
    default: return "Ipopt: internal failure";
  }
}

TangentScaleResult make_result(const core::PathSpec& raw, const Problem& pb, const std::vector<double>& scales) {
  TangentScaleResult r;
  r.spec = raw;
  r.scales = scales;
  r.length_weight = pb.length_weight;
  // One scale per frame but at cusps: a leaving scale the request gave elsewhere is replaced.
  write_scales(r.spec, pb.approach_var, pb.leave_var, scales.data());
  return r;
}

// The point to return: the solver's final point, then the other regular points it evaluated
// from the best solver objective up (ties in evaluation order), the first that passes the
// verification (regular and resolved on the fine rules) and beats the start by the fine
// measure. At most kMaxVerifications points are measured. Empty when none qualifies.
std::optional<std::pair<std::vector<double>, double>> verified_best(const Problem& pb,
                                                                    const std::vector<double>& final_scales,
                                                                    const std::vector<Candidate>& candidates,
                                                                    double start_value) {
  std::vector<const std::vector<double>*> order;
  if (!final_scales.empty()) order.push_back(&final_scales);
  std::vector<std::size_t> idx(candidates.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  std::stable_sort(idx.begin(), idx.end(),
                   [&](std::size_t a, std::size_t b) { return candidates[a].measure < candidates[b].measure; });
  for (std::size_t i : idx) order.push_back(&candidates[i].scales);
  int measured = 0;
  std::vector<const std::vector<double>*> seen;
  for (const auto* scales : order) {
    if (measured >= kMaxVerifications) break;
    if (std::any_of(seen.begin(), seen.end(), [&](const auto* s) { return *s == *scales; })) continue;
    seen.push_back(scales);
    ++measured;
    const Audit a = audit(pb, scales->data());
    if (a.regular && a.resolved && a.value < start_value) return std::make_pair(*scales, a.value);
  }
  return std::nullopt;
}

// The smoothest reading on NLopt's SLSQP (sequential quadratic programming, bounds and the
// regularity rows as inequality constraints). Each segment depends on every scale through the
// global solve, so the derivatives are central differences in y = ln(scale) of the whole
// evaluation (objective and rows together, step kDifferenceStep): 2 n + 1 global solves per
// gradient for n scales. Ipopt's exact-Hessian model of the lowest-degree reading does not
// apply; SLSQP's quasi-Newton model needs no Hessian. NLopt is reentrant (no global state
// for SLSQP), so no lock is taken. Iterations count evaluations with their gradient.
constexpr double kDifferenceStep = 1e-5;
constexpr double kSlsqpFtolRel = 1e-7;
constexpr double kSlsqpXtolRel = 1e-6;
constexpr double kFailedValue = 1e30;  // an evaluation that failed (singular solve): a bad point for SLSQP

class GlobalSolver {
 public:
  GlobalSolver(const Problem& pb, Clock::time_point stop_at, std::stop_token stop)
      : pb_(pb), stop_at_(stop_at), stop_(std::move(stop)), n_(pb.scale_count),
        m_(static_cast<int>(pb.constraint_count())) {
    GlobalEvaluation start;
    evaluate_global(pb_, pb_.start.data(), start, 0.0, points_);
    v0_ = start.largest;
  }

  // Runs SLSQP from the request's scales; returns NLopt's result.
  nlopt_result run(int max_evaluations) {
    nlopt_opt opt = nlopt_create(NLOPT_LD_SLSQP, static_cast<unsigned>(n_));
    opt_ = opt;
    std::vector<double> lo(n_), hi(n_), y(n_);
    for (int i = 0; i < n_; ++i) {
      lo[i] = std::log(pb_.lower[i]);
      hi[i] = std::log(pb_.upper[i]);
      y[i] = std::clamp(std::log(pb_.start[i]), lo[i], hi[i]);
    }
    nlopt_set_lower_bounds(opt, lo.data());
    nlopt_set_upper_bounds(opt, hi.data());
    nlopt_set_min_objective(opt, &GlobalSolver::objective, this);
    const std::vector<double> tol(m_, 0.0);
    nlopt_add_inequality_mconstraint(opt, static_cast<unsigned>(m_), &GlobalSolver::constraints, this, tol.data());
    nlopt_set_ftol_rel(opt, kSlsqpFtolRel);
    nlopt_set_xtol_rel(opt, kSlsqpXtolRel);
    nlopt_set_maxeval(opt, max_evaluations);
    double f = 0.0;
    const nlopt_result result = nlopt_optimize(opt, y.data(), &f);
    nlopt_destroy(opt);
    opt_ = nullptr;
    final_.resize(n_);
    for (int i = 0; i < n_; ++i) final_[i] = std::clamp(std::exp(y[i]), pb_.lower[i], pb_.upper[i]);
    return result;
  }

  const std::vector<Candidate>& candidates() const { return candidates_; }
  const std::vector<double>& final_scales() const { return final_; }
  bool timed_out() const { return timed_out_; }
  int iterations() const { return iterations_; }

 private:
  static double objective(unsigned, const double* y, double* grad, void* data) {
    auto& s = *static_cast<GlobalSolver*>(data);
    if (!s.update(y, grad != nullptr)) return kFailedValue;
    if (grad) std::copy(s.grad_.begin(), s.grad_.end(), grad);
    return s.ev_.f;
  }

  // NLopt's form c(y) <= 0: c = -G.
  static void constraints(unsigned m, double* result, unsigned n, const double* y, double* grad, void* data) {
    auto& s = *static_cast<GlobalSolver*>(data);
    if (!s.update(y, grad != nullptr)) {
      std::fill(result, result + m, kFailedValue);
      if (grad) std::fill(grad, grad + static_cast<std::size_t>(m) * n, 0.0);
      return;
    }
    for (unsigned j = 0; j < m; ++j) result[j] = -s.ev_.g[j];
    if (grad) {
      for (std::size_t k = 0; k < static_cast<std::size_t>(m) * n; ++k) grad[k] = -s.jac_[k];
    }
  }

  bool out_of_time() {
    if (Clock::now() >= stop_at_ || stop_.stop_requested()) {
      timed_out_ = true;
      if (opt_) nlopt_force_stop(opt_);
      return true;
    }
    return false;
  }

  // Evaluates at y (scales exp(y) clamped into the bounds) unless y is the last point, and its
  // derivatives if asked; records a regular point as a candidate.
  bool update(const double* y, bool derivatives) {
    const bool same = have_ && std::equal(y, y + n_, y_.begin());
    if (same && (!derivatives || have_derivatives_)) return ok_;
    if (out_of_time()) return false;
    if (!same) {
      y_.assign(y, y + n_);
      scales_.resize(n_);
      for (int i = 0; i < n_; ++i) scales_[i] = std::clamp(std::exp(y_[i]), pb_.lower[i], pb_.upper[i]);
      evaluate_global(pb_, scales_.data(), ev_, v0_, points_);
      have_ = true;
      have_derivatives_ = false;
      ok_ = ev_.ok;
      if (ok_ && ev_.regular) candidates_.push_back({scales_, pb_.peak() ? ev_.largest : ev_.f});
    }
    if (!ok_ || !derivatives) return ok_;
    ++iterations_;
    grad_.assign(n_, 0.0);
    jac_.assign(static_cast<std::size_t>(m_) * n_, 0.0);
    std::vector<double> probe = scales_;
    GlobalEvaluation plus, minus;
    for (int k = 0; k < n_; ++k) {
      if (out_of_time()) return false;
      probe[k] = scales_[k] * std::exp(kDifferenceStep);
      evaluate_global(pb_, probe.data(), plus, v0_, points_);
      probe[k] = scales_[k] * std::exp(-kDifferenceStep);
      evaluate_global(pb_, probe.data(), minus, v0_, points_);
      probe[k] = scales_[k];
      if (!plus.ok || !minus.ok) continue;  // a singular neighbour: no slope along k
      grad_[k] = (plus.f - minus.f) / (2.0 * kDifferenceStep);
      for (int j = 0; j < m_; ++j) jac_[j * n_ + k] = (plus.g[j] - minus.g[j]) / (2.0 * kDifferenceStep);
    }
    have_derivatives_ = true;
    return true;
  }

  const Problem& pb_;
  Clock::time_point stop_at_;
  std::stop_token stop_;
  int n_, m_;
  nlopt_opt opt_ = nullptr;
  double v0_ = 0.0;
  GlobalEvaluation ev_;
  std::vector<ControlPoints<double>> points_;
  std::vector<double> y_, scales_, grad_, jac_, final_;
  bool have_ = false, have_derivatives_ = false, ok_ = false;
  std::vector<Candidate> candidates_;
  bool timed_out_ = false;
  int iterations_ = 0;
};

const char* nlopt_status_name(nlopt_result r) {
  switch (r) {
    case NLOPT_SUCCESS: return "SLSQP: converged";
    case NLOPT_STOPVAL_REACHED: return "SLSQP: objective value reached";
    case NLOPT_FTOL_REACHED: return "SLSQP: converged (objective tolerance)";
    case NLOPT_XTOL_REACHED: return "SLSQP: converged (step tolerance)";
    case NLOPT_MAXEVAL_REACHED: return "SLSQP: evaluation limit reached";
    case NLOPT_MAXTIME_REACHED: return "SLSQP: time limit reached";
    case NLOPT_ROUNDOFF_LIMITED: return "SLSQP: stopped by rounding";
    case NLOPT_FORCED_STOP: return "SLSQP: stopped at the time limit";
    case NLOPT_INVALID_ARGS: return "SLSQP: invalid arguments";
    case NLOPT_OUT_OF_MEMORY: return "SLSQP: out of memory";
    default: return "SLSQP: failure";
  }
}

}  // namespace

namespace {

// One Ipopt solve of `options.objective` from the scales of `spec`.
core::Expected<TangentScaleResult> optimize_from(const core::PathSpec& spec, const TangentScaleOptions& options) {
  const auto t0 = Clock::now();
  auto problem = make_problem(spec, options);
  if (!problem) return tl::unexpected(std::move(problem.error()));
  const Problem& pb = *problem;

  Clock::time_point stop_at = options.deadline;
  if (options.budget_seconds) {
    const auto budget = std::chrono::duration<double>(std::min(*options.budget_seconds, 1e9));
    stop_at = std::min(stop_at, t0 + std::chrono::duration_cast<Clock::duration>(budget));
  }

  OptimizerReport report;
  report.objective_before = audit(pb, pb.start.data()).value;
  const auto finish = [&](const std::vector<double>& scales, double objective) {
    report.objective_after = objective;
    report.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    TangentScaleResult r = make_result(spec, pb, scales);
    r.report = report;
    return r;
  };

  if (!std::isfinite(report.objective_before)) {
    report.status = OptimizerStatus::kFailed;
    report.message = "the objective is not finite at the start";
    return finish(pb.start, report.objective_before);
  }
  if (Clock::now() >= stop_at || options.stop.stop_requested()) {
    report.status = OptimizerStatus::kTimeLimit;
    report.message = "no time left before the first iteration";
    return finish(pb.start, report.objective_before);
  }

  if (pb.global) {
    GlobalSolver solver(pb, stop_at, options.stop);
    const nlopt_result result = solver.run(std::max(1, options.max_iterations));
    report.iterations = solver.iterations();
    report.message = nlopt_status_name(result);
    switch (result) {
      case NLOPT_SUCCESS:
      case NLOPT_STOPVAL_REACHED:
      case NLOPT_FTOL_REACHED:
      case NLOPT_XTOL_REACHED:
      case NLOPT_ROUNDOFF_LIMITED: report.status = OptimizerStatus::kConverged; break;
      case NLOPT_MAXEVAL_REACHED: report.status = OptimizerStatus::kIterationLimit; break;
      case NLOPT_FORCED_STOP:
      case NLOPT_MAXTIME_REACHED: report.status = OptimizerStatus::kTimeLimit; break;
      default: report.status = OptimizerStatus::kFailed; break;
    }
    if (solver.timed_out()) report.status = OptimizerStatus::kTimeLimit;
    if (report.status == OptimizerStatus::kFailed) return finish(pb.start, report.objective_before);
    const auto best = verified_best(pb, solver.final_scales(), solver.candidates(), report.objective_before);
    if (!best) {
      if (report.status != OptimizerStatus::kTimeLimit) report.status = OptimizerStatus::kNoImprovement;
      report.message += "; no regular point beats the start by the fine measure";
      return finish(pb.start, report.objective_before);
    }
    return finish(best->first, best->second);
  }

  // Declared before the application, so released after it is destroyed (ipopt_lock.hpp).
  const auto ipopt = detail::lock_ipopt(stop_at, options.stop);
  if (!ipopt.owns_lock()) {
    report.status = OptimizerStatus::kTimeLimit;
    report.message = "the time ran out while another optimisation held the solver";
    return finish(pb.start, report.objective_before);
  }
  Ipopt::SmartPtr<ScaleNlp> nlp = new ScaleNlp(pb, stop_at, options.stop);
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = IpoptApplicationFactory();
  auto& opts = *app->Options();
  opts.SetIntegerValue("print_level", 0);
  opts.SetStringValue("sb", "yes");
  opts.SetIntegerValue("max_iter", options.max_iterations);
  opts.SetNumericValue("tol", kIpoptTol);
  opts.SetNumericValue("acceptable_tol", kIpoptAcceptableTol);
  opts.SetIntegerValue("acceptable_iter", kIpoptAcceptableIter);
  opts.SetNumericValue("acceptable_obj_change_tol", kIpoptAcceptableObjChange);
  opts.SetStringValue("mu_strategy", "adaptive");
  // The KKT systems have a few dozen rows: no iterative refinement unless the residual asks
  // for it (Ipopt's default always does one, a second MUMPS back-solve per solve).
  opts.SetIntegerValue("min_refinement_steps", 0);
  std::istringstream no_options_file;
  if (app->Initialize(no_options_file) != Ipopt::Solve_Succeeded) {
    report.status = OptimizerStatus::kFailed;
    report.message = "Ipopt did not initialise";
    return finish(pb.start, report.objective_before);
  }
  Ipopt::ApplicationReturnStatus status = app->OptimizeTNLP(nlp);
  report.iterations = nlp->iterations();
  if ((status == Ipopt::Infeasible_Problem_Detected || status == Ipopt::Restoration_Failed) && !nlp->timed_out()) {
    // Again with one regularity row per sample (see kRegularityRows), same application.
    problem->rows_per_segment = kRegularitySamples;
    nlp = new ScaleNlp(pb, stop_at, options.stop);
    status = app->OptimizeTNLP(nlp);
    report.iterations += nlp->iterations();
  }
  report.message = ipopt_status_name(status);

  switch (status) {
    case Ipopt::Solve_Succeeded:
    case Ipopt::Solved_To_Acceptable_Level:
    case Ipopt::Search_Direction_Becomes_Too_Small:
    case Ipopt::Feasible_Point_Found: report.status = OptimizerStatus::kConverged; break;
    case Ipopt::Maximum_Iterations_Exceeded: report.status = OptimizerStatus::kIterationLimit; break;
    case Ipopt::User_Requested_Stop:
    case Ipopt::Maximum_CpuTime_Exceeded: report.status = OptimizerStatus::kTimeLimit; break;
    default: report.status = OptimizerStatus::kFailed; break;
  }
  if (nlp->timed_out()) report.status = OptimizerStatus::kTimeLimit;
  if (report.status == OptimizerStatus::kFailed) return finish(pb.start, report.objective_before);

  const auto best = verified_best(pb, nlp->final_scales(), nlp->candidates(), report.objective_before);
  if (!best) {
    if (report.status != OptimizerStatus::kTimeLimit) report.status = OptimizerStatus::kNoImprovement;
    report.message += "; no regular point beats the start by the fine measure";
    return finish(pb.start, report.objective_before);
  }
  return finish(best->first, best->second);
}

}  // namespace

core::Expected<TangentScaleResult> optimize_tangent_scales(const core::PathSpec& spec,
                                                           const TangentScaleOptions& options) {
  const bool peak = options.objective == TangentScaleObjective::kPeakCurvature ||
                    options.objective == TangentScaleObjective::kPeakTorsion;
  if (!peak) return optimize_from(spec, options);
  // The peak objectives are rugged (a soft maximum over samples): from the request's scales
  // Ipopt may stop in a poor local optimum (thesis path C, peak curvature: 188 1/m). The
  // bending-energy optimum, a smooth and well-conditioned problem, is a far better start
  // (path C: 20.0 1/m). Both solves share the deadline; the result is never worse than the
  // request, and when the warm start does not beat it, the direct solve runs as before.
  const auto t0 = Clock::now();
  TangentScaleOptions smooth = options;
  smooth.objective = TangentScaleObjective::kBendingEnergy;  // with the request's length weight, or the default
  auto first = optimize_from(spec, smooth);
  if (!first) return first;
  const auto before = tangent_scale_objective(spec, options);
  if (!before) return tl::unexpected(before.error());
  if (first->report.status == OptimizerStatus::kConverged) {
    auto second = optimize_from(first->spec, options);
    if (!second) return second;
    if (second->report.objective_after < *before) {
      second->report.objective_before = *before;
      second->report.iterations += first->report.iterations;
      second->report.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      if (second->report.status == OptimizerStatus::kNoImprovement) {
        second->report.status = OptimizerStatus::kConverged;  // the bending optimum itself is the answer
      }
      second->report.message = "from the bending-energy optimum (" + std::to_string(first->report.iterations) +
                               " iterations); " + second->report.message;
      return second;
    }
  }
  auto direct = optimize_from(spec, options);
  if (direct) direct->report.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return direct;
}

core::Expected<double> tangent_scale_objective(const core::PathSpec& spec, const TangentScaleOptions& options) {
  auto problem = make_problem(spec, options);
  if (!problem) return tl::unexpected(std::move(problem.error()));
  std::vector<double> scales;
  for (std::size_t i = 0; i < problem->spec.frames.size(); ++i) {
    const auto& f = problem->spec.frames[i];
    scales.push_back(core::side_scale(f, false));
    if (problem->leave_var[i] != problem->approach_var[i]) scales.push_back(core::side_scale(f, true));
  }
  if (problem->global) {
    GlobalEvaluation ev;
    std::vector<ControlPoints<double>> points;
    evaluate_global(*problem, scales.data(), ev, 0.0, points);
    if (!ev.ok) {
      return tl::unexpected(core::Violations{{"path", "the smoothest solve at these tangent scales is singular"}});
    }
    return problem->peak() ? std::sqrt(ev.largest) : ev.f;
  }
  Evaluation ev;
  evaluate(*problem, scales.data(), ev);
  return reported(*problem, ev);
}

core::Expected<ObjectiveGradient> tangent_scale_gradient(const core::PathSpec& spec, const std::vector<double>& scales,
                                                         const TangentScaleOptions& options) {
  auto problem = make_problem(spec, options);
  if (!problem) return tl::unexpected(std::move(problem.error()));
  const Problem& pb = *problem;
  if (scales.size() != static_cast<std::size_t>(pb.scale_count)) {
    return tl::unexpected(core::Violations{{"scales", "expected " + std::to_string(pb.scale_count) + " scales, got " +
                                                          std::to_string(scales.size())}});
  }
  if (pb.global) {
    // Central differences in ln(scale) of the value (see GlobalSolver).
    const auto value_at = [&](const std::vector<double>& at, double& v) {
      GlobalEvaluation ev;
      std::vector<ControlPoints<double>> points;
      evaluate_global(pb, at.data(), ev, 0.0, points);
      v = pb.peak() ? ev.largest : ev.f;
      return ev.ok;
    };
    ObjectiveGradient out;
    if (!value_at(scales, out.value)) {
      return tl::unexpected(core::Violations{{"path", "the smoothest solve at these tangent scales is singular"}});
    }
    out.gradient.assign(pb.scale_count, 0.0);
    std::vector<double> probe = scales;
    for (int k = 0; k < pb.scale_count; ++k) {
      double plus = 0.0, minus = 0.0;
      probe[k] = scales[k] * std::exp(kDifferenceStep);
      const bool a = value_at(probe, plus);
      probe[k] = scales[k] * std::exp(-kDifferenceStep);
      const bool b = value_at(probe, minus);
      probe[k] = scales[k];
      if (a && b) out.gradient[k] = (plus - minus) / (2.0 * kDifferenceStep) / scales[k];
    }
    return out;
  }
  Evaluation ev;
  evaluate(pb, scales.data(), ev);
  ObjectiveGradient out;
  out.value = ev.f;
  out.gradient = ev.grad;
  if (pb.peak()) {
    const auto it = std::max_element(ev.peak.begin(), ev.peak.end());  // first of equal maxima
    const std::size_t row = static_cast<std::size_t>(it - ev.peak.begin());
    const auto& sg = pb.segments[row / kPeakSamples];
    out.value = ev.largest;
    out.gradient.assign(pb.scale_count, 0.0);
    out.gradient[sg.var0] = ev.peak[row].g[0];
    out.gradient[sg.var1] = ev.peak[row].g[1];
  }
  for (int i = 0; i < pb.scale_count; ++i) out.gradient[i] /= scales[i];  // d/ds = (d/dy) / s
  return out;
}

}  // namespace geotraj::optim
