// A jerk-limited change of one rate. See rate_profile.hpp.
#include "core/live/rate_profile.hpp"

#include <algorithm>
#include <cmath>

#include "core/error.hpp"

namespace geotraj::core {

RateProfile::RateProfile(double v0) {
  start_.v = v0;
  end_ = start_;
}

RateState RateProfile::advance(const RateState& s, double jerk, double dt) {
  RateState out;
  out.x = s.x + dt * (s.v + dt * (s.a / 2.0 + dt * jerk / 6.0));
  out.v = s.v + dt * (s.a + dt * jerk / 2.0);
  out.a = s.a + dt * jerk;
  out.j = jerk;
  return out;
}

RateProfile RateProfile::plan(double v0, double a0, double v1, double a_max, double j_max) {
  GEOTRAJ_CHECK(std::isfinite(v0) && std::isfinite(a0) && std::isfinite(v1));
  GEOTRAJ_CHECK(std::isfinite(a_max) && a_max > 0.0 && std::isfinite(j_max) && j_max > 0.0);
  RateProfile p(v0);
  p.start_.a = a0;
  // Where v comes to rest if a0 is brought to zero at once; the direction the rest must go.
  const double v_stop = v0 + a0 * std::abs(a0) / (2.0 * j_max);
  const double gap = v1 - v_stop;
  std::array<Phase, 3> phases{};
  std::size_t n = 0;
  if (std::abs(gap) <= 1e-15 * std::max(1.0, std::abs(v1))) {
    if (a0 != 0.0) phases[n++] = {std::abs(a0) / j_max, -std::copysign(j_max, a0)};
  } else {
    const double d = gap > 0.0 ? 1.0 : -1.0;
    const double b0 = d * a0, dv = d * (v1 - v0);  // mirrored: v increases by dv > b0|b0|/(2j)
    double ap = a_max;
    const auto dv13 = [&](double peak) {
      return (b0 + peak) * std::abs(peak - b0) / (2.0 * j_max) + peak * peak / (2.0 * j_max);
    };
    double cruise = 0.0;
    if (dv - dv13(ap) >= 0.0) {
      cruise = (dv - dv13(ap)) / ap;
    } else {
      // b0 <= a_max here (with b0 > a_max, dv13(a_max) = b0^2 / (2 j) < dv): the peak solves
      // (ap^2 - b0^2) / (2j) + ap^2 / (2j) = dv, and ap >= max(b0, 0) by the choice of d.
      ap = std::max(std::sqrt(std::max(0.0, j_max * dv + b0 * b0 / 2.0)), std::max(b0, 0.0));
    }
    if (ap != b0) phases[n++] = {std::abs(ap - b0) / j_max, d * std::copysign(j_max, ap - b0)};
    if (cruise > 0.0) phases[n++] = {cruise, 0.0};
    if (ap > 0.0) phases[n++] = {ap / j_max, -d * j_max};
  }
  RateState s = p.start_;
  for (std::size_t i = 0; i < n; ++i) {
    p.phases_[i] = phases[i];
    p.phase_start_[i] = s;
    p.phase_start_[i].j = phases[i].jerk;
    s = advance(s, phases[i].jerk, phases[i].duration);
    p.duration_ += phases[i].duration;
  }
  p.count_ = n;
  // The last phase lands on the target at rest up to rounding: pin it there.
  s.v = n > 0 ? v1 : v0;
  s.a = 0.0;
  s.j = 0.0;
  p.end_ = s;
  return p;
}

RateState RateProfile::at(double t) const {
  double t0 = 0.0;
  for (std::size_t i = 0; i < count_; ++i) {
    if (t < t0 + phases_[i].duration) return advance(phase_start_[i], phases_[i].jerk, std::max(0.0, t - t0));
    t0 += phases_[i].duration;
  }
  RateState s = end_;
  s.x += s.v * std::max(0.0, t - duration_);
  return s;
}

std::pair<double, double> RateProfile::range() const {
  double lo = std::min(start_.v, end_.v), hi = std::max(start_.v, end_.v);
  for (std::size_t i = 0; i < count_; ++i) {
    lo = std::min(lo, phase_start_[i].v);
    hi = std::max(hi, phase_start_[i].v);
    // Within a phase v is quadratic in t; its extremum is where a crosses zero.
    const double j = phases_[i].jerk, a = phase_start_[i].a;
    if (j != 0.0 && a * (a + j * phases_[i].duration) < 0.0) {
      const double v = phase_start_[i].v - a * a / (2.0 * j);
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  }
  return {lo, hi};
}

}  // namespace geotraj::core
