#include "core/geometry/analysis.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/geometry/arc_length.hpp"

namespace geotraj::core {

using Eigen::Vector3d;

namespace {

constexpr double kPi = 3.14159265358979323846;

double angle_between(const Vector3d& a, const Vector3d& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

struct Worst {
  ClosedLoopError result;
  void update(double err, const std::string& field) {
    if (!(err <= result.max_error)) {  // NaN counts as worst
      result.max_error = std::isnan(err) ? std::numeric_limits<double>::infinity() : err;
      result.worst_field = field;
    }
  }
};

double relative(double achieved, double asked) { return std::abs(achieved - asked) / std::max(1.0, std::abs(asked)); }

void compare_side(Worst& w, const std::string& at, const KeyFrame& asked, const SideConstraints& side,
                  const Vector3d& p_asked, const Vector3d& p_achieved, const LocalGeometry& g,
                  DerivativeConvention convention, UnspecifiedConstraints reading) {
  w.update((p_achieved - p_asked).norm() / std::max(1.0, p_asked.norm()), at + ".position");
  // An undefined direction on the curve counts as the largest angle error, pi.
  if (!g.regular) {
    w.update(kPi, at + ".tangent");
    return;
  }
  w.update(angle_between(g.T, side.T), at + ".tangent");
  // The side's own scale (side_scale: the leaving side of a cusp may have its own).
  w.update(relative(g.speed, side.d[0].norm()), at + ".tangentScale");
  if (!asked.kappa) {
    // A normal without a curvature is a constraint of the smoothest reading: the curve bends
    // in the plane of T and N, towards N or away from it, or not at all; the angle of the
    // achieved osculating plane to that plane is the error. (The thesis's reading makes the
    // curvature 0 there; a lowest-degree segment uses the normal for the tool only.)
    if (reading == UnspecifiedConstraints::kSmoothest && asked.N_W && g.has_normal) {
      w.update(std::min(angle_between(g.N, side.N), angle_between(g.N, -side.N)), at + ".normal");
    }
    return;
  }
  w.update(relative(g.kappa, *asked.kappa), at + ".curvature");
  if (!(*asked.kappa > 0.0)) return;  // torsion and derivatives are undefined (footnote 5)
  if (!g.has_normal) {
    w.update(kPi, at + ".normal");
    return;
  }
  w.update(angle_between(g.N, side.N), at + ".normal");
  const bool per_s = convention == DerivativeConvention::kPerArcLength;
  if (asked.tau) w.update(relative(g.tau, *asked.tau), at + ".torsion");
  if (asked.kappa_d) w.update(relative(per_s ? g.kappa_ds : g.kappa_du, *asked.kappa_d), at + ".curvatureDerivative");
  if (asked.tau_d) w.update(relative(per_s ? g.tau_ds : g.tau_du, *asked.tau_d), at + ".torsionDerivative");
}

}  // namespace

std::vector<AchievedFrame> achieved_geometry(const Path& path) {
  const std::size_t n = path.frames.size();
  const std::size_t m = path.segments.size();
  std::vector<AchievedFrame> out(n);
  for (std::size_t k = 0; k < n; ++k) {
    auto& a = out[k];
    a.p_W = path.frames[k].p_W;
    if (k > 0 || path.spec.closed) {
      const std::size_t arriving = (k + m - 1) % m;
      Jet jet;
      evaluate(path.segments[arriving], 1.0, kMaxJetOrder, jet);
      a.p_W = jet[0];
      // The trapezoid is exact at its ends (evaluated from the nearer end) and a natural
      // segment everywhere: no noise there.
      const bool exact = !std::holds_alternative<BezierSegment>(path.segments[arriving]);
      a.approach = local_geometry(jet, exact ? 0.0 : path.p_uu_noise[arriving]);
    }
    if (k < m) {
      Jet jet;
      evaluate(path.segments[k], 0.0, kMaxJetOrder, jet);
      a.p_W = jet[0];
      const bool exact = !std::holds_alternative<BezierSegment>(path.segments[k]);
      a.leave = local_geometry(jet, exact ? 0.0 : path.p_uu_noise[k]);
    }
  }
  return out;
}

ClosedLoopError closed_loop_error(const Path& path, const std::vector<AchievedFrame>& achieved) {
  GEOTRAJ_CHECK(achieved.size() == path.frames.size());
  Worst w;
  const std::size_t m = path.segments.size();
  for (std::size_t k = 0; k < achieved.size(); ++k) {
    const std::string at = frame_name(path, k);
    const KeyFrame& asked = path.spec.frames[k];
    const Vector3d& p = path.frames[k].p_W;
    if (achieved[k].approach) {
      Jet jet;
      evaluate(path.segments[(k + m - 1) % m], 1.0, 0, jet);
      compare_side(w, at + ".approach", asked, path.frames[k].approach, p, jet[0], *achieved[k].approach,
                   path.spec.convention, path.spec.unspecified);
    }
    if (achieved[k].leave) {
      Jet jet;
      evaluate(path.segments[k], 0.0, 0, jet);
      compare_side(w, at + ".leave", asked, path.frames[k].leave, p, jet[0], *achieved[k].leave, path.spec.convention,
                   path.spec.unspecified);
    }
  }
  return w.result;
}

std::vector<ProfilePoint> analyze(const Path& path, std::size_t count) {
  return *analyze(path, count, [] { return false; });
}

std::optional<std::vector<ProfilePoint>> analyze(const Path& path, std::size_t count,
                                                 const std::function<bool()>& stopped) {
  GEOTRAJ_CHECK(count >= 2);
  // Reserved, filled as it goes: a profile of 10^6 points is some 300 MB, whose initialisation
  // up front would take longer than the check interval allows a caller to wait.
  std::vector<ProfilePoint> out;
  out.reserve(count);
  const double m = path.u_max();
  std::size_t segment = 0;
  double prev_local = 0.0, running = 0.0;
  for (std::size_t i = 0; i < count; ++i) {
    if (i % kAnalysisCheckInterval == 0 && stopped()) return std::nullopt;
    ProfilePoint& pt = out.emplace_back();
    pt.u = i + 1 == count ? m : m * static_cast<double>(i) / static_cast<double>(count - 1);
    const auto [seg, ul] = locate(path, pt.u);
    if (seg != segment) {  // re-anchor on the segment's start for every new segment
      segment = seg;
      prev_local = 0.0;
      running = 0.0;
    }
    running += segment_arc_length(path.segments[seg], prev_local, ul);
    prev_local = ul;
    pt.segment = seg;
    pt.s = path.cumulative_lengths[seg] + running;
    Jet jet;
    evaluate(path.segments[seg], ul, kMaxJetOrder, jet);
    pt.p_W = jet[0];
    pt.geometry = local_geometry(jet, path.p_uu_noise[seg]);
  }
  out.back().s = path.length();
  return out;
}

}  // namespace geotraj::core
