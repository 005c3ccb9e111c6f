// The tangent-scale problem's set-up and measures (problem.hpp): the Chapter 5 control points
// of a segment, generic in the scalar, and the objectives, rows and verification on them.
#include "optim/tangent_scales/problem.hpp"

#include <algorithm>
#include <string>
#include <utility>

#include "core/format.hpp"
#include "core/geometry/constraints.hpp"
#include "core/geometry/smoothest.hpp"
#include "core/geometry/validate.hpp"

namespace geotraj::optim::tangent_scales_detail {
namespace {

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

bool finite(const AD& x) {
  return std::isfinite(x.f) && std::isfinite(x.g[0]) && std::isfinite(x.g[1]) && std::isfinite(x.h[0]) &&
         std::isfinite(x.h[1]) && std::isfinite(x.h[2]);
}

// At the verification, |p'| may dip between the regularity samples to this fraction of the
// floor (a polynomial of degree <= 16 between samples 1/32 apart moves little).
constexpr double kAuditSpeedFraction = 0.5;
// The integral objectives on the solver's rule and on the 8 times finer rule must agree to
// this (relative) for a point to be returned: the solver's rule resolved the curve.
constexpr double kRuleAgreement = 1e-3;
// A regularity sample counts as met down to this (relative, in |p'|^2).
constexpr double kFeasibilityTolerance = 1e-6;
// A regularity row is a soft minimum of its samples' ln(|p'|^2 / floor^2) with this power (see
// regularity_rows): it lies at most ln(4) / 64 = 0.022 below the smallest of its 4 samples, so
// it is conservative (row >= 0 implies every sample meets the floor) and raises the floor by
// at most 1.1 % in |p'| (all 4 samples equally close), less when only one approaches it.
constexpr double kRegularityAggregatePower = 64.0;
// The peak objectives minimise a smooth aggregate of the peak rows v_j (kappa^2 or weighted
// tau^2 at the samples), the log-sum-exp (Kreisselmeier-Steinhauser) function
//   F = ln( sum_j ((v_j + eps) / v_0)^q ) / q,  v_0 the largest row at the start,
// an upper bound of ln(max_j v_j / v_0) within ln(rows) / q: the minimax problem without an
// epigraph row per sample (which an interior-point method holds back with its barrier). q =
// kAggregatePower; eps = kPeakEps v_0 keeps straight points finite.
constexpr double kAggregatePower = 48.0;
constexpr double kPeakEps = 1e-12;

constexpr const char* kOptionsField = "optimize.tangentScales.";

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

bool side_scale_differs(const core::KeyFrame& f) {
  return f.leave_tangent_scale && core::side_scale(f, true) != core::side_scale(f, false);
}

}  // namespace

void evaluate(const Problem& pb, const double* scales, Evaluation& ev, double v0) {
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

double reported(const Problem& pb, const Evaluation& ev) { return pb.peak() ? std::sqrt(ev.largest) : ev.f; }

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

}  // namespace geotraj::optim::tangent_scales_detail
