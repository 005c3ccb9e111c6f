#include "geotraj/optim/tangent_scales.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <utility>

#include <ceres/jet.h>
#include <coin/IpIpoptApplication.hpp>
#include <coin/IpTNLP.hpp>

#include "geotraj/core/bezier.hpp"
#include "geotraj/core/constraints.hpp"
#include "geotraj/core/differential_geometry.hpp"
#include "geotraj/core/validate.hpp"

namespace geotraj::optim {
namespace {

using Clock = std::chrono::steady_clock;
using Eigen::Vector3d;
template <class S>
using Vec3 = Eigen::Matrix<S, 3, 1>;
// Each segment depends on two scales: forward-mode dual numbers with two directions.
using Dual = ceres::Jet<double, 2>;

double value_of(double x) { return x; }
double value_of(const Dual& x) { return x.a; }

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
// A regularity row counts as met down to this (rows are scaled to 1 at the floor).
constexpr double kFeasibilityTolerance = 1e-6;
// The peak objectives minimise a smooth aggregate of the peak rows v_j (kappa^2 or weighted
// tau^2 at the samples), the log-sum-exp (Kreisselmeier-Steinhauser) function
//   F = ln( sum_j ((v_j + eps) / v_0)^q ) / q,  v_0 the largest row at the start,
// an upper bound of ln(max_j v_j / v_0) within ln(rows) / q: the minimax problem without an
// epigraph row per sample (which an interior-point method holds back with its barrier). q =
// kAggregatePower; eps = kPeakEps v_0 keeps straight points finite.
constexpr double kAggregatePower = 48.0;
constexpr double kPeakEps = 1e-12;
constexpr const char* kOptionsField = "optimize.tangentScales.";
// Ipopt. Most of its time goes to the linear solver (MUMPS), whose back-solves grow with the
// quasi-Newton history, so the history is short (4 pairs for at most a few dozen scales).
// tol 1e-6 on Ipopt's scaled KKT error; Ipopt stops earlier at the acceptable level (KKT
// error 1e-3) once the objective changes by less than 1e-4 relative on 2 successive
// iterations: below the fixed rules' own accuracy (kRuleAgreement) there is nothing to gain.
constexpr int kIpoptHistory = 4;
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
double bernstein_derivative(int d, int i, int k, double u) {
  if (k > d) return 0.0;
  double sum = 0.0;
  for (int j = 0; j <= k; ++j) {
    const int m = i - j, n = d - k;
    if (m < 0 || m > n) continue;
    const double b = core::binomial(n, m) * std::pow(u, m) * std::pow(1.0 - u, n - m);
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
  TangentScaleObjective objective = TangentScaleObjective::kBendingEnergy;
  double length_weight = 0.0;
  int scale_count = 0;
  std::vector<int> approach_var, leave_var;  // per frame
  std::vector<double> lower, upper, start;   // per scale [m]
  std::vector<SegmentVars> segments;
  Rule rule, audit_rule;
  std::map<int, Tables> tables;  // by degree

  bool peak() const {
    return objective == TangentScaleObjective::kPeakCurvature || objective == TangentScaleObjective::kPeakTorsion;
  }
  std::size_t peak_rows() const { return peak() ? segments.size() * kPeakSamples : 0; }
  std::size_t constraint_count() const { return segments.size() * kRegularitySamples; }
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
  start[0] = f0.p_W.cast<S>();
  core::side_derivatives<S>(f0, pb.spec.convention, sg.T0, sg.N0, s0, d);
  for (int k = 1; k <= sg.n0; ++k) start[k] = d[k - 1];
  end[0] = f1.p_W.cast<S>();
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

// The regularity rows of one segment: |p'|^2 / speed_floor^2 (>= 1 when met).
template <class S>
void segment_speeds(const SegmentVars& sg, const ControlPoints<S>& b, const BasisTable& t, S* out) {
  const int d = t.degree;
  for (std::size_t j = 0; j < t.points; ++j) {
    out[j] = combine(&t.w[1][j * (d + 1)], b, d).squaredNorm() / sg.speed_floor2;
  }
}

// Everything at one point (the scales): values and exact derivatives.
struct Evaluation {
  double f = 0.0;                                // the solver's objective (peaks: the aggregate F)
  std::vector<double> grad;                      // d f / d scales
  double largest = 0.0;                          // peaks: the largest peak row [1/m^2]
  std::vector<double> peak;                      // peaks: the rows v_j [1/m^2]
  std::vector<std::array<double, 2>> peak_grad;  // d v_j / d (var0, var1) of its segment
  std::vector<double> g;                         // regularity rows
  std::vector<std::array<double, 2>> g_grad;     // d g_j / d (var0, var1) of its segment
  bool regular = false;                          // every regularity row met
};

// The solver's objective and rows at `scales`, with AD derivatives. Each segment's control
// points are computed once (in two-direction dual numbers: its two scales) and shared by its
// rows. `v0` scales the aggregate (peaks; <= 0: the largest row here). No allocation once
// `ev` has its size.
void evaluate(const Problem& pb, const double* scales, Evaluation& ev, double v0 = 0.0) {
  ev.grad.assign(pb.scale_count, 0.0);
  ev.peak.resize(pb.peak_rows());
  ev.peak_grad.resize(pb.peak_rows());
  ev.g.resize(pb.constraint_count());
  ev.g_grad.resize(pb.constraint_count());
  std::array<Dual, std::max(kPeakSamples, kRegularitySamples)> rows;
  double energy = 0.0, length = 0.0;
  ev.largest = 0.0;
  ev.regular = true;
  for (std::size_t i = 0; i < pb.segments.size(); ++i) {
    const auto& sg = pb.segments[i];
    ControlPoints<Dual> b;
    control_points(pb, sg, Dual(scales[sg.var0], 0), Dual(scales[sg.var1], 1), b);
    if (pb.peak()) {
      segment_peaks(pb, sg, b, sg.tables->peak, false, rows.data());
      for (int j = 0; j < kPeakSamples; ++j) {
        const std::size_t row = i * kPeakSamples + j;
        ev.peak[row] = rows[j].a;
        ev.peak_grad[row] = {rows[j].v[0], rows[j].v[1]};
        ev.largest = std::max(ev.largest, rows[j].a);
      }
    } else {
      Dual e, l;
      segment_integrals(pb, b, sg.tables->quad, pb.rule, e, l);
      const Dual f = pb.objective == TangentScaleObjective::kArcLength ? l : e + l * pb.length_weight;
      energy += e.a;
      length += l.a;
      ev.grad[sg.var0] += f.v[0];
      ev.grad[sg.var1] += f.v[1];
    }
    segment_speeds(sg, b, sg.tables->regular, rows.data());
    for (int j = 0; j < kRegularitySamples; ++j) {
      const std::size_t row = i * kRegularitySamples + j;
      ev.g[row] = rows[j].a;
      ev.g_grad[row] = {rows[j].v[0], rows[j].v[1]};
      if (!(rows[j].a >= 1.0 - kFeasibilityTolerance)) ev.regular = false;
    }
  }
  if (!pb.peak()) {
    ev.f = pb.objective == TangentScaleObjective::kArcLength ? length : energy + pb.length_weight * length;
    return;
  }
  // The aggregate F (see kAggregatePower) by log-sum-exp, shifted by its largest term.
  if (!(v0 > 0.0)) v0 = ev.largest > 0.0 ? ev.largest : 1.0;
  const double eps = kPeakEps * v0;
  const double top = kAggregatePower * std::log((ev.largest + eps) / v0);
  double sum = 0.0;
  for (std::size_t row = 0; row < ev.peak.size(); ++row) {
    const double a = kAggregatePower * std::log((ev.peak[row] + eps) / v0);
    const double w = std::exp(a - top);
    sum += w;
    // dF/dv_j = softmax_j / (v_j + eps); the softmax's sum is applied below.
    const auto& sg = pb.segments[row / kPeakSamples];
    const double dv = w / (ev.peak[row] + eps);
    ev.grad[sg.var0] += dv * ev.peak_grad[row][0];
    ev.grad[sg.var1] += dv * ev.peak_grad[row][1];
  }
  for (double& g : ev.grad) g /= sum;
  ev.f = (top + std::log(sum)) / kAggregatePower;
}

// The solver's objective in its reported unit (square root of the peak rows).
double reported(const Problem& pb, const Evaluation& ev) { return pb.peak() ? std::sqrt(ev.largest) : ev.f; }

bool finite(const Evaluation& ev) {
  if (!std::isfinite(ev.f)) return false;
  for (double v : ev.peak)
    if (!std::isfinite(v)) return false;
  for (double v : ev.grad)
    if (!std::isfinite(v)) return false;
  for (double v : ev.g)
    if (!std::isfinite(v)) return false;
  for (const auto& r : ev.g_grad)
    if (!std::isfinite(r[0]) || !std::isfinite(r[1])) return false;
  return true;
}

// The verification measure of one point, in double, on rules kAuditFactor times finer than
// the solver's: the objective in its reported unit (peak torsion with the hard curvature
// floor), and whether the curve stays regular (|p'| >= kAuditSpeedFraction x the floor at
// every fine point) and, for the integrals, whether the solver's rule agrees with the fine
// one to kRuleAgreement.
struct Audit {
  double value = 0.0;
  bool regular = true;
  bool resolved = true;
};

Audit audit(const Problem& pb, const double* scales) {
  Audit a;
  double energy = 0.0, length = 0.0, coarse_energy = 0.0, coarse_length = 0.0, largest = 0.0;
  std::vector<double> values;
  for (const auto& sg : pb.segments) {
    ControlPoints<double> b;
    control_points(pb, sg, scales[sg.var0], scales[sg.var1], b);
    const Tables& t = *sg.tables;
    values.resize(t.audit_points.points);
    segment_speeds(sg, b, t.audit_points, values.data());
    for (double v : values) {
      if (!(v >= kAuditSpeedFraction * kAuditSpeedFraction)) a.regular = false;
    }
    if (pb.peak()) {
      segment_peaks(pb, sg, b, t.audit_points, true, values.data());
      for (double v : values) largest = std::max(largest, v);
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
    return a;
  }
  const bool arc = pb.objective == TangentScaleObjective::kArcLength;
  a.value = arc ? length : energy + pb.length_weight * length;
  const double coarse = arc ? coarse_length : coarse_energy + pb.length_weight * coarse_length;
  a.resolved = std::abs(coarse - a.value) <= kRuleAgreement * std::abs(a.value);
  if (!std::isfinite(a.value)) a.regular = false;
  return a;
}

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

// Validates the path and the options and sets the problem up. Field paths relative to the request.
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
  const std::string range = "[" + fmt(limits.min_tangent_scale) + ", " + fmt(limits.max_tangent_scale) + "] m";
  if (options.min_scale && !scale_ok(*options.min_scale)) {
    violations.push_back({at + "minScale", "must be a tangent scale in " + range + ", got " + fmt(*options.min_scale)});
  }
  if (options.max_scale && !scale_ok(*options.max_scale)) {
    violations.push_back({at + "maxScale", "must be a tangent scale in " + range + ", got " + fmt(*options.max_scale)});
  } else if (options.min_scale && options.max_scale && *options.max_scale < *options.min_scale) {
    violations.push_back({at + "maxScale", "must be >= minScale (" + fmt(*options.min_scale) + " m), got " +
                                               fmt(*options.max_scale)});
  }
  if (!(std::isfinite(options.length_weight) && options.length_weight >= 0.0)) {
    violations.push_back({at + "lengthWeight", "must be >= 0 [1/m^2], got " + fmt(options.length_weight)});
  }
  if (options.budget_seconds && !(*options.budget_seconds >= 0.0)) {
    violations.push_back({at + "budgetSeconds", "must be >= 0 s, got " + fmt(*options.budget_seconds)});
  }
  if (options.max_iterations < 1) {
    violations.push_back({at + "maxIterations", "must be >= 1, got " + std::to_string(options.max_iterations)});
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));

  Problem pb;
  pb.spec = std::move(*valid);
  pb.objective = options.objective;
  pb.length_weight = options.length_weight;
  const auto& frames = pb.spec.frames;
  const std::size_t count = frames.size();
  const bool closed = pb.spec.closed;

  // Variables and bounds.
  pb.approach_var.resize(count);
  pb.leave_var.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const auto& f = frames[i];
    double chord = 0.0;
    if (closed || i > 0) chord = std::max(chord, (f.p_W - frames[(i + count - 1) % count].p_W).norm());
    if (closed || i + 1 < count) chord = std::max(chord, (f.p_W - frames[(i + 1) % count].p_W).norm());
    const double reference = chord > 0.0 ? chord : f.tangent_scale.value_or(1.0);
    double hi = options.max_scale.value_or(10.0 * reference);
    double lo = options.min_scale.value_or(0.1 * reference);
    hi = std::clamp(hi, limits.min_tangent_scale, limits.max_tangent_scale);
    lo = std::clamp(lo, limits.min_tangent_scale, limits.max_tangent_scale);
    if (!options.min_scale) lo = std::min(lo, hi);
    if (!options.max_scale) hi = std::max(hi, lo);
    const int sides = f.cusp ? 2 : 1;
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
  const std::vector<double> peak_u = uniform_points(kPeakSamples);
  const std::vector<double> regular_u = midpoints(kRegularitySamples);
  const std::vector<double> audit_u = uniform_points(kAuditFactor * (kPeakSamples - 1) + 1);
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
    sg.n0 = c0.leave.order;
    sg.n1 = c1.approach.order;
    sg.T0 = c0.leave.T;
    sg.N0 = c0.leave.N;
    sg.T1 = c1.approach.T;
    sg.N1 = c1.approach.N;
    // Coincident frames (chord 0): the floors follow the smaller starting scale instead.
    double chord = (frames[sg.to].p_W - frames[sg.from].p_W).norm();
    if (!(chord > 0.0)) chord = std::min(pb.start[sg.var0], pb.start[sg.var1]);
    sg.speed_floor2 = std::pow(kMinSpeedFraction * chord, 2);
    sg.kappa_floor2 = std::pow(kTorsionCurvatureFraction / chord, 2);
    const int d = sg.n0 + sg.n1 + 1;
    if (!pb.tables.count(d)) {
      Tables t;
      t.quad = basis_table(d, pb.rule.u);
      t.peak = basis_table(d, peak_u);
      t.regular = basis_table(d, regular_u);
      t.audit_quad = basis_table(d, pb.audit_rule.u);
      t.audit_points = basis_table(d, audit_u);
      pb.tables.emplace(d, std::move(t));
    }
    pb.segments.push_back(sg);
  }
  for (auto& sg : pb.segments) sg.tables = &pb.tables.at(sg.n0 + sg.n1 + 1);
  return pb;
}

// ---------------------------------------------------------------------------------------------
// Ipopt.

// Variables: y_i = ln(scale_i) (the scales span two decades and the objectives vary like
// powers of them: in logarithms the quasi-Newton model is far better conditioned).
// Objective: the integral, or the peaks' aggregate F (kAggregatePower). Rows: the regularity
// rows |p'(u_j)|^2 / speed_floor^2 >= 1, each depending on its segment's two scales.
class ScaleNlp : public Ipopt::TNLP {
 public:
  // A point the solver evaluated that meets the regularity rows, with its solver measure
  // (the integral, or the largest peak row).
  struct Candidate {
    std::vector<double> scales;
    double measure = 0.0;
  };

  ScaleNlp(const Problem& pb, Clock::time_point stop_at, std::stop_token stop)
      : pb_(pb), stop_at_(stop_at), stop_(std::move(stop)), n_(pb.scale_count),
        m_(static_cast<int>(pb.constraint_count())) {
    evaluate(pb_, pb_.start.data(), ev_);
    v0_ = ev_.largest;  // the aggregate's unit: the largest peak row at the start
    candidates_.reserve(256);
  }

  const std::vector<Candidate>& candidates() const { return candidates_; }
  const std::vector<double>& final_scales() const { return final_; }
  bool timed_out() const { return timed_out_; }
  int iterations() const { return iterations_; }

  bool get_nlp_info(Ipopt::Index& n, Ipopt::Index& m, Ipopt::Index& nnz_jac_g, Ipopt::Index& nnz_h_lag,
                    IndexStyleEnum& index_style) override {
    n = n_;
    m = m_;
    nnz_jac_g = 2 * m_;
    nnz_h_lag = 0;  // limited-memory quasi-Newton
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
      g_l[j] = 1.0;
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
    for (int i = 0; i < pb_.scale_count; ++i) grad[i] = ev_.grad[i] * scales_[i];  // d/dy = s d/ds
    return true;
  }

  bool eval_g(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Index m, Ipopt::Number* g) override {
    if (!update(x)) return false;
    std::copy(ev_.g.begin(), ev_.g.begin() + m, g);
    return true;
  }

  bool eval_jac_g(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Index m, Ipopt::Index, Ipopt::Index* rows,
                  Ipopt::Index* cols, Ipopt::Number* values) override {
    if (values == nullptr) {
      for (int j = 0; j < m; ++j) {
        const auto& sg = pb_.segments[j / kRegularitySamples];
        rows[2 * j] = rows[2 * j + 1] = j;
        cols[2 * j] = sg.var0;
        cols[2 * j + 1] = sg.var1;
      }
      return true;
    }
    if (!update(x)) return false;
    for (int j = 0; j < m; ++j) {
      const auto& sg = pb_.segments[j / kRegularitySamples];
      values[2 * j] = ev_.g_grad[j][0] * scales_[sg.var0];  // d/dy = s d/ds
      values[2 * j + 1] = ev_.g_grad[j][1] * scales_[sg.var1];
    }
    return true;
  }

  bool eval_h(Ipopt::Index, const Ipopt::Number*, bool, Ipopt::Number, Ipopt::Index, const Ipopt::Number*, bool,
              Ipopt::Index, Ipopt::Index*, Ipopt::Index*, Ipopt::Number*) override {
    return false;  // never called: hessian_approximation = limited-memory
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
  for (std::size_t i = 0; i < r.spec.frames.size(); ++i) {
    auto& f = r.spec.frames[i];
    f.tangent_scale = scales[pb.approach_var[i]];
    if (f.cusp) f.leave_tangent_scale = scales[pb.leave_var[i]];
  }
  return r;
}

// The point to return: the solver's final point, then the other regular points it evaluated
// from the best solver objective up (ties in evaluation order), the first that passes the
// verification (regular and resolved on the fine rules) and beats the start by the fine
// measure. At most kMaxVerifications points are measured. Empty when none qualifies.
std::optional<std::pair<std::vector<double>, double>> verified_best(const Problem& pb, const ScaleNlp& nlp,
                                                                    double start_value) {
  std::vector<const std::vector<double>*> order;
  if (!nlp.final_scales().empty()) order.push_back(&nlp.final_scales());
  std::vector<std::size_t> idx(nlp.candidates().size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  std::stable_sort(idx.begin(), idx.end(),
                   [&](std::size_t a, std::size_t b) { return nlp.candidates()[a].measure < nlp.candidates()[b].measure; });
  for (std::size_t i : idx) order.push_back(&nlp.candidates()[i].scales);
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

}  // namespace

core::Expected<TangentScaleResult> optimize_tangent_scales(const core::PathSpec& spec,
                                                           const TangentScaleOptions& options) {
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

  Ipopt::SmartPtr<ScaleNlp> nlp = new ScaleNlp(pb, stop_at, options.stop);
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = IpoptApplicationFactory();
  auto& opts = *app->Options();
  opts.SetIntegerValue("print_level", 0);
  opts.SetStringValue("sb", "yes");
  // A handful of variables: a limited-memory quasi-Newton Hessian is enough (no exact one).
  opts.SetStringValue("hessian_approximation", "limited-memory");
  opts.SetIntegerValue("limited_memory_max_history", kIpoptHistory);
  opts.SetIntegerValue("max_iter", options.max_iterations);
  opts.SetNumericValue("tol", kIpoptTol);
  opts.SetNumericValue("acceptable_tol", kIpoptAcceptableTol);
  opts.SetIntegerValue("acceptable_iter", kIpoptAcceptableIter);
  opts.SetNumericValue("acceptable_obj_change_tol", kIpoptAcceptableObjChange);
  opts.SetStringValue("mu_strategy", "adaptive");
  std::istringstream no_options_file;
  if (app->Initialize(no_options_file) != Ipopt::Solve_Succeeded) {
    report.status = OptimizerStatus::kFailed;
    report.message = "Ipopt did not initialise";
    return finish(pb.start, report.objective_before);
  }
  const Ipopt::ApplicationReturnStatus status = app->OptimizeTNLP(nlp);
  report.iterations = nlp->iterations();
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

  const auto best = verified_best(pb, *nlp, report.objective_before);
  if (!best) {
    if (report.status != OptimizerStatus::kTimeLimit) report.status = OptimizerStatus::kNoImprovement;
    report.message += "; no regular point beats the start by the fine measure";
    return finish(pb.start, report.objective_before);
  }
  return finish(best->first, best->second);
}

core::Expected<double> tangent_scale_objective(const core::PathSpec& spec, const TangentScaleOptions& options) {
  auto problem = make_problem(spec, options);
  if (!problem) return tl::unexpected(std::move(problem.error()));
  std::vector<double> scales;
  for (const auto& f : problem->spec.frames) {
    scales.push_back(core::side_scale(f, false));
    if (f.cusp) scales.push_back(core::side_scale(f, true));
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
    out.gradient[sg.var0] = ev.peak_grad[row][0];
    out.gradient[sg.var1] = ev.peak_grad[row][1];
  }
  return out;
}

}  // namespace geotraj::optim
