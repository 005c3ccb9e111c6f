#include "core/geometry/validate.hpp"
#include "core/format.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>
#include <string>

namespace geotraj::core {
namespace {

// Messages give 6 significant digits (core/format.hpp); vectors as (x, y, z).
std::string fmt(double v) { return number(v, 6); }
std::string fmt(const Eigen::Vector3d& v) { return "(" + fmt(v.x()) + ", " + fmt(v.y()) + ", " + fmt(v.z()) + ")"; }

class Collector {
 public:
  explicit Collector(Violations& out) : out_(out) {}
  void add(std::string field, std::string what) { out_.push_back({std::move(field), std::move(what)}); }

  // True when finite; records a violation otherwise.
  bool finite(const std::string& field, double v) {
    if (std::isfinite(v)) return true;
    add(field, "must be a finite number, got " + fmt(v));
    return false;
  }
  bool finite(const std::string& field, const Eigen::Vector3d& v) {
    if (v.allFinite()) return true;
    add(field, "must have finite components, got " + fmt(v));
    return false;
  }

 private:
  Violations& out_;
};

// Normalises a vector whose length is within tol of 1; records a violation otherwise.
bool unit_vector(Collector& c, const std::string& field, const char* name, Eigen::Vector3d& v,
                 double tol) {
  if (!c.finite(field, v)) return false;
  const double n = v.norm();
  if (std::abs(n - 1.0) > tol) {
    c.add(field, std::string("the ") + name + " must be a unit vector (length within " + fmt(tol) +
                     " of 1), got " + fmt(v) + " of length " + fmt(n));
    return false;
  }
  v /= n;
  return true;
}

void validate_frame(Collector& c, const std::string& at, KeyFrame& f, std::size_t index, std::size_t count,
                    bool closed, UnspecifiedConstraints reading, const FrameTolerances& tol,
                    const PathLimits& limits) {
  if (c.finite(at + ".position", f.p_W) && f.p_W.cwiseAbs().maxCoeff() > limits.max_coordinate) {
    c.add(at + ".position", "coordinates must lie within " + fmt(limits.max_coordinate) + " m of the origin, got " +
                                fmt(f.p_W));
  }
  const bool tangent_ok = unit_vector(c, at + ".tangent", "tangent", f.T_W, tol.unit_length);

  bool normal_ok = false;
  if (f.N_W) {
    normal_ok = unit_vector(c, at + ".normal", "normal", *f.N_W, tol.unit_length);
    if (normal_ok && tangent_ok) {
      const double dot = f.T_W.dot(*f.N_W);
      if (std::abs(dot) > tol.perpendicular) {
        c.add(at + ".normal", "must be perpendicular to the tangent (|T . N| <= " + fmt(tol.perpendicular) +
                                  "), got T . N = " + fmt(dot));
        normal_ok = false;
      } else {
        // Make N exactly perpendicular to T (Gram-Schmidt), then unit again.
        *f.N_W = (*f.N_W - dot * f.T_W).normalized();
      }
    }
  }
  if (f.B_W) {
    if (c.finite(at + ".binormal", *f.B_W) && normal_ok && tangent_ok) {
      const Eigen::Vector3d expected = f.T_W.cross(*f.N_W);
      const double err = (*f.B_W - expected).norm();
      if (err > tol.binormal) {
        c.add(at + ".binormal", "must equal tangent x normal = " + fmt(expected) + ", got " + fmt(*f.B_W));
      }
    } else if (!f.N_W) {
      c.add(at + ".binormal", "a binormal needs a normal (the binormal is checked against tangent x normal)");
    }
    f.B_W.reset();  // checked; the frame's binormal is always T x N from here on
  }

  // Bounded magnitudes keep every product of the conversion (5.10)-(5.22) finite.
  const auto bounded = [&](const std::optional<double>& v, const char* name) {
    if (v && std::isfinite(*v) && std::abs(*v) > limits.max_abs_geometry) {
      c.add(at + "." + name, "magnitude must be at most " + fmt(limits.max_abs_geometry) + ", got " + fmt(*v));
    }
  };
  bounded(f.kappa, "curvature");
  bounded(f.kappa_d, "curvatureDerivative");
  bounded(f.tau, "torsion");
  bounded(f.tau_d, "torsionDerivative");

  bool kappa_positive = false;
  if (f.kappa) {
    if (c.finite(at + ".curvature", *f.kappa)) {
      if (*f.kappa < 0.0) {
        c.add(at + ".curvature", "must be >= 0 (the bending direction is the normal), got " + fmt(*f.kappa));
      } else {
        kappa_positive = *f.kappa > 0.0;
        if (kappa_positive && !f.N_W) {
          c.add(at + ".normal", "is required where curvature > 0 (the curve bends towards the normal)");
        }
        // |p' x p''| = kappa scale^3 enters squared in (5.14)-(5.22): keep it a normal double.
        // Both sides of a cusp: the leaving side may have its own scale.
        const double scale = f.tangent_scale.value_or(1.0);
        const double leave_scale = f.leave_tangent_scale.value_or(scale);
        const double smaller = std::min(scale, leave_scale);
        if (kappa_positive && std::isfinite(scale) && std::isfinite(leave_scale) && smaller > 0.0 &&
            !(*f.kappa * smaller * smaller * smaller > 1e-150)) {
          c.add(at + ".curvature", "curvature x tangentScale^3 = " + fmt(*f.kappa * smaller * smaller * smaller) +
                                       " is too small to define the osculating plane in double precision (needs > 1e-150)");
        }
      }
    }
  }

  // Thesis footnote 5: torsion and the derivatives are undefined where curvature is zero.
  // Under the thesis's reading a zero there is the zero derivative of that order (5.7).
  const bool zeros = reading == UnspecifiedConstraints::kThesisZeros;
  const auto needs_curvature = [&](const std::optional<double>& v, const char* name, const char* what) {
    if (!v) return;
    if (!c.finite(at + "." + name, *v)) return;
    if (zeros && *v == 0.0) return;
    if (!f.kappa) {
      c.add(at + "." + name, std::string(what) + " needs a curvature > 0 at the same frame; curvature is not given");
    } else if (std::isfinite(*f.kappa) && *f.kappa == 0.0) {
      c.add(at + "." + name, std::string(what) + " is undefined where curvature is 0 (give a curvature > 0)");
    }
  };
  needs_curvature(f.kappa_d, "curvatureDerivative", "a curvature derivative");
  needs_curvature(f.tau, "torsion", "torsion");
  needs_curvature(f.tau_d, "torsionDerivative", "a torsion derivative");
  if (f.tau_d && !f.tau && !zeros) {
    c.add(at + ".torsionDerivative", "needs the torsion at the same frame (give torsion, 0 if it should vanish)");
  }

  const auto check_scale = [&](const std::optional<double>& scale, const std::string& field) {
    if (!scale || !c.finite(field, *scale)) return;
    if (!(*scale > 0.0)) {
      c.add(field, "must be > 0 (it is |dp/du| at the frame), got " + fmt(*scale));
    } else if (*scale < limits.min_tangent_scale) {
      c.add(field, "must be at least " + fmt(limits.min_tangent_scale) +
                       " m (smaller ones lose the tangent in rounding), got " + fmt(*scale));
    } else if (*scale > limits.max_tangent_scale) {
      c.add(field, "must be at most " + fmt(limits.max_tangent_scale) + " m, got " + fmt(*scale));
    }
  };
  check_scale(f.tangent_scale, at + ".tangentScale");
  check_scale(f.leave_tangent_scale, at + ".leaveTangentScale");
  if (f.leave_tangent_scale && !closed && index + 1 == count) {
    c.add(at + ".leaveTangentScale", "the last frame of an open path has no leaving side");
  }

  const bool has_both_sides = closed || (index > 0 && index + 1 < count);
  if (f.cusp && !has_both_sides) {
    c.add(at + ".cusp", index == 0 ? "a cusp needs a segment arriving at the frame; the first frame of an open path has none"
                                   : "a cusp needs a segment leaving the frame; the last frame of an open path has none");
  }
  if (f.inflection) {
    if (!has_both_sides) {
      c.add(at + ".inflection", index == 0 ? "an inflection needs a segment arriving at the frame; the first frame of an open path has none"
                                           : "an inflection needs a segment leaving the frame; the last frame of an open path has none");
    } else if (!f.kappa) {
      c.add(at + ".inflection", "an inflection inverts the normal of the curvature: give a curvature at the frame");
    }
  }
}

// Tangent scales the request leaves out (KeyFrame::tangent_scale): each side takes the chord
// length |p_j - p_i| [m] of its own segment, so that |dp/du| is about the segment's chord
// everywhere (a Hermite segment whose end speeds are its chord neither kinks nor bulges).
// A side without a segment (the ends of an open path) takes the other side's chord.
void default_tangent_scales(Collector& c, PathSpec& spec, const PathLimits& limits) {
  const std::size_t n = spec.frames.size();
  if (n < 2) return;
  for (const auto& f : spec.frames)
    if (!f.p_W.allFinite()) return;  // reported by validate_frame
  const std::size_t m = segment_count(n, spec.closed);
  const auto chord = [&](std::size_t seg) -> std::optional<double> {
    if (seg >= m) return std::nullopt;
    const double len = segment_chord(spec, seg);
    return len >= limits.min_tangent_scale ? std::optional<double>(len) : std::nullopt;
  };
  for (std::size_t i = 0; i < n; ++i) {
    KeyFrame& f = spec.frames[i];
    if (f.tangent_scale && f.leave_tangent_scale) continue;
    const bool has_in = spec.closed || i > 0;
    const std::optional<double> in = has_in ? chord((i + m - 1) % m) : std::nullopt;
    const std::optional<double> out = chord(i);
    const std::optional<double> approach = in ? in : out;
    const std::optional<double> leave = out ? out : in;
    if (!f.tangent_scale) {
      if (!approach) {
        c.add("frames[" + std::to_string(i) + "].tangentScale",
              "is not given and cannot default to the chord length: the neighbouring key frames lie at the same "
              "position as this one; give a tangent scale");
        continue;
      }
      f.tangent_scale = *approach;
      if (!f.leave_tangent_scale && leave && (spec.closed || i + 1 < n)) f.leave_tangent_scale = *leave;
    }
  }
}

void validate_breakpoints(Collector& c, const PathSpec& spec, std::size_t segments) {
  if (!spec.breakpoints.empty() && spec.blend != BlendMethod::kTrapezoidal) {
    c.add("breakpoints", "are only used by the TRAPEZOIDAL blend; the request blends with POLYNOMIAL");
    return;
  }
  // One entry per segment at most: more is one mistake, not one per entry (a request of
  // many empty entries must not buy an answer listing each).
  if (spec.breakpoints.size() > segments) {
    c.add("breakpoints", "has " + std::to_string(spec.breakpoints.size()) + " entries; the path has " +
                             std::to_string(segments) + " segments, and each takes one entry at most");
    return;
  }
  std::vector<bool> seen(segments, false);
  for (std::size_t i = 0; i < spec.breakpoints.size(); ++i) {
    const auto& bp = spec.breakpoints[i];
    const std::string at = "breakpoints[" + std::to_string(i) + "]";
    if (bp.segment >= segments) {
      c.add(at + ".segment", "names segment " + std::to_string(bp.segment) + " but the path has " +
                                 std::to_string(segments) + " segments (0.." + std::to_string(segments - 1) + ")");
      continue;
    }
    if (seen[bp.segment]) c.add(at + ".segment", "segment " + std::to_string(bp.segment) + " has breakpoints twice");
    seen[bp.segment] = true;
    if (bp.all.empty() && bp.x.empty() && bp.y.empty() && bp.z.empty()) {
      c.add(at, "gives no breakpoints (fill `all`, or `x`, `y`, `z`)");
    }
    const auto check_list = [&](const std::vector<double>& u, const char* name) {
      const std::string field = at + "." + name;
      for (std::size_t k = 0; k < u.size(); ++k) {
        if (!std::isfinite(u[k]) || u[k] < 0.0 || u[k] > 1.0) {
          c.add(field, "breakpoint " + std::to_string(k) + " = " + fmt(u[k]) +
                           " must lie in the segment's local parameter range [0, 1]");
          return;
        }
        if (k > 0 && u[k] < u[k - 1]) {
          c.add(field, "breakpoints must not decrease; breakpoint " + std::to_string(k) + " = " + fmt(u[k]) +
                           " < " + fmt(u[k - 1]));
          return;
        }
      }
      if (u.size() >= 2 && !(u[1] > u[0])) {
        c.add(field, "the first ramp must have a width: u_1 > u_0, got " + fmt(u[0]) + " and " + fmt(u[1]));
      }
    };
    check_list(bp.all, "all");
    check_list(bp.x, "x");
    check_list(bp.y, "y");
    check_list(bp.z, "z");
  }
}

}  // namespace

Expected<PathSpec> validate_path(const PathSpec& spec, const FrameTolerances& tol, const PathLimits& limits) {
  Violations violations;
  Collector c(violations);
  PathSpec out = spec;
  if (out.frames.size() < 2) {
    c.add("frames", "a path needs at least 2 key frames, got " + std::to_string(out.frames.size()));
  }
  if (out.frames.size() > limits.max_frames) {
    c.add("frames", "at most " + std::to_string(limits.max_frames) + " key frames per path, got " +
                        std::to_string(out.frames.size()));
    return tl::unexpected(std::move(violations));
  }
  default_tangent_scales(c, out, limits);
  for (std::size_t i = 0; i < out.frames.size(); ++i) {
    validate_frame(c, "frames[" + std::to_string(i) + "]", out.frames[i], i, out.frames.size(), out.closed,
                   out.unspecified, tol, limits);
  }
  if (violations.empty() && out.unspecified == UnspecifiedConstraints::kThesisZeros) {
    // The thesis's zeros, written down: every geometric constraint a frame leaves out is
    // 0 (5.7, 7.2.8), so the closed loop checks them like given ones.
    for (auto& f : out.frames) {
      f.kappa = f.kappa.value_or(0.0);
      if (*f.kappa > 0.0) {
        f.kappa_d = f.kappa_d.value_or(0.0);
        f.tau = f.tau.value_or(0.0);
        f.tau_d = f.tau_d.value_or(0.0);
      }
    }
  }
  validate_breakpoints(c, out, segment_count(out.frames.size(), out.closed));
  if (out.max_curvature && !(std::isfinite(*out.max_curvature) && *out.max_curvature > 0.0)) {
    c.add("maxCurvature", "must be a positive, finite curvature in 1/m (the tightest bend the path may have "
                          "without a warning), got " + fmt(*out.max_curvature));
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return out;
}

Violations validate_key_frame(const std::string& at, KeyFrame& frame, bool arriving, bool leaving,
                              UnspecifiedConstraints reading, const FrameTolerances& tol, const PathLimits& limits) {
  Violations violations;
  Collector c(violations);
  const std::size_t index = arriving ? 1 : 0;
  validate_frame(c, at, frame, index, index + (leaving ? 2 : 1), /*closed=*/false, reading, tol, limits);
  return violations;
}

}  // namespace geotraj::core
