#include "core/motion/motion.hpp"
#include "core/format.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

namespace geotraj::core {

namespace {


// ---------------------------------------------------------------------------------------
// Arc length over short intervals: 6-point Gauss-Legendre (exact for degree 11), panels of
// at most kPanel in u, split at trapezoid breakpoints (where |p'| loses smoothness).

constexpr double kPanel = 1.0 / 64;
constexpr std::array<double, 3> kGlX = {0.2386191860831969086305017, 0.6612093864662645136613996,
                                        0.9324695142031520278123016};
constexpr std::array<double, 3> kGlW = {0.4679139345726910473898703, 0.3607615730481386075698335,
                                        0.1713244923791703450402961};

// |dp/du| [m] of a segment at local u.
inline double speed_u(const Segment& seg, const BezierSegment* bez, double u) {
  if (bez) return bernstein_sum(bez->h[1].data(), bez->degree - 1, u).norm();
  Jet jet;
  evaluate(seg, u, 1, jet);
  return jet[1].norm();
}

// Integral of |dp/du| over [a, b] inside one smooth piece, by panels of GL6.
double gl_smooth(const Segment& seg, const BezierSegment* bez, double a, double b) {
  const int panels = std::max(1, static_cast<int>(std::ceil((b - a) / kPanel)));
  const double w = (b - a) / panels;
  double sum = 0.0;
  for (int p = 0; p < panels; ++p) {
    const double c = a + (p + 0.5) * w, h = 0.5 * w;
    double acc = 0.0;
    for (int i = 0; i < 3; ++i) acc += kGlW[i] * (speed_u(seg, bez, c - h * kGlX[i]) + speed_u(seg, bez, c + h * kGlX[i]));
    sum += acc * h;
  }
  return sum;
}

// s(b) - s(a) on one segment, local parameters in [0, 1] (either order) [m].
double segment_arc(const Segment& seg, double a, double b) {
  if (a == b) return 0.0;
  if (b < a) return -segment_arc(seg, b, a);
  const auto* bez = std::get_if<BezierSegment>(&seg);
  if (bez) return gl_smooth(seg, bez, a, b);
  if (const auto* nat = std::get_if<NaturalSegment>(&seg)) return natural_arc(*nat, a, b);  // exact
  const auto& trap = std::get<TrapezoidSegment>(seg);
  std::array<double, 3 * (2 * kMaxTrapezoidOrder + 2) + 2> cuts;
  std::size_t count = 0;
  cuts[count++] = a;
  for (const auto& axis : trap.axes)
    for (int k = 0; k <= 2 * axis.n + 1; ++k)
      if (axis.u[k] > a && axis.u[k] < b) cuts[count++] = axis.u[k];
  cuts[count++] = b;
  std::sort(cuts.begin(), cuts.begin() + count);
  double s = 0.0;
  for (std::size_t i = 0; i + 1 < count; ++i)
    if (cuts[i + 1] > cuts[i]) s += gl_smooth(seg, nullptr, cuts[i], cuts[i + 1]);
  return s;
}

// Curvature |p' x p''| / |p'|^3 (5.4) [1/m] at local u; 0 where the curve is straight to
// rounding (the part of p'' across p' below the segment's noise level).
double curvature_at(const Segment& seg, double noise, double u) {
  Jet jet;
  evaluate(seg, u, 2, jet);
  const double sp = jet[1].norm();
  if (!(sp > 0.0)) return 0.0;
  const double cross = jet[1].cross(jet[2]).norm();
  if (cross / sp <= noise) return 0.0;
  return cross / (sp * sp * sp);
}

// Largest curvature on a segment [1/m]: 200 samples, then golden-section refinement of the
// largest around its neighbours.
double segment_kappa_max(const Segment& seg, double noise) {
  constexpr int kSamples = 200;
  double best = -1.0;
  int best_i = 0;
  for (int i = 0; i <= kSamples; ++i) {
    const double k = curvature_at(seg, noise, static_cast<double>(i) / kSamples);
    if (k > best) best = k, best_i = i;
  }
  double lo = std::max(0, best_i - 1) / static_cast<double>(kSamples);
  double hi = std::min(kSamples, best_i + 1) / static_cast<double>(kSamples);
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = curvature_at(seg, noise, x1), f2 = curvature_at(seg, noise, x2);
  for (int it = 0; it < 60 && hi - lo > 1e-13; ++it) {
    if (f1 > f2) {
      hi = x2, x2 = x1, f2 = f1;
      x1 = hi - g * (hi - lo);
      f1 = curvature_at(seg, noise, x1);
    } else {
      lo = x1, x1 = x2, f1 = f2;
      x2 = lo + g * (hi - lo);
      f2 = curvature_at(seg, noise, x2);
    }
    best = std::max({best, f1, f2});
  }
  return best;
}

bool finite_positive(double x) { return std::isfinite(x) && x > 0.0; }

}  // namespace

// ---------------------------------------------------------------------------------------

Violations validate_motion(const MotionSpec& spec, MotionTiming timing) {
  const bool by_profile = timing == MotionTiming::kProfile;
  Violations v;
  if (!std::isfinite(spec.duration_s) || spec.duration_s < 0.0)
    v.push_back({"motion.durationS", "must be a finite time >= 0 s (0: as fast as the limits allow), got " +
                                         number(spec.duration_s)});
  if (spec.profile != ProfileShape::kTrapezoidal && spec.profile != ProfileShape::kSCurve)
    v.push_back({"motion.profile", "unknown profile shape " + std::to_string(static_cast<int>(spec.profile))});
  if (!std::isfinite(spec.ramp_fraction) || !(spec.ramp_fraction > 0.0) || spec.ramp_fraction > 0.5)
    v.push_back({"motion.rampFraction",
                 "must be in (0, 0.5] (ramp time over portion time), got " + number(spec.ramp_fraction)});
  if (spec.ramp_time_s) {
    if (!finite_positive(*spec.ramp_time_s)) {
      v.push_back({"motion.rampTimeS", "must be a finite time > 0 s, got " + number(*spec.ramp_time_s)});
    } else if (spec.ramp_fraction_given) {
      v.push_back({"motion.rampTimeS", "give the ramps as rampTimeS or as rampFraction, not both"});
    } else if (by_profile && !(spec.duration_s > 0.0)) {
      v.push_back({"motion.rampTimeS", "is used with a duration only (durationS > 0); a fastest motion (durationS 0) "
                                       "takes its ramps from the limits"});
    }
  }
  if (!finite_positive(spec.cycle_rate_hz) || spec.cycle_rate_hz > kMaxCycleRateHz)
    v.push_back({"motion.cycleRateHz", "must be in (0, " + number(kMaxCycleRateHz) + "] Hz, got " +
                                           number(spec.cycle_rate_hz)});
  const auto tp = static_cast<int>(spec.time_parameterization);
  if (tp < 0 || tp > static_cast<int>(TimeParameterization::kTaylorSecondOrder))
    v.push_back({"motion.timeParameterization", "unknown time parameterization " + std::to_string(tp)});
  if (!finite_positive(spec.speed_scale) || spec.speed_scale > 1.0)
    v.push_back({"motion.speedScale", "must be in (0, 1], got " + number(spec.speed_scale)});
  if (!finite_positive(spec.acceleration_scale) || spec.acceleration_scale > 1.0)
    v.push_back({"motion.accelerationScale", "must be in (0, 1], got " + number(spec.acceleration_scale)});
  const auto check_limit = [&](const char* field, const std::optional<double>& x, const char* unit) {
    if (x && !finite_positive(*x))
      v.push_back({field, std::string("must be finite and > 0 ") + unit + " when given, got " + number(*x)});
  };
  check_limit("motion.maxSpeed", spec.max_speed, "m/s");
  check_limit("motion.maxAcceleration", spec.max_acceleration, "m/s^2");
  check_limit("motion.maxJerk", spec.max_jerk, "m/s^3");
  check_limit("motion.maxAngularSpeed", spec.max_angular_speed, "rad/s");
  check_limit("motion.maxAngularAcceleration", spec.max_angular_acceleration, "rad/s^2");
  if (by_profile && spec.duration_s == 0.0) {
    if (!spec.max_speed || !spec.max_acceleration)
      v.push_back({"motion.durationS",
                   "is 0 (as fast as the limits allow): needs maxSpeed and maxAcceleration"});
    if (spec.profile == ProfileShape::kSCurve && !spec.max_jerk)
      v.push_back({"motion.maxJerk", "is needed for a minimum-time S-curve (durationS 0)"});
  }
  return v;
}

Expected<MotionPlan> plan_motion(const Path& path, const MotionSpec& spec) {
  if (auto v = validate_motion(spec); !v.empty()) return tl::make_unexpected(v);
  GEOTRAJ_CHECK(!path.segments.empty() && path.cumulative_lengths.size() == path.segments.size() + 1);
  const double total = path.length();
  if (!(total > 0.0)) return tl::make_unexpected(Violations{{"motion.durationS", "the path has zero length"}});

  MotionPlan plan;
  plan.spec = spec;
  // Rests: u = 0, every cusp or stop frame strictly inside, u = M (frame k at u = k).
  const std::size_t m = path.segment_count();
  std::vector<std::size_t> rests{0};
  for (std::size_t k = 1; k < m; ++k)
    if (path.spec.frames[k].cusp || path.spec.frames[k].stop) rests.push_back(k);
  rests.push_back(m);

  const double scale = spec.speed_scale;
  const double duration = spec.duration_s / scale;
  // A ramp time: one peak speed v for every portion, v (T - n t_b) = L (n portions).
  std::optional<double> ramp_time, shared_speed;
  if (spec.ramp_time_s && duration > 0.0) {
    ramp_time = *spec.ramp_time_s / scale;
    std::size_t moving = 0;
    for (std::size_t i = 0; i + 1 < rests.size(); ++i)
      if (path.cumulative_lengths[rests[i + 1]] > path.cumulative_lengths[rests[i]]) ++moving;
    const double cruise = duration - static_cast<double>(moving) * *ramp_time;
    if (!(cruise > 0.0)) {
      return tl::make_unexpected(Violations{
          {"motion.rampTimeS", "the " + std::to_string(moving) + " portions between rests need " + number(*ramp_time) +
                                   " s of ramps each; the move time " + number(duration) +
                                   " s leaves none for travel: shorten the ramps or lengthen the move"}});
    }
    shared_speed = total / cruise;
  }
  double t = 0.0;
  for (std::size_t i = 0; i + 1 < rests.size(); ++i) {
    MotionPortion por;
    por.u_start = static_cast<double>(rests[i]);
    por.u_end = static_cast<double>(rests[i + 1]);
    por.s_start = path.cumulative_lengths[rests[i]];
    por.length = path.cumulative_lengths[rests[i + 1]] - por.s_start;
    por.t_start = t;
    Expected<SpeedProfile> profile = SpeedProfile{};
    if (por.length > 0.0) {
      if (duration > 0.0) {
        // Equal peak speed: T_i proportional to L_i, so v_max = L_i / (T_i (1 - f)) is the same.
        double t_i = duration * (por.length / total);
        double fraction = spec.ramp_fraction;
        if (shared_speed) {  // v = L_i / (T_i - t_b) for every portion
          t_i = por.length / *shared_speed + *ramp_time;
          fraction = *ramp_time / t_i;
          if (fraction > 0.5) {
            return tl::make_unexpected(Violations{
                {"motion.rampTimeS", "the portion from u = " + number(por.u_start) + " to " + number(por.u_end) + " (" +
                                         number(por.length) + " m) is too short for two ramps of " + number(*ramp_time) +
                                         " s at the shared peak speed " + number(*shared_speed) + " m/s"}});
          }
        }
        profile = spec.profile == ProfileShape::kTrapezoidal ? trapezoid_profile(por.length, t_i, fraction)
                                                             : scurve_profile(por.length, t_i, fraction);
      } else {
        // Minimum time; the speed scale is a time scaling: v s, a s^2, j s^3.
        const double a_lim = *spec.max_acceleration * scale * scale;
        for (std::size_t sgm = rests[i]; sgm < rests[i + 1]; ++sgm)
          por.kappa_max = std::max(por.kappa_max, segment_kappa_max(path.segments[sgm], path.p_uu_noise[sgm]));
        double v_lim = *spec.max_speed * scale;
        if (por.kappa_max > 0.0) v_lim = std::min(v_lim, std::sqrt(a_lim / por.kappa_max));  // kappa v^2 <= a_max
        profile = spec.profile == ProfileShape::kTrapezoidal
                      ? min_time_trapezoid(por.length, v_lim, a_lim)
                      : min_time_double_s(por.length, v_lim, a_lim, *spec.max_jerk * scale * scale * scale);
      }
    }
    if (!profile) return tl::make_unexpected(prefixed(profile.error(), "motion."));
    por.profile = std::move(*profile);
    t += por.profile.duration;
    plan.peak_speed = std::max(plan.peak_speed, peak_speed(por.profile));
    plan.peak_acceleration = std::max(plan.peak_acceleration, peak_acceleration(por.profile));
    plan.portions.push_back(std::move(por));
  }
  // With a duration, the portions' times add up to it up to rounding; make it exact.
  plan.duration_s = duration > 0.0 ? duration : t;

  const double grid = plan.duration_s * spec.cycle_rate_hz;
  if (!(grid < kMaxMotionSamples)) {
    const std::string what = duration > 0.0 ? "durationS x cycleRateHz = " + number(grid) + " samples"
                                            : "the minimum-time motion lasts " + number(plan.duration_s) +
                                                  " s under these limits, " + number(grid) + " samples,";
    // The request's own durationS is a field to change; a minimum-time motion's length is what
    // the limits make of the path.
    return tl::make_unexpected(Violations{{"motion.durationS",
                                           what + " more than " + number(kMaxMotionSamples) +
                                               " per stream: shorten the motion, lower cycleRateHz or raise the limits",
                                           duration > 0.0 ? ViolationKind::kInvalid : ViolationKind::kUnattainable}});
  }
  // A move time too short for the path makes speeds overflow: refuse it, never stream inf.
  if (!std::isfinite(plan.peak_speed) || !std::isfinite(plan.peak_acceleration)) {
    return tl::make_unexpected(Violations{{"motion.durationS", "is too short for a path of " + number(path.length()) +
                                                                   " m: the speeds overflow double precision"}});
  }
  plan.sample_count = grid_sample_count(plan.duration_s, spec.cycle_rate_hz);
  return plan;
}

std::size_t grid_sample_count(double duration_s, double rate_hz) {
  const double grid = duration_s * rate_hz;
  GEOTRAJ_CHECK(grid < kMaxMotionSamples);
  const double n = std::floor(grid + 1e-9);
  return static_cast<std::size_t>(n) + (grid - n <= 1e-9 ? 1 : 2);
}

double grid_time(std::size_t k, std::size_t count, double duration_s, double rate_hz) {
  if (k + 1 >= count) return duration_s;
  return static_cast<double>(k) / rate_hz;
}

// ---------------------------------------------------------------------------------------

MotionSampler::MotionSampler(const Path& path, const MotionPlan& plan) : path_(&path), plan_(&plan) {
  GEOTRAJ_CHECK(!plan.portions.empty());
  period_ = 1.0 / plan.spec.cycle_rate_hz;
  reset();
}

void MotionSampler::reset() {
  k_ = 0;
  enter_portion(0);
}

double MotionSampler::time_of(std::size_t k) const {
  return grid_time(k, plan_->sample_count, plan_->duration_s, plan_->spec.cycle_rate_hz);
}

MotionSampler::Point MotionSampler::point_in_portion(double u) const {
  const auto& por = plan_->portions[portion_];
  const auto first = static_cast<std::size_t>(por.u_start), last = static_cast<std::size_t>(por.u_end) - 1;
  const double fl = std::floor(u);
  const std::size_t seg = fl <= static_cast<double>(first) ? first : std::min(last, static_cast<std::size_t>(fl));
  return {seg, std::clamp(u - static_cast<double>(seg), 0.0, 1.0)};
}

double MotionSampler::arc_length_to(const Point& q) const {
  const Segment& seg = path_->segments[q.segment];
  if (q.segment == anchor_.segment) return anchor_s_ + segment_arc(seg, anchor_.u_local, q.u_local);
  // Re-anchor at the segment's start or end: the path's adaptive (1e-12) segment lengths.
  if (q.segment > anchor_.segment) return path_->cumulative_lengths[q.segment] + segment_arc(seg, 0.0, q.u_local);
  return path_->cumulative_lengths[q.segment + 1] - segment_arc(seg, q.u_local, 1.0);
}

void MotionSampler::enter_portion(std::size_t i) {
  portion_ = i;
  cursor_ = {};
  const auto& por = plan_->portions[i];
  u_ = por.u_start;
  t_prev_ = por.t_start;
  anchor_ = point_in_portion(u_);
  anchor_s_ = por.s_start;
  evaluate(path_->segments[anchor_.segment], anchor_.u_local, 2, jet_);
}

double MotionSampler::solve_arc_length(double s_target, double u_guess) {
  const auto& por = plan_->portions[portion_];
  const double tol = std::max(1e-12, 8 * std::numeric_limits<double>::epsilon() * path_->length());
  double lo = static_cast<double>(anchor_.segment) + anchor_.u_local, hi = por.u_end;
  double u = std::clamp(u_guess, lo, hi);
  // The previous iterate, for the short Hermite step below.
  Point q_prev{};
  double s_prev = 0.0, sp_prev = 0.0, dsp_prev = 0.0;
  bool have_prev = false;
  for (int iter = 0;; ++iter) {
    const Point q = point_in_portion(u);
    const Segment& seg = path_->segments[q.segment];
    evaluate(seg, q.u_local, 2, jet_);
    const double sp = jet_[1].norm();                          // ds/du [m]
    const double dsp = sp > 0.0 ? jet_[1].dot(jet_[2]) / sp : 0.0;  // d2s/du2 [m]
    double s;
    const double h = q.u_local - q_prev.u_local;
    if (have_prev && q.segment == q_prev.segment && std::abs(h) <= 1e-3 &&
        std::holds_alternative<BezierSegment>(seg)) {
      // Newton's correction is short: the two-point Hermite rule on ds/du with its
      // derivative at both ends, error h^5 |s^(5)| / 720, below 1e-15 m here, and free
      // (both jets are at hand).
      s = s_prev + h / 2 * (sp_prev + sp) + h * h / 12 * (dsp_prev - dsp);
    } else {
      s = arc_length_to(q);
    }
    const double r = s - s_target;  // [m]
    if (std::abs(r) <= tol || iter >= 60 || hi - lo <= 4 * std::numeric_limits<double>::epsilon() * (1 + hi)) {
      anchor_ = q;
      anchor_s_ = s;
      return u;
    }
    (r > 0.0 ? hi : lo) = u;
    q_prev = q, s_prev = s, sp_prev = sp, dsp_prev = dsp, have_prev = true;
    // u(s*) = u(s - r) ~ u - r u_s + r^2 u_ss / 2, u_s = 1/|p'|, u_ss = -(p'.p'')/|p'|^4.
    double next = sp > 0.0 ? u - r / sp - 0.5 * r * r * dsp / (sp * sp * sp) : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);  // safeguard: bisect
    u = next;
  }
}

bool MotionSampler::next(MotionSample& out) {
  if (k_ >= plan_->sample_count) return false;
  sample(time_of(k_), k_ + 1 >= plan_->sample_count, out);
  ++k_;
  return true;
}

void MotionSampler::at(double t, MotionSample& out) {
  const bool last = !(t < plan_->duration_s);
  sample(last ? plan_->duration_s : std::max(t, t_prev_), last, out);
}

void MotionSampler::sample(double t, bool last, MotionSample& out) {
  const auto& portions = plan_->portions;
  // A sample at a rest between portions belongs to the later portion (its start).
  while (portion_ + 1 < portions.size() && (last || t >= portions[portion_ + 1].t_start)) enter_portion(portion_ + 1);
  const MotionPortion& por = portions[portion_];
  const double tau = t - por.t_start;
  const double T = por.profile.duration;
  // The last sample is the final rest exactly (the portions' times add up to the duration
  // only to rounding).
  const bool at_end = last || tau >= T, at_start = !at_end && !(tau > 0.0);
  const auto mode = plan_->spec.time_parameterization;

  double u_t = 0.0, u_tt = 0.0;  // du/dt [1/s], d2u/dt2 [1/s^2]
  bool have_jet = false;         // jet_ and anchor_ already at u_
  const ProfileState st_prev = (mode == TimeParameterization::kTaylorFirstOrder ||
                                mode == TimeParameterization::kTaylorSecondOrder)
                                   ? evaluate(por.profile, t_prev_ - por.t_start, cursor_)
                                   : ProfileState{};
  const ProfileState st = at_end ? ProfileState{por.length, 0.0, 0.0, 0.0} : evaluate(por.profile, tau, cursor_);
  double s_out = 0.0;

  if (at_end) {
    u_ = por.u_end;
  } else if (at_start) {
    u_ = por.u_start;
  } else {
    switch (mode) {
      case TimeParameterization::kArcLength: {
        const double ds = por.s_start + st.s - anchor_s_;  // from the previous sample [m]
        const double sp = jet_[1].norm();
        const double guess = sp > 0.0 ? u_ + ds / sp - 0.5 * ds * ds * jet_[1].dot(jet_[2]) / (sp * sp * sp * sp) : u_;
        u_ = solve_arc_length(por.s_start + st.s, guess);
        s_out = anchor_s_;
        have_jet = true;
        break;
      }
      case TimeParameterization::kLinear: {
        const double du = por.u_end - por.u_start;
        u_ = por.u_start + (tau / T) * du;  // (6.3)
        u_t = du / T;
        break;
      }
      case TimeParameterization::kSmooth: {
        const double x = tau / T, du = por.u_end - por.u_start;
        const double q = x * x * x * (10 + x * (-15 + 6 * x));    // (6.4)
        const double q_x = 30 * x * x * (1 + x * (-2 + x));        // dq/dx
        const double q_xx = 60 * x * (1 + x * (-3 + 2 * x));       // d2q/dx2
        u_ = por.u_start + q * du;                                  // (6.5)
        u_t = q_x * du / T;
        u_tt = q_xx * du / (T * T);
        break;
      }
      case TimeParameterization::kTaylorFirstOrder:
      case TimeParameterization::kTaylorSecondOrder: {
        // Step from the previous sample (u_, t_prev_) with the curve there (jet_).
        const double dt = t - t_prev_;
        const double sp = jet_[1].norm();
        double du = 0.0;
        if (sp > 0.0) {
          du = st_prev.v * dt / sp;  // (6.9)
          if (mode == TimeParameterization::kTaylorSecondOrder) {
            const double utt = st_prev.a / sp - st_prev.v * st_prev.v * jet_[1].dot(jet_[2]) / (sp * sp * sp * sp);  // (6.14)
            du += 0.5 * dt * dt * utt;  // (6.15)
          }
        }
        u_ = std::clamp(u_ + du, por.u_start, por.u_end);
        break;
      }
    }
  }

  if (!have_jet) {
    const Point q = point_in_portion(u_);
    evaluate(path_->segments[q.segment], q.u_local, 2, jet_);
    if (at_end) {
      s_out = por.s_start + por.length;
    } else if (at_start) {
      s_out = por.s_start;
    } else {
      s_out = arc_length_to(q);
    }
    anchor_ = q;
    anchor_s_ = s_out;
  }
  const double sp = jet_[1].norm();
  if (mode == TimeParameterization::kLinear || mode == TimeParameterization::kSmooth) {
    // The direct maps at a rest: 6.3 keeps its constant du/dt (a finite speed at rests, as
    // the thesis's Figure 6.9 shows); 6.4 has q' = q'' = 0 at x = 0 and 1.
    if ((at_start || at_end) && mode == TimeParameterization::kLinear && T > 0.0) u_t = (por.u_end - por.u_start) / T;
  } else if (sp > 0.0) {
    u_t = st.v / sp;                                                                // (6.8)
    u_tt = st.a / sp - st.v * st.v * jet_[1].dot(jet_[2]) / (sp * sp * sp * sp);  // (6.14)
  }

  out.t = t;
  out.u = u_;
  out.s = s_out;
  out.segment = anchor_.segment;
  out.portion = portion_;
  out.p_W = jet_[0];
  out.v_W = jet_[1] * u_t;                         // (2.29) dp/dt = p' du/dt
  out.a_W = jet_[2] * (u_t * u_t) + jet_[1] * u_tt;  // (2.31) d2p/dt2
  out.speed = out.v_W.norm();
  // d2s/dt2 = d/dt(|p'| u_t) = |p'| u_tt + (p' . p'' / |p'|) u_t^2 (2.36 differentiated).
  out.s_ddot = sp > 0.0 ? sp * u_tt + jet_[1].dot(jet_[2]) / sp * (u_t * u_t) : 0.0;
  t_prev_ = t;
}

}  // namespace geotraj::core
