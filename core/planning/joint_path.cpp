// Joint-space paths through waypoints: the blended polyline, its time-optimal timing and
// its samples. See joint_path.hpp.
#include "core/planning/joint_path.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <tuple>

#include "core/format.hpp"
#include "core/planning/time_optimal.hpp"
#include "core/planning/time_optimal_detail.hpp"
#include "core/robot/dynamics.hpp"

namespace geotraj::core {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// A continuous joint's waypoints are bounded so that sigma and the sums stay exact enough.
constexpr double kMaxContinuousPosition = 1e6;
// A corner whose directions differ by less than this is passed on the line.
constexpr double kStraight = 1e-12;
// d1 . d2 below -1 + this: the path reverses (a rest).
constexpr double kReversal = 1e-9;
// The blend's shape c is searched in [kShapeLow, kShapeHigh] (c = 1/2 puts P2 = P3 = w).
constexpr double kShapeLow = 0.02, kShapeHigh = 0.5;

// g(c): the middle of the blend is w + g(c) l (d2 - d1).
double middle_factor(double c) { return (16.0 - 25.0 * c) / 32.0; }

// The quintic Bezier's derivatives at t from its forward differences: B' = 5 sum C(4,k)
// b_k D1_k, B'' = 20 sum C(3,k) b_k D2_k, B''' = 60 sum C(2,k) b_k D3_k (Bernstein b_k).
template <class V>
void bezier5(const std::array<V, 6>& P, double t, V& b, V& b1, V& b2, V& b3, bool third = true) {
  const double s = 1.0 - t;
  const double t2 = t * t, s2 = s * s, t3 = t2 * t, s3 = s2 * s, t4 = t3 * t, s4 = s3 * s;
  b = s4 * s * P[0] + 5.0 * s4 * t * P[1] + 10.0 * s3 * t2 * P[2] + 10.0 * s2 * t3 * P[3] + 5.0 * s * t4 * P[4] +
      t4 * t * P[5];
  b1 = 5.0 * (s4 * (P[1] - P[0]) + 4.0 * s3 * t * (P[2] - P[1]) + 6.0 * s2 * t2 * (P[3] - P[2]) +
              4.0 * s * t3 * (P[4] - P[3]) + t4 * (P[5] - P[4]));
  b2 = 20.0 * (s3 * (P[2] - 2.0 * P[1] + P[0]) + 3.0 * s2 * t * (P[3] - 2.0 * P[2] + P[1]) +
               3.0 * s * t2 * (P[4] - 2.0 * P[3] + P[2]) + t3 * (P[5] - 2.0 * P[4] + P[3]));
  if (!third) return;
  b3 = 60.0 * (s2 * (P[3] - 3.0 * P[2] + 3.0 * P[1] - P[0]) + 2.0 * s * t * (P[4] - 3.0 * P[3] + 3.0 * P[2] - P[1]) +
               t2 * (P[5] - 3.0 * P[4] + 3.0 * P[3] - P[2]));
}

// The blend's control points for the corner at w (directions d1 in, d2 out), shape c,
// half-length l.
template <class V>
std::array<V, 6> blend_points(const V& w, const V& d1, const V& d2, double c, double l) {
  return {V(w - l * d1), V(w - (1.0 - c) * l * d1), V(w - (1.0 - 2.0 * c) * l * d1),
          V(w + (1.0 - 2.0 * c) * l * d2), V(w + (1.0 - c) * l * d2), V(w + l * d2)};
}

// The c in [kShapeLow, kShapeHigh] where cost is smallest: a scan of 13 shapes, then a
// golden section around the best.
template <class Cost>
double smallest_shape(const Cost& cost) {
  constexpr int kScan = 13;
  double best_c = kShapeLow, best = kInf;
  for (int i = 0; i < kScan; ++i) {
    const double c = kShapeLow + (kShapeHigh - kShapeLow) * i / (kScan - 1);
    if (const double f = cost(c); f < best) best = f, best_c = c;
  }
  const double step = (kShapeHigh - kShapeLow) / (kScan - 1);
  double lo = std::max(kShapeLow, best_c - step), hi = std::min(kShapeHigh, best_c + step);
  const double phi = (std::sqrt(5.0) - 1.0) / 2.0;
  double x1 = hi - phi * (hi - lo), x2 = lo + phi * (hi - lo), f1 = cost(x1), f2 = cost(x2);
  for (int i = 0; i < 16; ++i) {
    if (f1 < f2) {
      hi = x2, x2 = x1, f2 = f1, x1 = hi - phi * (hi - lo), f1 = cost(x1);
    } else {
      lo = x1, x1 = x2, f1 = f2, x2 = lo + phi * (hi - lo), f2 = cost(x2);
    }
  }
  return best < std::min(f1, f2) ? best_c : (f1 < f2 ? x1 : x2);
}

// The two shapes of a corner of angle theta that matter (they depend on theta alone): the
// one of the smallest peak curvature kappa_1(c) (the blend's length fixed by its lines), and
// the one of the smallest kappa_1(c) g(c) (its length tolerance / (g(c) gap): the deviation
// fixed). Tabulated once, at kShapeAngles + 1 angles over [0, pi], interpolated linearly.
constexpr int kShapeAngles = 64;
struct ShapeTable {
  std::array<double, kShapeAngles + 1> fixed_length{}, fixed_deviation{};
};

const ShapeTable& shape_table() {
  static const ShapeTable table = [] {
    ShapeTable t;
    for (int i = 0; i <= kShapeAngles; ++i) {
      // The ends stand for the angles just inside them (straight and reversing corners are not
      // blended).
      const double theta = std::numbers::pi * std::clamp(static_cast<double>(i), 0.25, kShapeAngles - 0.25) / kShapeAngles;
      t.fixed_length[static_cast<std::size_t>(i)] = smallest_shape([&](double c) { return blend_peak_curvature(c, theta); });
      t.fixed_deviation[static_cast<std::size_t>(i)] =
          smallest_shape([&](double c) { return blend_peak_curvature(c, theta) * middle_factor(c); });
    }
    return t;
  }();
  return table;
}

double interpolated(const std::array<double, kShapeAngles + 1>& table, double theta) {
  const double x = std::clamp(theta / std::numbers::pi, 0.0, 1.0) * kShapeAngles;
  const auto i = std::min(static_cast<std::size_t>(x), static_cast<std::size_t>(kShapeAngles - 1));
  const double f = x - static_cast<double>(i);
  return (1.0 - f) * table[i] + f * table[i + 1];
}

// The shape and half-length of a corner of angle theta with |d2 - d1| = gap: the c that
// makes the largest curvature kappa_1(c) / l(c) smallest, where l(c) is the largest the
// tolerance allows (tolerance / (g(c) gap)) within `available`. The tolerance sets l for c
// below c_x, where g(c_x) = tolerance / (available gap) (g decreases), the line above it: the
// best c is the table's fixed-deviation shape if it lies below c_x, its fixed-length shape if
// above, or c_x (three evaluations of the curvature instead of a search at every corner).
std::pair<double, double> corner_shape(double theta, double gap, double tolerance, double available) {
  auto length = [&](double c) { return std::min(available, tolerance / (middle_factor(c) * gap)); };
  auto cost = [&](double c) { return blend_peak_curvature(c, theta) / length(c); };
  const double c_x = std::clamp((16.0 - 32.0 * tolerance / (available * gap)) / 25.0, kShapeLow, kShapeHigh);
  double best_c = c_x, best = cost(c_x);
  auto consider = [&](double c) {
    if (const double f = cost(c); f < best) best = f, best_c = c;
  };
  const ShapeTable& table = shape_table();
  if (const double c = interpolated(table.fixed_deviation, theta); c < c_x) consider(c);
  if (const double c = interpolated(table.fixed_length, theta); c > c_x) consider(c);
  return {best_c, length(best_c)};
}

JointVector to_vector(const std::vector<double>& v) {
  JointVector q(static_cast<Eigen::Index>(v.size()));
  for (std::size_t j = 0; j < v.size(); ++j) q(static_cast<Eigen::Index>(j)) = v[j];
  return q;
}

// The segment holding sigma, starting from `hint`.
std::size_t find_segment(const JointPath& path, double sigma, std::size_t hint) {
  const auto& seg = path.segments;
  std::size_t i = std::min(hint, seg.size() - 1);
  if (sigma < seg[i].sigma0) {
    const auto it = std::upper_bound(seg.begin(), seg.end(), sigma,
                                     [](double x, const JointPathSegment& s) { return x < s.sigma0; });
    i = it == seg.begin() ? 0 : static_cast<std::size_t>(it - seg.begin()) - 1;
  }
  while (i + 1 < seg.size() && sigma > seg[i].sigma1) ++i;
  return i;
}

}  // namespace

double blend_peak_curvature(double c, double theta) {
  using V = Eigen::Vector2d;
  const V w = V::Zero(), d1(1.0, 0.0), d2(std::cos(theta), std::sin(theta));
  const auto P = blend_points<V>(w, d1, d2, c, 1.0);
  constexpr int kPoints = 65;
  double peak = 0.0;
  V b, b1, b2, b3;
  for (int i = 0; i < kPoints; ++i) {
    bezier5(P, 0.5 * i / (kPoints - 1), b, b1, b2, b3);
    const double speed = b1.norm();
    if (!(speed > 0.0)) return kInf;
    peak = std::max(peak, std::abs(b1.x() * b2.y() - b1.y() * b2.x()) / (speed * speed * speed));
  }
  return peak;
}

Expected<JointPath> build_joint_path(const RobotModel& robot, const JointPathSpec& spec) {
  Violations v;
  const std::size_t n = robot.dof();
  const std::size_t count = spec.waypoints.size();
  if (count < 2) v.push_back({"waypoints", "needs at least 2 waypoints (has " + std::to_string(count) + ")"});
  if (count > kMaxJointWaypoints)
    v.push_back({"waypoints", "has " + std::to_string(count) + " waypoints, more than the " +
                                  std::to_string(kMaxJointWaypoints) + " a joint path may have"});
  if (!std::isfinite(spec.blend_tolerance) || spec.blend_tolerance < 0.0)
    v.push_back({"blendTolerance", "must be finite and >= 0 (is " + number(spec.blend_tolerance) + ")"});
  for (std::size_t i = 0; i < count && i < kMaxJointWaypoints && v.size() < 64; ++i) {
    const auto& p = spec.waypoints[i].positions;
    const std::string field = "waypoints[" + std::to_string(i) + "].positions";
    if (p.size() != n) {
      v.push_back({field, "has " + std::to_string(p.size()) + " values; the " + robot.name + " has " +
                              std::to_string(n) + " joints"});
      continue;
    }
    for (std::size_t j = 0; j < n; ++j) {
      const std::string at = field + "[" + std::to_string(j) + "]";
      const JointLimits& lim = robot.limits[j];
      if (!std::isfinite(p[j])) {
        v.push_back({at, "must be finite"});
      } else if (robot.joints[j].type == JointType::kContinuous ? std::abs(p[j]) > kMaxContinuousPosition
                                                                 : !within_position_limits(robot.joints[j].type, lim, p[j])) {
        v.push_back({at, number(p[j]) + " is outside joint " + std::to_string(j) + "'s position limits [" +
                             (robot.joints[j].type == JointType::kContinuous
                                  ? number(-kMaxContinuousPosition) + ", " + number(kMaxContinuousPosition)
                                  : number(lim.min_position) + ", " + number(lim.max_position)) +
                             "]"});
      }
    }
  }
  if (!v.empty()) return tl::make_unexpected(v);

  JointPath path;
  path.dof = n;
  path.waypoints.resize(count);
  // The waypoints kept (consecutive ones within kJointWaypointMerge are one).
  std::vector<JointVector> w;
  std::vector<std::size_t> origin;  // the requested index of each kept waypoint
  std::vector<bool> stop;
  for (std::size_t i = 0; i < count; ++i) {
    JointVector q = to_vector(spec.waypoints[i].positions);
    if (!w.empty() && (q - w.back()).norm() <= kJointWaypointMerge) {
      path.waypoints[i].kind = JointWaypointPass::Kind::kMerged;
      stop.back() = stop.back() || spec.waypoints[i].stop;
      continue;
    }
    w.push_back(std::move(q));
    origin.push_back(i);
    stop.push_back(spec.waypoints[i].stop);
  }
  const std::size_t m = w.size();
  // The last requested waypoint is met exactly: when it merged into the one before, that one
  // becomes it.
  if (m > 0) w.back() = to_vector(spec.waypoints.back().positions);
  path.rests.push_back(0.0);
  path.first = w.front();
  path.last = w.back();
  if (m == 1) {
    for (auto& pass : path.waypoints) pass.sigma = 0.0;
    return path;
  }

  std::vector<JointVector> d(m - 1);
  std::vector<double> L(m - 1);
  for (std::size_t k = 0; k + 1 < m; ++k) {
    const JointVector step = w[k + 1] - w[k];
    L[k] = step.norm();
    d[k] = step / L[k];
  }
  // What each kept waypoint is: a rest, a straight pass or a blend.
  using Kind = JointWaypointPass::Kind;
  std::vector<Kind> kind(m, Kind::kRest);
  std::vector<double> gap(m, 0.0), theta(m, 0.0);
  for (std::size_t k = 1; k + 1 < m; ++k) {
    const double cosine = std::clamp(d[k - 1].dot(d[k]), -1.0, 1.0);
    gap[k] = (d[k] - d[k - 1]).norm();
    theta[k] = 2.0 * std::asin(std::min(1.0, gap[k] / 2.0));  // accurate for small angles too
    if (stop[k] || spec.blend_tolerance == 0.0 || cosine < -1.0 + kReversal) continue;
    kind[k] = gap[k] < kStraight ? Kind::kThrough : Kind::kBlend;
  }
  // Each blend's shape and half-length: half of a line it shares with another blend, all of
  // one that ends at a rest or a straight pass.
  std::vector<double> shape(m, 0.0), half(m, 0.0);
  for (std::size_t k = 1; k + 1 < m; ++k) {
    if (kind[k] != Kind::kBlend) continue;
    const double before = kind[k - 1] == Kind::kBlend ? L[k - 1] / 2.0 : L[k - 1];
    const double after = kind[k + 1] == Kind::kBlend ? L[k] / 2.0 : L[k];
    std::tie(shape[k], half[k]) = corner_shape(theta[k], gap[k], spec.blend_tolerance, std::min(before, after));
  }
  // The segments, back to back in sigma.
  double sigma = 0.0;
  auto pass_at = [&](std::size_t k, Kind what, double at, double deviation) {
    JointWaypointPass& pass = path.waypoints[origin[k]];
    pass.kind = what;
    pass.sigma = at;
    pass.deviation = deviation;
    pass.blend_length = what == Kind::kBlend ? half[k] : 0.0;
    pass.blend_shape = what == Kind::kBlend ? shape[k] : 0.0;
  };
  pass_at(0, Kind::kRest, 0.0, 0.0);
  for (std::size_t k = 0; k + 1 < m; ++k) {
    const double from = kind[k] == Kind::kBlend ? half[k] : 0.0;
    const double to = L[k] - (kind[k + 1] == Kind::kBlend ? half[k + 1] : 0.0);
    if (to - from > 1e-12 * L[k]) {  // blends that take the whole line leave none (to rounding)
      JointPathSegment line;
      line.kind = JointPathSegment::Kind::kLine;
      line.sigma0 = sigma;
      line.sigma1 = sigma + (to - from);
      line.a = from > 0.0 ? JointVector(w[k] + from * d[k]) : w[k];
      line.b = to < L[k] ? JointVector(w[k] + to * d[k]) : w[k + 1];  // a waypoint exactly
      line.d = d[k];
      line.waypoint = origin[k];
      path.segments.push_back(std::move(line));
      sigma = path.segments.back().sigma1;
    }
    const std::size_t c = k + 1;  // the corner at the line's end
    if (kind[c] == Kind::kBlend) {
      JointPathSegment blend;
      blend.kind = JointPathSegment::Kind::kBlend;
      blend.sigma0 = sigma;
      blend.sigma1 = sigma + 5.0 * shape[c] * half[c];
      blend.P = blend_points<JointVector>(w[c], d[k], d[c], shape[c], half[c]);
      blend.waypoint = origin[c];
      pass_at(c, Kind::kBlend, 0.5 * (blend.sigma0 + blend.sigma1), middle_factor(shape[c]) * half[c] * gap[c]);
      path.segments.push_back(std::move(blend));
      sigma = path.segments.back().sigma1;
    } else {
      pass_at(c, kind[c], sigma, 0.0);
      if (kind[c] == Kind::kRest) path.rests.push_back(sigma);
    }
  }
  path.length = sigma;
  // Merged waypoints pass where the waypoint they merged into does.
  for (std::size_t i = 1; i < count; ++i)
    if (path.waypoints[i].kind == Kind::kMerged) path.waypoints[i].sigma = path.waypoints[i - 1].sigma;
  return path;
}

namespace {

// evaluate; without `third`, out.q_sss is not computed (what the grids, the sample check and
// the sampler need: a quarter less work on blends).
void evaluate_point(const JointPath& path, double sigma, JointPathPoint& out, std::size_t& hint, bool third) {
  const auto n = static_cast<Eigen::Index>(path.dof);
  if (path.segments.empty()) {
    out.q = path.first;
    out.q_s.setZero(n), out.q_ss.setZero(n), out.q_sss.setZero(n);
    out.segment = 0;
    return;
  }
  sigma = std::clamp(sigma, 0.0, path.length);
  hint = find_segment(path, sigma, hint);
  const JointPathSegment& seg = path.segments[hint];
  out.segment = hint;
  if (seg.kind == JointPathSegment::Kind::kLine) {
    const double f = std::clamp((sigma - seg.sigma0) / (seg.sigma1 - seg.sigma0), 0.0, 1.0);
    out.q = (1.0 - f) * seg.a + f * seg.b;
    out.q_s = seg.d;
    out.q_ss.setZero(n);
    out.q_sss.setZero(n);
    return;
  }
  const double h = seg.sigma1 - seg.sigma0;
  const double t = std::clamp((sigma - seg.sigma0) / h, 0.0, 1.0);
  bezier5(seg.P, t, out.q, out.q_s, out.q_ss, out.q_sss, third);
  out.q_s /= h;
  out.q_ss /= h * h;
  if (third) out.q_sss /= h * h * h;
}

}  // namespace

void evaluate(const JointPath& path, double sigma, JointPathPoint& out, std::size_t& hint) {
  evaluate_point(path, sigma, out, hint, true);
}

namespace {

// The grid of one portion [r0, r1] of the path: each blend `blend_intervals` intervals
// (cosine spacing in sigma, or uniform), each line by its share of `line_intervals` (at least
// kMinLineIntervals), s from r0; with the joint torques' terms where `torques` (a model with
// torque limits: set_torque_terms).
std::vector<GridPoint> portion_grid(const JointPath& path, double r0, double r1, const JointPathOptions& options,
                                    const RobotModel* torques) {
  double lines = 0.0;
  for (const auto& seg : path.segments)
    if (seg.kind == JointPathSegment::Kind::kLine && seg.sigma1 > r0 && seg.sigma0 < r1) lines += seg.sigma1 - seg.sigma0;
  std::vector<double> sigmas{r0};
  for (const auto& seg : path.segments) {
    if (!(seg.sigma1 > r0 && seg.sigma0 < r1)) continue;
    const double span = seg.sigma1 - seg.sigma0;
    const bool blend = seg.kind == JointPathSegment::Kind::kBlend;
    const std::size_t k =
        blend ? std::max<std::size_t>(2, options.blend_intervals)
              : std::max<std::size_t>(kMinLineIntervals,
                                      static_cast<std::size_t>(std::ceil(static_cast<double>(options.line_intervals) *
                                                                         span / std::max(lines, 1e-300))));
    for (std::size_t i = 1; i <= k; ++i) {
      // A blend's points crowd towards its ends (cosine spacing): the path acceleration is
      // constant on each interval, and the interval that meets a line must already respect
      // the blend's curvature at its far end; a short one leaves the joint accelerations
      // nearly continuous where the blend meets the line.
      const double f = blend && options.crowd_blend_ends ? 0.5 * (1.0 - std::cos(std::numbers::pi * static_cast<double>(i) / static_cast<double>(k)))
                             : static_cast<double>(i) / static_cast<double>(k);
      sigmas.push_back(i == k ? seg.sigma1 : seg.sigma0 + span * f);
    }
  }
  sigmas.back() = r1;
  std::vector<GridPoint> grid;
  grid.reserve(sigmas.size());
  JointPathPoint point, mid;
  std::size_t hint = 0, mid_hint = 0;
  for (const double s : sigmas) {
    if (!grid.empty() && !(s - r0 > grid.back().s)) continue;
    evaluate_point(path, s, point, hint, false);
    if (!grid.empty()) {
      // The limits at the interval's middle too, where the path bends (a blend).
      GridPoint& before = grid.back();
      const double m = r0 + 0.5 * (before.s + (s - r0));
      evaluate_point(path, m, mid, mid_hint, false);
      if (path.segments[mid.segment].kind == JointPathSegment::Kind::kBlend) {
        before.q_s_mid = mid.q_s;
        before.q_ss_mid = mid.q_ss;
      }
    }
    GridPoint g;
    g.s = s - r0;
    g.q_s = point.q_s;
    g.q_ss = point.q_ss;
    if (torques != nullptr) set_torque_terms(*torques, point.q, g);
    grid.push_back(std::move(g));
  }
  return grid;
}

// The portion holding sigma (its index in rests), and the grid interval of portion p.
std::size_t portion_of(const std::vector<double>& rests, double sigma) {
  const auto it = std::upper_bound(rests.begin(), rests.end(), sigma);
  const auto p = static_cast<std::size_t>(std::max<std::ptrdiff_t>(1, it - rests.begin()) - 1);
  return std::min(p, rests.size() - 2);
}

std::size_t interval_of(const std::vector<GridPoint>& grid, double s) {
  const auto it = std::upper_bound(grid.begin(), grid.end(), s, [](double x, const GridPoint& g) { return x < g.s; });
  const auto k = static_cast<std::size_t>(std::max<std::ptrdiff_t>(1, it - grid.begin()) - 1);
  return std::min(k, grid.size() - 2);
}

// One pass over the samples of `plan` at `rate` [Hz] (check_joint_path_samples).
std::optional<Violations> check_pass(const JointPathPlan& plan, double rate, const TimeOptimalLimits& limits,
                                     const JointPathOptions& options, JointPathCheck& out) {
  const std::size_t count = grid_sample_count(plan.duration_s, rate);
  const bool jerk = limits.joint_jerk.size() > 0 && (limits.joint_jerk.array() < kInf).any();
  ProfileCursor cursor;
  std::size_t hint = 0;
  JointPathPoint point;
  JointVector q_ddot, q_ddot_prev, q_dot;
  time_optimal_detail::TorqueScratch scratch;
  const bool torques = limits.joint_torque.size() == static_cast<Eigen::Index>(plan.model->dof());
  double t_prev = 0.0;
  SampleCheck& check = out.check;
  struct Worst {
    double value = 0.0, limit = 0.0, t = 0.0, sigma = 0.0;
    int order = 0;
    Eigen::Index joint = -1;
  } worst;
  for (std::size_t i = 0; i < count; ++i) {
    if (i % 256 == 0 && options.stop.stop_requested()) return Violations{{"motion", "stopped: the call was cancelled"}};
    const double t = grid_time(i, count, plan.duration_s, rate);
    const ProfileState x = evaluate(plan.profile, t, cursor);
    evaluate_point(plan.path, x.s, point, hint, false);
    q_ddot = point.q_s * x.a + point.q_ss * (x.v * x.v);
    const double dt = t - t_prev;
    // The sample's portion and grid interval.
    const std::size_t p = portion_of(plan.path.rests, x.s);
    const std::size_t k = interval_of(plan.grids[p], x.s - plan.path.rests[p]);
    // An excess tightens the grid around it (SampleCheck::tighten). `ratio` (where >= 0): the
    // usage, when it is not value / limit (a torque's, dynamic_torque_usage: its part beyond
    // gravity's, which scales as an acceleration).
    auto note = [&](double value, double limit, int order, Eigen::Index j, double& usage, double ratio = -1.0) {
      if (!(limit < kInf)) return;
      const double r = ratio >= 0.0 ? ratio : value / limit;
      usage = std::max(usage, value / limit);
      if (r > check.worst_usage) {
        check.worst_usage = r;
        worst = {value, limit, t, x.s, order, j};  // described once, after the pass
      }
      if (r > 1.0 + options.sample_tolerance) check.tighten(p, k, r, order);
    };
    // Torques: screened by the grid's terms, exact near a limit.
    if (torques) {
      const GridPoint &g0 = plan.grids[p][k], &g1 = plan.grids[p][k + 1];
      const double within = std::clamp((x.s - plan.path.rests[p] - g0.s) / (g1.s - g0.s), 0.0, 1.0);
      q_dot = point.q_s * x.v;
      Eigen::Index joint = -1;
      double load = 0.0;
      const auto torque = [&](double value, double limit, Eigen::Index j, double ratio) {
        note(value, limit, 4, j, out.torque_usage, ratio);
      };
      if (!time_optimal_detail::check_torques(plan.model, point.q, q_dot, q_ddot, g0, g1, within, x.a, x.v * x.v,
                                              limits, scratch, torque, joint, load))
        return Violations{gravity_beyond(joint, load, limits.joint_torque(joint), t, x.s)};
    }
    for (Eigen::Index j = 0; j < point.q_s.size(); ++j) {
      note(std::abs(point.q_s(j) * x.v), limits.joint_velocity(j), 1, j, out.velocity_usage);
      note(std::abs(q_ddot(j)), limits.joint_acceleration(j), 2, j, out.acceleration_usage);
      if (jerk && i > 0 && dt > 0.0)
        note(std::abs(q_ddot(j) - q_ddot_prev(j)) / dt, limits.joint_jerk(j), 3, j, out.jerk_usage);
    }
    q_ddot_prev = q_ddot;
    t_prev = t;
  }
  if (worst.joint >= 0) {
    static constexpr const char* kKind[] = {"", " velocity ", " acceleration ", " jerk ", " torque "};
    check.worst = "joint " + std::to_string(worst.joint) + kKind[worst.order] + number(worst.value, 6) + " of " +
                  number(worst.limit, 6) + " at t = " + number(worst.t, 6) + " s (sigma = " + number(worst.sigma, 6) +
                  ", " + number(rate, 6) + " Hz)";
  }
  return std::nullopt;
}

}  // namespace

SpeedProfile joined_profile(const std::vector<SpeedProfile>& profiles, const std::vector<double>& rests) {
  SpeedProfile out;
  double t = 0.0;
  for (std::size_t p = 0; p < profiles.size(); ++p) {
    for (ProfilePiece piece : profiles[p].pieces) {
      piece.t0 += t;
      piece.s0 += rests[p];
      out.pieces.push_back(piece);
    }
    t += profiles[p].duration;
  }
  out.duration = t;
  out.length = rests.back();
  return out;
}

Expected<JointPathCheck> check_joint_path_samples(const JointPathPlan& plan, const TimeOptimalLimits& limits,
                                                  const JointPathOptions& options) {
  JointPathCheck out;
  out.check.shrink.resize(plan.grids.size());
  out.check.jerk_shrink.resize(plan.grids.size());
  for (std::size_t p = 0; p < plan.grids.size(); ++p) {
    out.check.shrink[p].assign(plan.grids[p].size(), 1.0);
    out.check.jerk_shrink[p].assign(plan.grids[p].size(), 1.0);
  }
  const double rate = plan.spec.cycle_rate_hz;
  double multiple = options.check_rate_hz > rate ? std::ceil(options.check_rate_hz / rate * (1.0 - 1e-12)) : 1.0;
  const double budget = static_cast<double>(options.max_check_samples) / std::max(1.0, plan.duration_s * rate);
  multiple = std::min(multiple, std::max(1.0, std::floor(budget)));
  // Velocities and accelerations at the finer rate, whose samples include the cycle's (every
  // multiple-th): one pass. A jerk by differences depends on the rate: both.
  const bool jerk = limits.joint_jerk.size() > 0 && (limits.joint_jerk.array() < kInf).any();
  if (multiple > 1.0 && !jerk) {
    if (auto failed = check_pass(plan, rate * multiple, limits, options, out)) return tl::make_unexpected(std::move(*failed));
    out.check.check_rate_hz = rate * multiple;
    return out;
  }
  if (auto failed = check_pass(plan, rate, limits, options, out)) return tl::make_unexpected(std::move(*failed));
  out.check.check_rate_hz = rate;
  if (out.check.broken) return out;
  if (multiple > 1.0) {
    if (auto failed = check_pass(plan, rate * multiple, limits, options, out)) return tl::make_unexpected(std::move(*failed));
    out.check.check_rate_hz = rate * multiple;
  }
  return out;
}

Expected<JointPathPlan> plan_joint_path(const ValidRobot& robot, JointPath path, const MotionSpec& motion,
                                        const JointPathOptions& options) {
  const RobotModel& model = robot;
  GEOTRAJ_CHECK(path.dof == model.dof());
  if (auto v = validate_motion(motion, motion.duration_s > 0.0 ? MotionTiming::kProfile : MotionTiming::kLimits);
      !v.empty())
    return tl::make_unexpected(v);
  JointPathPlan plan{.model = robot, .spec = motion, .path = std::move(path), .profile = {}, .duration_s = 0.0,
                     .sample_count = 0, .binding = {}, .velocity_usage = 0.0, .acceleration_usage = 0.0,
                     .refinements = 0, .check_rate_hz = 0.0, .grid_points = 0, .duration_grid_error = 0.0,
                     .grids = {}, .solutions = {}, .limit_scale = {}, .limits = {}};
  const double rate = motion.cycle_rate_hz;
  auto finish = [&](double duration) -> Expected<JointPathPlan> {
    if (!(duration * rate < kMaxMotionSamples))
      return tl::make_unexpected(Violations{unattainable(
          "motion.durationS", "the joint path lasts " + number(duration, 6) + " s, more samples than a motion may hold")});
    plan.duration_s = duration;
    plan.sample_count = grid_sample_count(duration, rate);
    return std::move(plan);
  };
  if (plan.path.segments.empty()) {
    plan.profile.duration = motion.duration_s / motion.speed_scale;
    return finish(plan.profile.duration);
  }

  // The joints' limits only (speedScale and accelerationScale applied).
  MotionSpec joint_only = motion;
  joint_only.max_speed.reset(), joint_only.max_acceleration.reset(), joint_only.max_jerk.reset();
  joint_only.max_angular_speed.reset(), joint_only.max_angular_acceleration.reset();
  plan.limits = time_optimal_limits(joint_only, &model);
  const TimeOptimalLimits& limits = plan.limits;

  const auto& rests = plan.path.rests;
  const std::size_t P = rests.size() - 1;
  plan.grids.resize(P);
  plan.limit_scale.resize(P);
  plan.solutions.resize(P);
  for (std::size_t p = 0; p < P; ++p) {
    plan.grids[p] = portion_grid(plan.path, rests[p], rests[p + 1], options, torque_limited(model) ? &model : nullptr);
    plan.limit_scale[p].assign(plan.grids[p].size(), 1.0);
    // Between the points of a blend's grid the joints' accelerations pass their values at
    // the ends and the middle by up to a few 1e-4 of the limit: the blends' points start
    // that much inside the limits, and the sample check rarely needs a refinement.
    for (std::size_t i = 0; i < plan.grids[p].size(); ++i) {
      const bool blend = plan.grids[p][i].q_s_mid.size() > 0 || (i > 0 && plan.grids[p][i - 1].q_s_mid.size() > 0);
      if (blend) plan.limit_scale[p][i] = 1.0 - kBlendLimitMargin;
    }
    plan.grid_points += plan.grids[p].size();
  }
  for (int round = 0;; ++round) {
    if (options.stop.stop_requested()) return tl::unexpected(Violations{{"motion", "stopped: the call was cancelled"}});
    std::vector<SpeedProfile> profiles(P);
    for (std::size_t p = 0; p < P; ++p) {
      auto sol = time_optimal_detail::sweep(plan.grids[p], limits, &plan.limit_scale[p]);
      if (!sol) {
        Violations v = sol.error();
        for (auto& fv : v) fv.description += " (joint path, sigma from " + number(rests[p], 6) + ")";
        return tl::make_unexpected(v);
      }
      profiles[p] = sol->profile;
      plan.solutions[p] = std::move(*sol);
    }
    plan.profile = joined_profile(profiles, rests);
    plan.duration_s = plan.profile.duration;
    plan.refinements = round;
    if (!options.verify_samples) break;
    auto check = check_joint_path_samples(plan, limits, options);
    if (!check) return tl::make_unexpected(check.error());
    plan.velocity_usage = check->velocity_usage;
    plan.acceleration_usage = check->acceleration_usage;
    plan.check_rate_hz = check->check.check_rate_hz;
    if (!check->check.broken) break;
    if (round >= options.max_refinements)
      return tl::make_unexpected(Violations{unattainable(
          "motion", "the sampled joint path still exceeds a limit by " +
                        number(100.0 * (check->check.worst_usage - 1.0), 6) + " % after " + std::to_string(round) +
                        " refinements (" + check->check.worst + ")")});
    tighten_limits(check->check, round, options.uniform_refinement_from, plan.limit_scale, nullptr);
  }
  // The duration's grid error: the same limits on every second grid point.
  double half_duration = 0.0;
  for (std::size_t p = 0; p < P; ++p) {
    const std::vector<std::size_t> half = every_second_point(plan.grids[p].size());
    auto sol = half.size() >= 3 ? time_optimal_detail::sweep(plan.grids[p], limits, &plan.limit_scale[p], &half)
                                : Expected<TimeOptimalSolution>();
    half_duration = half.size() >= 3 && sol ? half_duration + sol->duration : kInf;
  }
  plan.duration_grid_error = std::isfinite(half_duration) ? std::abs(half_duration - plan.duration_s) : 0.0;
  double t0 = 0.0;
  for (std::size_t p = 0; p < P; ++p) {
    for (BindingStretch st : plan.solutions[p].binding) {
      st.portion = p;
      st.s_start += rests[p], st.s_end += rests[p];
      st.t_start += t0, st.t_end += t0;
      plan.binding.push_back(st);
    }
    t0 += plan.solutions[p].duration;
  }
  if (motion.duration_s > 0.0) {
    // The given duration: the same motion stretched (or compressed) uniformly in time.
    const double T = motion.duration_s / motion.speed_scale, c = T / plan.duration_s;
    plan.profile = time_scaled(std::move(plan.profile), c);
    plan.profile.duration = T;
    plan.velocity_usage /= c;
    plan.acceleration_usage /= c * c;
    plan.binding.clear();
    return finish(T);
  }
  return finish(plan.duration_s);
}

void joint_path_at(const JointPathPlan& plan, double t, ProfileCursor& cursor, std::size_t& hint, MoveSample& out) {
  const bool at_end = t >= plan.duration_s;
  const ProfileState x = at_end ? ProfileState{plan.path.length, 0.0, 0.0, 0.0} : evaluate(plan.profile, t, cursor);
  JointPathPoint point;  // fixed-capacity vectors: no heap
  evaluate_point(plan.path, x.s, point, hint, false);
  out.q = at_end ? plan.path.last : point.q;
  out.q_dot = point.q_s * x.v;
  out.q_ddot = point.q_s * x.a + point.q_ss * (x.v * x.v);
  joint_tool_state(plan.model, out);
  out.t = t;
  out.u = plan.path.length > 0.0 ? x.s / plan.path.length : (at_end ? 1.0 : 0.0);
  out.s = 0.0;
}

JointVector joint_path_jerk(const JointPathPlan& plan, double t) {
  const ProfileState x = evaluate(plan.profile, t);
  JointPathPoint point;
  std::size_t hint = 0;
  evaluate(plan.path, x.s, point, hint);
  return point.q_sss * (x.v * x.v * x.v) + 3.0 * point.q_ss * (x.v * x.a) + point.q_s * x.j;
}

JointPathSampler::JointPathSampler(const JointPathPlan& plan) : plan_(&plan) {
  GEOTRAJ_CHECK(plan.sample_count > 0);
  reset();
}

void JointPathSampler::reset() {
  k_ = 0;
  cursor_ = {};
  hint_ = 0;
}

bool JointPathSampler::next(MoveSample& out) {
  const JointPathPlan& p = *plan_;
  if (k_ >= p.sample_count) return false;
  at(grid_time(k_, p.sample_count, p.duration_s, p.spec.cycle_rate_hz), out);
  return true;
}

void JointPathSampler::at(double t, MoveSample& out) {
  joint_path_at(*plan_, std::clamp(t, 0.0, plan_->duration_s), cursor_, hint_, out);
  if (k_ > 0 && out.q_WT.coeffs().dot(q_prev_.coeffs()) < 0.0) out.q_WT.coeffs() = -out.q_WT.coeffs();
  q_prev_ = out.q_WT;
  ++k_;
}

}  // namespace geotraj::core
