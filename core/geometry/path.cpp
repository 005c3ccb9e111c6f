#include "core/geometry/path.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/geometry/arc_length.hpp"
#include "core/geometry/pieces.hpp"
#include "core/geometry/smoothest.hpp"
#include "core/geometry/validate.hpp"

namespace geotraj::core {

using Eigen::Vector3d;

namespace {

// Hermite data of one side: jet[0] = p, jet[k] = d^k p/du^k for k <= order, zero above.
Jet side_jet(const Vector3d& p, const SideConstraints& side) {
  Jet jet;
  jet[0] = p;
  for (int k = 1; k <= kMaxJetOrder; ++k) jet[k] = k <= side.order ? side.d[k - 1] : Vector3d::Zero();
  return jet;
}

// The breakpoint list for one axis of one segment and the field that gave it.
struct AxisBreakpoints {
  std::vector<double> u;
  std::string field;  // empty when defaulted
};

AxisBreakpoints axis_breakpoints(const PathSpec& spec, std::size_t segment, int axis, int n) {
  static constexpr const char* kAxisName[] = {"x", "y", "z"};
  for (std::size_t i = 0; i < spec.breakpoints.size(); ++i) {
    const auto& bp = spec.breakpoints[i];
    if (bp.segment != segment) continue;
    const std::vector<double>* lists[] = {&bp.x, &bp.y, &bp.z};
    const std::string at = "breakpoints[" + std::to_string(i) + "].";
    if (!lists[axis]->empty()) return {*lists[axis], at + kAxisName[axis]};
    if (!bp.all.empty()) return {bp.all, at + "all"};
  }
  const auto uniform = uniform_breakpoints(n);  // (B.10)
  return {std::vector<double>(uniform.begin(), uniform.begin() + 2 * n + 2), {}};
}

Expected<Segment> make_segment(const PathSpec& spec, std::size_t index, const FrameConstraints& from,
                               const FrameConstraints& to) {
  const Jet start = side_jet(from.p_W, from.leave);
  const Jet end = side_jet(to.p_W, to.approach);
  const int n0 = from.leave.order;
  const int n1 = to.approach.order;
  if (spec.blend == BlendMethod::kPolynomial) return Segment{hermite_bezier(start, n0, end, n1)};

  // The trapezoid needs the full state 0..n-1 at both ends; orders that a frame leaves
  // free are taken as zero there (the thesis's convention, Table 7.9).
  const int n = trapezoid_order(n0, n1);
  TrapezoidSegment seg;
  Violations violations;
  for (int axis = 0; axis < 3; ++axis) {
    std::array<double, kMaxTrapezoidOrder> s{}, e{};
    for (int k = 0; k < n; ++k) {
      s[k] = start[k](axis);
      e[k] = end[k](axis);
    }
    const AxisBreakpoints bp = axis_breakpoints(spec, index, axis, n);
    if (bp.u.size() != static_cast<std::size_t>(2 * n + 2)) {
      const bool reported = std::any_of(violations.begin(), violations.end(),
                                        [&](const FieldViolation& v) { return v.field == bp.field; });
      if (reported) continue;  // several axes fall back to the same `all` list
      violations.push_back({bp.field, "segment " + std::to_string(index) + " blends with an order-" + std::to_string(n) +
                                          " trapezoid (its frames fix derivatives up to " + std::to_string(n - 1) +
                                          "), which needs " + std::to_string(2 * n + 2) + " breakpoints; got " +
                                          std::to_string(bp.u.size())});
      continue;
    }
    auto axis_or = make_trapezoid(n, bp.u, std::span<const double>(s.data(), n), std::span<const double>(e.data(), n));
    if (!axis_or) {
      violations.push_back({bp.field.empty() ? "breakpoints" : bp.field,
                            "segment " + std::to_string(index) + ": " + axis_or.error()});
      continue;
    }
    seg.axes[axis] = *axis_or;
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return Segment{seg};
}

bool finite(const SideConstraints& s) {
  for (int k = 0; k < s.order; ++k)
    if (!s.d[k].allFinite()) return false;
  return true;
}

}  // namespace

Expected<Path> build_path(const PathSpec& raw) {
  if (raw.start || !raw.pieces.empty()) return build_piece_path(raw);
  auto valid = validate_path(raw);
  if (!valid) return tl::unexpected(std::move(valid.error()));
  Path path;
  path.spec = std::move(*valid);
  const auto& frames = path.spec.frames;
  Violations violations;
  path.frames.reserve(frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    path.frames.push_back(convert_frame(frames[i], path.spec.convention));
    if (!finite(path.frames.back().approach) || !finite(path.frames.back().leave)) {
      violations.push_back({"frames[" + std::to_string(i) + "]",
                            "the constraints at this frame overflow double precision (derivatives of p are not finite); "
                            "reduce the torsion, derivatives or tangent scale"});
    }
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  switch (path.spec.unspecified) {
    case UnspecifiedConstraints::kSmoothest:
      if (auto filled = fill_smoothest(path.spec, path.frames); !filled) return tl::unexpected(std::move(filled.error()));
      break;
    case UnspecifiedConstraints::kThesisZeros:
      fill_thesis_zeros(path.frames);
      break;
    case UnspecifiedConstraints::kLowestDegree:
      break;
  }
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (!finite(path.frames[i].approach) || !finite(path.frames[i].leave)) {
      return tl::unexpected(Violations{{"frames[" + std::to_string(i) + "]",
                                        "the smoothest derivatives at this frame overflow double precision; reduce the "
                                        "tangent scales or choose THESIS_ZEROS"}});
    }
  }

  const std::size_t m = segment_count(frames.size(), path.spec.closed);
  path.segments.reserve(m);
  for (std::size_t i = 0; i < m; ++i) {
    auto seg = make_segment(path.spec, i, path.frames[i], path.frames[(i + 1) % frames.size()]);
    if (!seg) {
      violations.insert(violations.end(), seg.error().begin(), seg.error().end());
      continue;
    }
    path.segments.push_back(std::move(*seg));
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));

  path.p_uu_noise.reserve(m);
  for (const auto& seg : path.segments) path.p_uu_noise.push_back(segment_noise(seg));
  path.segment_lengths.reserve(m);
  path.cumulative_lengths.reserve(m + 1);
  path.cumulative_lengths.push_back(0.0);
  for (std::size_t i = 0; i < m; ++i) {
    path.segment_lengths.push_back(segment_arc_length(path.segments[i], 0.0, 1.0));
    path.cumulative_lengths.push_back(path.cumulative_lengths.back() + path.segment_lengths.back());
    if (!std::isfinite(path.cumulative_lengths.back())) {
      violations.push_back({"frames[" + std::to_string(i) + "]",
                            "the segment leaving this frame is too long to measure in double precision; reduce the "
                            "torsion, derivatives or tangent scale"});
      return tl::unexpected(std::move(violations));
    }
  }
  return path;
}

std::string frame_name(const Path& path, std::size_t k) {
  if (k < path.frame_fields.size()) return path.frame_fields[k];
  return "frames[" + std::to_string(k) + "]";
}

std::string frame_field(const Path& path, std::size_t k, const char* name) {
  return frame_name(path, k) + "." + name;
}

std::string mode_field(const Path& path, std::size_t k) {
  return frame_field(path, k < path.mode_frames.size() ? path.mode_frames[k] : k, "orientationMode");
}

double segment_noise(const Segment& segment) {
  constexpr double kUlps = 256.0 * std::numeric_limits<double>::epsilon();
  // A natural segment's d2p/du2 is (s1 - s0)^2 kappa N with N from its frame: no cancellation.
  if (std::holds_alternative<NaturalSegment>(segment)) return 0.0;
  if (const auto* bez = std::get_if<BezierSegment>(&segment)) {
    double largest = 0.0;
    for (int i = 0; i <= bez->degree; ++i) largest = std::max(largest, bez->b[i].cwiseAbs().maxCoeff());
    return kUlps * bez->degree * bez->degree * largest;  // d(d-1) Delta^2 b
  }
  double sum = 0.0;
  for (const auto& axis : std::get<TrapezoidSegment>(segment).axes) {
    for (int k = 0; k < axis.n; ++k) sum += std::abs(axis.start[k]);
    for (int r = 0; r <= axis.n; ++r) sum += std::abs(axis.c[r]);
  }
  return kUlps * sum;
}

std::pair<std::size_t, double> locate(const Path& path, double u) {
  GEOTRAJ_CHECK(!path.segments.empty());
  const double m = path.u_max();
  if (!(u > 0.0)) return {0, 0.0};  // also NaN
  if (u >= m) return {path.segments.size() - 1, 1.0};
  const double i = std::floor(u);
  return {static_cast<std::size_t>(i), u - i};
}

void evaluate(const Segment& segment, double u_local, int max_order, Jet& jet) {
  GEOTRAJ_CHECK(max_order >= 0 && max_order <= kMaxJetOrder);
  if (const auto* bez = std::get_if<BezierSegment>(&segment)) {
    evaluate(*bez, u_local, max_order, jet);
    return;
  }
  if (const auto* nat = std::get_if<NaturalSegment>(&segment)) {
    const double l = nat->length();
    const Jet s = nat->curve->jet_at(nat->s0 + u_local * l);
    double f = 1.0;
    for (int k = 0; k <= max_order; ++k, f *= l) jet[k] = s[k] * f;
    return;
  }
  const auto& trap = std::get<TrapezoidSegment>(segment);
  double v[kMaxJetOrder + 1];
  for (int axis = 0; axis < 3; ++axis) {
    evaluate(trap.axes[axis], u_local, max_order, v);
    for (int k = 0; k <= max_order; ++k) jet[k](axis) = v[k];
  }
}

Jet evaluate(const Path& path, double u, int max_order) {
  const auto [i, ul] = locate(path, u);
  Jet jet;
  for (auto& v : jet) v.setZero();
  evaluate(path.segments[i], ul, max_order, jet);
  return jet;
}

}  // namespace geotraj::core
