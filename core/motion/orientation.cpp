#include "core/motion/orientation.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

#include "core/geometry/analysis.hpp"
#include "core/geometry/differential_geometry.hpp"
#include "core/format.hpp"

namespace geotraj::core {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

/// Uniform intervals of a segment's orientation grid before adaptive refinement.
constexpr int kGridStartIntervals = 64;
/// Bisections of one starting interval at most (width 2^-42 of the segment in u).
constexpr int kGridMaxDepth = 36;
/// A turn [rad] still left over an interval of the finest width is a jump, not a rotation.
constexpr double kGridJump = 0.1;


const char* mode_name(OrientationMode mode) {
  switch (mode) {
    case OrientationMode::kFixed: return "ORIENTATION_MODE_FIXED";
    case OrientationMode::kFrameBased: return "ORIENTATION_MODE_FRAME_BASED";
    case OrientationMode::kCustom: return "ORIENTATION_MODE_CUSTOM";
    case OrientationMode::kFrenet: return "ORIENTATION_MODE_FRENET";
    case OrientationMode::kParallelTransport: return "ORIENTATION_MODE_PARALLEL_TRANSPORT";
  }
  return "ORIENTATION_MODE_UNSPECIFIED";
}


/// Ry(pi): the tool's z axis reversed about its y axis; [-B N T] Ry(pi) = [B N -T].
const Quaterniond kFlip(0.0, 0.0, 1.0, 0.0);  // (w, x, y, z)

double angle_between(const Vector3d& a, const Vector3d& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

/// The tool's z axis of R_WT (third column).
Vector3d tool_z(const Quaterniond& q) { return q * Vector3d::UnitZ(); }

/// Local geometry on a segment at local u (jet up to order 3 for tau; order 4 zeroed).
LocalGeometry geometry_at(const Path& path, std::size_t segment, double u) {
  Jet jet;
  jet[4].setZero();
  evaluate(path.segments[segment], u, 3, jet);
  return local_geometry(jet, path.p_uu_noise[segment]);
}

/// The Frenet tool frame [-B N T] (6.21), flipped after an odd number of cusps.
Quaterniond frenet_frame(const LocalGeometry& g, bool flipped) {
  const Quaterniond q = tool_frame(g.T, g.N);
  return flipped ? Quaterniond(q * kFlip) : q;
}

/// An adaptive grid on local u in [0, 1]: 64 uniform intervals, each bisected until the turn
/// measured through its midpoint is at most kOrientationGridTurn. `eval(u)` returns the
/// sample or nothing where it is undefined; `turn(a, b)` the angle between two samples.
/// On failure, `bad_u` is where the samples are undefined or jump.
template <class S>
struct Grid {
  std::vector<double> u;
  std::vector<S> s;
  bool ok = true;
  double bad_u = 0.0;
  bool undefined = false;  ///< the sample is undefined at bad_u (else it jumps there)
};

template <class S, class Eval, class Turn>
void refine(Grid<S>& grid, const Eval& eval, const Turn& turn, double a, const S& sa, double b, const S& sb,
            int depth) {
  if (!grid.ok) return;
  const double m = 0.5 * (a + b);
  const std::optional<S> sm = eval(m);
  if (!sm) {
    grid.ok = false;
    grid.undefined = true;
    grid.bad_u = m;
    return;
  }
  const double t = turn(sa, *sm) + turn(*sm, sb);
  if (t <= kOrientationGridTurn) {
    grid.u.push_back(b);
    grid.s.push_back(sb);
    return;
  }
  if (depth >= kGridMaxDepth) {
    if (t > kGridJump) {
      grid.ok = false;
      grid.bad_u = m;
      return;
    }
    grid.u.push_back(m);
    grid.s.push_back(*sm);
    grid.u.push_back(b);
    grid.s.push_back(sb);
    return;
  }
  refine(grid, eval, turn, a, sa, m, *sm, depth + 1);
  refine(grid, eval, turn, m, *sm, b, sb, depth + 1);
}

template <class S, class Eval, class Turn>
Grid<S> adaptive_grid(const Eval& eval, const Turn& turn) {
  Grid<S> grid;
  std::optional<S> prev = eval(0.0);
  if (!prev) {
    grid.ok = false;
    grid.undefined = true;
    return grid;
  }
  grid.u.push_back(0.0);
  grid.s.push_back(*prev);
  for (int k = 1; k <= kGridStartIntervals && grid.ok; ++k) {
    const double a = static_cast<double>(k - 1) / kGridStartIntervals;
    const double b = static_cast<double>(k) / kGridStartIntervals;
    const std::optional<S> next = eval(b);
    if (!next) {
      grid.ok = false;
      grid.undefined = true;
      grid.bad_u = b;
      return grid;
    }
    refine(grid, eval, turn, a, *prev, b, *next, 0);
    prev = next;
  }
  return grid;
}

/// A point of the curve with its unit tangent, for the double reflection.
struct CurvePoint {
  Vector3d p;
  Vector3d T;
};

/// Parallel transport by the double-reflection method (Wang, Juttler, Zheng, Liu 2008): the
/// reference vector r (the tool's y axis, perpendicular to the tangent) is carried from
/// grid point k to k + 1 by two reflections, which are exact rotations (Eq. 7.22 with the
/// erratum of Eq. 2.35: no explicit Euler step, the frame stays orthonormal).
Vector3d double_reflection(const CurvePoint& a, const CurvePoint& b, const Vector3d& r) {
  Vector3d rL = r, tL = a.T;
  const Vector3d v1 = b.p - a.p;
  const double c1 = v1.squaredNorm();
  if (c1 > 0.0) {
    rL = r - (2.0 / c1) * v1.dot(r) * v1;  // reflection in the bisecting plane of the chord
    tL = a.T - (2.0 / c1) * v1.dot(a.T) * v1;
  }
  const Vector3d v2 = b.T - tL;
  const double c2 = v2.squaredNorm();
  Vector3d out = c2 > 0.0 ? Vector3d(rL - (2.0 / c2) * v2.dot(rL) * v2) : rL;  // onto b.T
  out -= out.dot(b.T) * b.T;  // remove the rounding along the tangent
  return out.normalized();
}

/// R_WT with z = sign T and y = r (r perpendicular to T, unit): [y x z, y, z].
Quaterniond frame_from(const Vector3d& T, const Vector3d& r, bool flipped) {
  const Vector3d z = flipped ? Vector3d(-T) : T;
  Matrix3d R;
  R.col(0) = r.cross(z);
  R.col(1) = r;
  R.col(2) = z;
  return Quaterniond(R).normalized();
}

/// The key frame k's tool frame [-B N T] with the frame's own T and N; where the frame gives
/// no normal, the normal measured on the curve there (`measured`), if the curve bends.
std::optional<Quaterniond> key_frame_tool(const Path& path, std::size_t k, const std::optional<LocalGeometry>& measured) {
  const KeyFrame& f = path.spec.frames[k];
  const Vector3d T = f.T_W.normalized();
  if (f.N_W) return tool_frame(T, *f.N_W);
  if (measured && measured->has_normal) {
    const Vector3d N = measured->N - measured->N.dot(T) * T;
    if (N.norm() > 0.5) return tool_frame(T, N.normalized());
  }
  return std::nullopt;
}

void set_slerp(SegmentOrientation& so, const Quaterniond& target) {
  so.q_end = target.normalized();
  Quaterniond rel = so.q_end * so.q_start.conjugate();  // q_end q_start^-1, in W
  if (rel.w() < 0.0) rel.coeffs() = -rel.coeffs();       // the shorter way round
  const double sin_half = rel.vec().norm();
  so.theta = 2.0 * std::atan2(sin_half, rel.w());
  so.axis_W = sin_half > 0.0 ? Vector3d(rel.vec() / sin_half) : Vector3d::Zero();
}

std::string where(std::size_t segment, double u) {
  return "u = " + number(u, 6) + " of segment " + std::to_string(segment) + " (path u = " +
         number(static_cast<double>(segment) + u, 6) + ")";
}

}  // namespace

Quaterniond tool_frame(const Vector3d& T_W, const Vector3d& N_W) {
  Matrix3d R;
  R.col(0) = -T_W.cross(N_W);  // -B
  R.col(1) = N_W;
  R.col(2) = T_W;  // (6.21)
  return Quaterniond(R).normalized();
}

Expected<OrientationPlan> plan_orientation(const Path& path, const Eigen::Quaterniond& start_W) {
  const auto& frames = path.spec.frames;
  const std::size_t n = frames.size();
  const std::size_t m = path.segment_count();
  GEOTRAJ_CHECK(m > 0 && path.p_uu_noise.size() == m && path.segment_lengths.size() == m);
  Violations violations;

  // Custom orientations: required with kCustom, not allowed with other modes, unit.
  std::vector<std::optional<Quaterniond>> custom(n);
  for (std::size_t k = 0; k < n; ++k) {
    const KeyFrame& f = frames[k];
    const std::string field = frame_field(path, k, "orientation");
    // A path that starts held fixed may give the orientation held (see the header).
    const bool held_start = k == 0 && f.orientation_mode == OrientationMode::kFixed;
    if (f.orientation_mode != OrientationMode::kCustom && !(held_start && f.orientation)) {
      if (f.orientation)
        violations.push_back({field, std::string("is only used with ORIENTATION_MODE_CUSTOM (and ORIENTATION_MODE_FIXED "
                                                 "on the first frame: the orientation held); this frame's mode is ") +
                                         mode_name(f.orientation_mode)});
      continue;
    }
    if (!f.orientation) {
      violations.push_back({field, "is required with ORIENTATION_MODE_CUSTOM (the tool's target orientation R_WT)"});
      continue;
    }
    const double norm = f.orientation->norm();
    if (!f.orientation->coeffs().allFinite()) {
      violations.push_back({field, "must have finite components"});
    } else if (!(std::abs(norm - 1.0) <= 1e-3)) {
      violations.push_back({field, "must be a unit quaternion (|q| within 1e-3 of 1), got |q| = " + number(norm, 6)});
    } else {
      custom[k] = f.orientation->normalized();
    }
  }

  const std::vector<AchievedFrame> achieved = achieved_geometry(path);
  OrientationPlan plan;
  plan.segments.resize(m);
  int cusps = 0;
  bool start_known = true;  // false after an error that leaves the start orientation unknown
  for (std::size_t i = 0; i < m; ++i) {
    SegmentOrientation& so = plan.segments[i];
    const KeyFrame& f = frames[i];
    const std::size_t next = (i + 1) % n;
    const std::string mode_at = mode_field(path, i);
    so.mode = f.orientation_mode;
    so.eased = f.ease_orientation &&
               (so.mode == OrientationMode::kCustom || so.mode == OrientationMode::kFrameBased);
    if (f.cusp) ++cusps;  // the leaving side of frame i runs against its tangent
    so.flipped = cusps % 2 == 1;

    if (i == 0 && so.mode == OrientationMode::kFixed && (path.spec.start || custom[0])) {
      // Held fixed as the frame's `orientation` says, or (a path of pieces) as the robot
      // starts, whatever the curve does where it starts.
      so.q_start = custom[0] ? *custom[0] : start_W.normalized();
    } else if (i == 0) {
      if (so.mode != OrientationMode::kFrenet) {  // Deviation for kFrenet: see the header
        const auto q0 = key_frame_tool(path, 0, achieved[0].leave);
        if (q0) {
          so.q_start = *q0;
        } else if (so.mode != OrientationMode::kParallelTransport) {
          so.q_start = start_W.normalized();  // a straight start: the tool as it is before the motion
        } else {
          start_known = false;
          violations.push_back({frame_field(path, 0, "normal"),
                                "ORIENTATION_MODE_PARALLEL_TRANSPORT starts the tool in frame 0's [-B N T] (Eq. 6.21), "
                                "which needs a normal: the frame gives none and the curve is straight there; give a "
                                "normal, or start with ORIENTATION_MODE_FIXED (the tool keeps its start orientation)"});
        }
      }
    } else {
      so.q_start = plan.segments[i - 1].q_end;
    }

    switch (so.mode) {
      case OrientationMode::kFixed:
        so.q_end = so.q_start;
        break;

      case OrientationMode::kFrameBased: {
        const auto target = key_frame_tool(path, next, achieved[next].approach);
        if (!target) {
          start_known = false;
          violations.push_back({frame_field(path, next, "normal"),
                                "segment " + std::to_string(i) + " (frames[" + std::to_string(i) +
                                    "].orientationMode = ORIENTATION_MODE_FRAME_BASED) turns the tool to this frame's "
                                    "[-B N T] (Eq. 6.21), which needs a normal: the frame gives none and the curve is "
                                    "straight there; give a normal"});
          break;
        }
        set_slerp(so, *target);
        break;
      }

      case OrientationMode::kCustom:
        if (!custom[i]) {
          start_known = false;  // reported above
          break;
        }
        set_slerp(so, *custom[i]);
        break;

      case OrientationMode::kFrenet: {
        const bool flipped = so.flipped;
        auto eval = [&](double u) -> std::optional<Quaterniond> {
          const LocalGeometry g = geometry_at(path, i, u);
          if (!g.regular || !g.has_normal) return std::nullopt;
          return frenet_frame(g, flipped);
        };
        auto turn = [](const Quaterniond& a, const Quaterniond& b) { return a.angularDistance(b); };
        Grid<Quaterniond> grid = adaptive_grid<Quaterniond>(eval, turn);
        if (!grid.ok) {
          start_known = false;
          violations.push_back(
              {mode_at, std::string("ORIENTATION_MODE_FRENET follows the curve's Frenet frame [-B N T], but at ") +
                               where(i, grid.bad_u) +
                               (grid.undefined ? " the curvature vanishes (the curve is straight there), so the normal "
                                                 "is undefined"
                                               : " the curvature (nearly) vanishes and the Frenet frame flips about the "
                                                 "tangent") +
                               "; use ORIENTATION_MODE_PARALLEL_TRANSPORT, which needs no normal"});
          break;
        }
        if (i > 0 && start_known) {
          const double jump = so.q_start.angularDistance(grid.s.front());
          if (jump > kOrientationJoinTolerance) {
            violations.push_back(
                {mode_at, "the tool would turn by " + number(jump, 6) + " rad instantly where segment " + std::to_string(i) +
                                 " starts: the previous segment ends in another orientation than the curve's Frenet "
                                 "frame there (a frame without curvature, an inflection, or another mode before); "
                                 "give the frame a curvature and normal, or use ORIENTATION_MODE_PARALLEL_TRANSPORT"});
          }
        }
        so.q_start = grid.s.front();
        so.q_end = grid.s.back();
        so.grid_u = std::move(grid.u);
        so.grid_q = std::move(grid.s);
        so.grid_T.reserve(so.grid_q.size());
        so.grid_p.reserve(so.grid_q.size());
        for (std::size_t k = 0; k < so.grid_q.size(); ++k) {
          Jet jet;
          evaluate(path.segments[i], so.grid_u[k], 1, jet);
          so.grid_p.push_back(jet[0]);
          so.grid_T.push_back(jet[1].normalized());
        }
        break;
      }

      case OrientationMode::kParallelTransport: {
        auto eval = [&](double u) -> std::optional<CurvePoint> {
          Jet jet;
          evaluate(path.segments[i], u, 1, jet);
          const double speed = jet[1].norm();
          if (!(speed > 0.0)) return std::nullopt;
          return CurvePoint{jet[0], jet[1] / speed};
        };
        auto turn = [](const CurvePoint& a, const CurvePoint& b) { return angle_between(a.T, b.T); };
        Grid<CurvePoint> grid = adaptive_grid<CurvePoint>(eval, turn);
        if (!grid.ok) {
          start_known = false;
          violations.push_back({mode_at, "ORIENTATION_MODE_PARALLEL_TRANSPORT follows the tangent, but at " +
                                                where(i, grid.bad_u) +
                                                " the curve has a singular point (dp/du = 0) where the tangent "
                                                "is undefined or reverses; change the tangent scales of the frames"});
          break;
        }
        const Vector3d z0 = so.flipped ? Vector3d(-grid.s.front().T) : grid.s.front().T;
        const double realign = angle_between(tool_z(so.q_start), z0);
        if (i > 0 && start_known && realign > kOrientationJoinTolerance) {
          violations.push_back(
              {mode_at, "the tool would turn by " + number(realign, 6) + " rad instantly where segment " +
                               std::to_string(i) +
                               " starts: ORIENTATION_MODE_PARALLEL_TRANSPORT keeps the tool's z axis along the "
                               "tangent, but the previous segment ends with the z axis elsewhere; end it in this "
                               "frame (ORIENTATION_MODE_FRAME_BASED) or follow the tangent there as well"});
        }
        // The minimal rotation that puts the start orientation's z onto the tangent.
        const Quaterniond start = (Quaterniond::FromTwoVectors(tool_z(so.q_start), z0) * so.q_start).normalized();
        Vector3d r = start * Vector3d::UnitY();
        so.q_start = frame_from(grid.s.front().T, (r - r.dot(grid.s.front().T) * grid.s.front().T).normalized(),
                                so.flipped);
        r = so.q_start * Vector3d::UnitY();
        so.grid_u = std::move(grid.u);
        so.grid_q.reserve(so.grid_u.size());
        so.grid_q.push_back(so.q_start);
        so.grid_T.reserve(grid.s.size());
        so.grid_p.reserve(grid.s.size());
        for (const auto& pt : grid.s) {
          so.grid_p.push_back(pt.p);
          so.grid_T.push_back(pt.T);
        }
        for (std::size_t k = 1; k < grid.s.size(); ++k) {
          r = double_reflection(grid.s[k - 1], grid.s[k], r);
          Quaterniond q = frame_from(grid.s[k].T, r, so.flipped);
          if (q.dot(so.grid_q.back()) < 0.0) q.coeffs() = -q.coeffs();  // same hemisphere for the SLERP
          so.grid_q.push_back(q);
        }
        so.q_end = so.grid_q.back();
        break;
      }
    }
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return plan;
}

namespace {

// The orientation as planned (the modes of Table 6.3), without the chosen roll.
OrientationSample planned_at(const OrientationPlan& plan, const Path& path, std::size_t segment, double u_local,
                             double s, double s_dot, double s_ddot) {
  GEOTRAJ_CHECK(plan.segments.size() == path.segment_count() && segment < plan.segments.size());
  const SegmentOrientation& so = plan.segments[segment];
  const double u = std::clamp(u_local, 0.0, 1.0);
  OrientationSample out;
  switch (so.mode) {
    case OrientationMode::kFixed:
      out.q_WT = so.q_start;
      return out;

    case OrientationMode::kFrameBased:
    case OrientationMode::kCustom: {
      const double length = path.segment_lengths[segment];
      const double sigma =
          length > 0.0 ? std::clamp((s - path.cumulative_lengths[segment]) / length, 0.0, 1.0) : u;  // [0, 1]
      // SLERP (6.18, with the erratum of 6.2) as a rotation about the fixed axis a (W):
      // q = exp(h theta a / 2) q_start, h = sigma or its quintic ease; exactly q_end at sigma = 1.
      const double h = so.eased ? sigma * sigma * sigma * (10.0 + sigma * (-15.0 + 6.0 * sigma)) : sigma;
      const double h_1 = so.eased ? 30.0 * sigma * sigma * (1.0 - sigma) * (1.0 - sigma) : 1.0;  // dh/dsigma
      const double h_2 = so.eased ? 60.0 * sigma * (1.0 - sigma) * (1.0 - 2.0 * sigma) : 0.0;   // d2h/dsigma2
      out.q_WT = sigma >= 1.0 ? so.q_end
                              : Quaterniond(Eigen::AngleAxisd(h * so.theta, so.axis_W) * so.q_start).normalized();
      const double sigma_dot = length > 0.0 ? s_dot / length : 0.0;     // [1/s]
      const double sigma_ddot = length > 0.0 ? s_ddot / length : 0.0;   // [1/s^2]
      out.omega_W = so.axis_W * (so.theta * h_1 * sigma_dot);             // [rad/s]
      out.alpha_W = so.axis_W * (so.theta * (h_2 * sigma_dot * sigma_dot + h_1 * sigma_ddot));  // [rad/s^2], fixed axis
      return out;
    }

    case OrientationMode::kFrenet: {
      Jet jet;
      evaluate(path.segments[segment], u, 4, jet);  // order 4 for tau_s
      const LocalGeometry g = local_geometry(jet, path.p_uu_noise[segment]);
      if (g.regular && g.has_normal) {
        out.q_WT = frenet_frame(g, so.flipped);                  // (6.21)
        const Vector3d darboux = g.tau * g.T + g.kappa * g.B;    // [1/m]
        out.omega_W = s_dot * darboux;                           // Darboux vector (6.22) times ds/dt
        // d/dt (s_dot D) = s_ddot D + s_dot^2 dD/ds, dD/ds = tau_s T + kappa_s B [1/m^2]
        out.alpha_W = s_ddot * darboux + (s_dot * s_dot) * (g.tau_ds * g.T + g.kappa_ds * g.B);
        return out;
      }
      break;  // rounding ate the normal at a point plan_orientation found regular: the grid
    }

    case OrientationMode::kParallelTransport:
      break;
  }

  // Between grid points (kParallelTransport; kFrenet fallback): carry both neighbouring grid
  // frames to the exact point and tangent at u by one double reflection each, then SLERP
  // between the two: both have z = +-T(u), so the SLERP is a tiny twist about it, and the
  // result is exactly the grid frame at a grid point (continuous).
  GEOTRAJ_CHECK(!so.grid_u.empty() && so.grid_u.size() == so.grid_q.size() && so.grid_T.size() == so.grid_q.size() &&
                so.grid_p.size() == so.grid_q.size());
  const auto it = std::upper_bound(so.grid_u.begin(), so.grid_u.end(), u);
  const std::size_t hi = std::min<std::size_t>(static_cast<std::size_t>(it - so.grid_u.begin()), so.grid_u.size() - 1);
  const std::size_t lo = hi == 0 ? 0 : hi - 1;
  const double width = so.grid_u[hi] - so.grid_u[lo];
  const double f = width > 0.0 ? std::clamp((u - so.grid_u[lo]) / width, 0.0, 1.0) : 0.0;
  Jet jet;
  jet[4].setZero();
  evaluate(path.segments[segment], u, 3, jet);
  const LocalGeometry g = local_geometry(jet, path.p_uu_noise[segment]);  // tau, kappa_s need order 3 only
  Quaterniond q;
  if (g.regular) {
    const CurvePoint here{jet[0], g.T};
    const Vector3d r_lo =
        double_reflection({so.grid_p[lo], so.grid_T[lo]}, here, so.grid_q[lo] * Vector3d::UnitY());
    const Vector3d r_hi =
        double_reflection({so.grid_p[hi], so.grid_T[hi]}, here, so.grid_q[hi] * Vector3d::UnitY());
    Quaterniond from_lo = frame_from(g.T, r_lo, so.flipped);
    const Quaterniond from_hi = frame_from(g.T, r_hi, so.flipped);
    if (from_lo.dot(from_hi) < 0.0) from_lo.coeffs() = -from_lo.coeffs();
    q = from_lo.slerp(f, from_hi);
  } else {
    q = so.grid_q[lo].slerp(f, so.grid_q[hi]);
  }
  out.q_WT = q.normalized();
  if (g.has_normal) {
    out.omega_W = s_dot * g.kappa * g.B;  // rotation-minimising: no twist (7.22)
    // d/dt (s_dot kappa B) = s_ddot kappa B + s_dot^2 (kappa_s B - kappa tau N) (B_s = -tau N)
    out.alpha_W = s_ddot * g.kappa * g.B + (s_dot * s_dot) * (g.kappa_ds * g.B - g.kappa * g.tau * g.N);
  } else if (g.regular) {
    // Straight to rounding: kappa B = p' x p'' / |p'|^3 is 0 here; its arc-length
    // derivative is (p' x p''' - 3 C (p'.p'') / |p'|^2) / |p'|^4 with C = p' x p'' = 0.
    const double v4 = g.speed * g.speed * g.speed * g.speed;
    out.alpha_W = (s_dot * s_dot) * jet[1].cross(jet[3]) / v4;
  }
  return out;
}

}  // namespace

OrientationSample orientation_at(const OrientationPlan& plan, const Path& path, std::size_t segment, double u_local,
                                 double s, double s_dot, double s_ddot) {
  OrientationSample out = planned_at(plan, path, segment, u_local, s, s_dot, s_ddot);
  if (plan.roll == nullptr) return out;
  double phi = 0.0, phi_s = 0.0, phi_ss = 0.0;
  plan.roll->at(s, phi, phi_s, phi_ss);
  Matrix3d R = out.q_WT.toRotationMatrix();
  turn_about_tool_axis(R, out.omega_W, out.alpha_W, phi, phi_s * s_dot, phi_ss * s_dot * s_dot + phi_s * s_ddot);
  out.q_WT = Quaterniond(R).normalized();
  return out;
}

void turn_about_tool_axis(Matrix3d& R, Vector3d& omega, Vector3d& alpha, double phi, double phi_dot,
                          double phi_ddot) {
  const Vector3d z = R.col(2);
  R = R * Eigen::AngleAxisd(phi, Vector3d::UnitZ()).toRotationMatrix();
  alpha += phi_ddot * z + phi_dot * omega.cross(z);
  omega += phi_dot * z;
}

RollProfile::RollProfile(std::vector<double> phi, double length) : phi_(std::move(phi)) {
  GEOTRAJ_CHECK(phi_.size() >= 2 && length > 0.0 && std::isfinite(length));
  for (const double x : phi_) GEOTRAJ_CHECK(std::isfinite(x));
  const std::size_t M = phi_.size() - 1;
  h_ = length / static_cast<double>(M);
  // Natural spline, uniform knots: m_{k-1} + 4 m_k + m_{k+1} = 6 (phi_{k+1} - 2 phi_k + phi_{k-1}) / h^2,
  // m_0 = m_M = 0 (Thomas algorithm).
  m_.assign(M + 1, 0.0);
  if (M >= 2) {
    std::vector<double> c(M, 0.0), d(M, 0.0);
    for (std::size_t k = 1; k < M; ++k) {
      const double rhs = 6.0 * (phi_[k + 1] - 2.0 * phi_[k] + phi_[k - 1]) / (h_ * h_);
      const double denom = 4.0 - (k > 1 ? c[k - 1] : 0.0);
      c[k] = 1.0 / denom;
      d[k] = (rhs - (k > 1 ? d[k - 1] : 0.0)) / denom;
    }
    for (std::size_t k = M - 1; k >= 1; --k) {
      m_[k] = d[k] - c[k] * m_[k + 1];
      if (k == 1) break;
    }
  }
}

void RollProfile::at(double s, double& phi, double& phi_s, double& phi_ss) const {
  const std::size_t M = phi_.size() - 1;
  if (!(s > 0.0)) {
    phi = phi_.front(), phi_s = 0.0, phi_ss = 0.0;
    if (s == 0.0) {
      phi_s = (phi_[1] - phi_[0]) / h_ - h_ * (2.0 * m_[0] + m_[1]) / 6.0;
      phi_ss = m_[0];
    }
    return;
  }
  if (s >= length()) {
    phi = phi_.back(), phi_s = 0.0, phi_ss = 0.0;
    if (s == length()) {
      phi_s = (phi_[M] - phi_[M - 1]) / h_ + h_ * (m_[M - 1] + 2.0 * m_[M]) / 6.0;
      phi_ss = m_[M];
    }
    return;
  }
  const std::size_t k = std::min(static_cast<std::size_t>(s / h_), M - 1);
  const double a = (static_cast<double>(k + 1) * h_ - s) / h_;  // weight of knot k
  const double b = 1.0 - a;
  phi = a * phi_[k] + b * phi_[k + 1] + ((a * a * a - a) * m_[k] + (b * b * b - b) * m_[k + 1]) * h_ * h_ / 6.0;
  phi_s = (phi_[k + 1] - phi_[k]) / h_ - (3.0 * a * a - 1.0) * h_ / 6.0 * m_[k] + (3.0 * b * b - 1.0) * h_ / 6.0 * m_[k + 1];
  phi_ss = a * m_[k] + b * m_[k + 1];
}

}  // namespace geotraj::core
