// A path of pieces. See pieces.hpp.
#include "core/geometry/pieces.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <utility>
#include <variant>

#include "core/format.hpp"
#include "core/geometry/arc_length.hpp"
#include "core/geometry/validate.hpp"

namespace geotraj::core {

using Eigen::Vector3d;

namespace {

std::string piece_field(std::size_t i) { return "pieces[" + std::to_string(i) + "]"; }

bool bends(const PieceProfile& p) {
  return std::any_of(p.kappa.begin(), p.kappa.end(), [](double c) { return c != 0.0; });
}

// Any unit vector perpendicular to the unit vector t.
Vector3d perpendicular(const Vector3d& t) {
  const Vector3d a = std::abs(t.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY();
  return (a - a.dot(t) * t).normalized();
}

FrenetFrame frenet(const Vector3d& p, const Vector3d& T, const Vector3d& N) {
  FrenetFrame f;
  f.p = p;
  f.R.col(0) = T;
  f.R.col(1) = N;
  f.R.col(2) = T.cross(N);
  return f;
}

// Two curvatures (or torsions) [1/m] the same at a join: to 1e-9 relative, 1e-9 1/m absolute.
bool same(double a, double b) { return std::abs(a - b) <= 1e-9 * std::max({1.0, std::abs(a), std::abs(b)}); }

// One natural piece of the request, the part [s0, s1] of its curve kept (transitions trim).
struct NaturalItem {
  std::size_t piece = 0;
  std::shared_ptr<const NaturalCurve> curve;
  double s0 = 0.0, s1 = 0.0;
  std::optional<BezierSegment> transition_in;  // the transition that replaced its start
};

// Consecutive `to` pieces [first, last].
struct RunItem {
  std::size_t first = 0, last = 0;
};

using Item = std::variant<NaturalItem, RunItem>;

// The orientation mode and its data that a synthesized frame inherits from the user's frame
// that governs it (`start` or a `to` frame).
void inherit(KeyFrame& f, const KeyFrame& governing) {
  f.orientation_mode =
      governing.orientation_mode == OrientationMode::kCustom ? OrientationMode::kFixed : governing.orientation_mode;
  f.ease_orientation = governing.ease_orientation;
}

// The key frame at arc length s of a natural curve, with its full state (kappa >= 0 along N).
KeyFrame natural_frame(const NaturalCurve& c, double s) {
  const FrenetFrame F = c.frame_at(s);
  double k = c.kappa_at(s), k1 = c.kappa_at(s, 1);
  Vector3d N = F.N();
  if (k < 0.0) k = -k, k1 = -k1, N = -N;  // the bending direction is the normal (tau unchanged)
  KeyFrame f;
  f.p_W = F.p;
  f.T_W = F.T();
  f.N_W = N;
  f.kappa = k;
  if (k > 0.0) {
    f.kappa_d = k1;
    f.tau = c.tau_at(s);
    f.tau_d = c.tau_at(s, 1);
  }
  return f;
}

// jet in s -> jet in u for |dp/du| = scale.
Jet scaled(const Jet& s, double scale) {
  Jet u;
  double f = 1.0;
  for (int k = 0; k <= kMaxJetOrder; ++k, f *= scale) u[k] = s[k] * f;
  return u;
}

// ---------------------------------------------------------------------------------------
// Transitions.

// The G4 Bezier from a's curve at a_s to b's curve at b_s (tangent scale: the chord).
BezierSegment g4_blend(const NaturalCurve& a, double a_s, const NaturalCurve& b, double b_s) {
  const Jet ja = a.jet_at(a_s), jb = b.jet_at(b_s);
  const double chord = (jb[0] - ja[0]).norm();
  return hermite_bezier(scaled(ja, chord), kMaxJetOrder, scaled(jb, chord), kMaxJetOrder);
}

// Distance [m] from q to c's part [lo, hi]: Newton on (c(s) - q) . c'(s) = 0 from `s` (a
// local minimum, so never below the true distance to the part).
double distance_to(const NaturalCurve& c, double lo, double hi, const Vector3d& q, double s) {
  s = std::clamp(s, lo, hi);
  for (int it = 0; it < 12; ++it) {
    const Jet j = c.jet_at(s);
    const Vector3d d = j[0] - q;
    const double g = d.dot(j[1]);          // unit speed: d/ds |d|^2 / 2
    const double h = 1.0 + d.dot(j[2]);    // its derivative
    const double next = std::clamp(s - (h > 0.1 ? g / h : g), lo, hi);
    const bool done = std::abs(next - s) <= 1e-15 * std::max(1.0, std::abs(s));
    s = next;
    if (done) break;
  }
  return (c.frame_at(s).p - q).norm();
}

// The largest distance [m] of the transition of half-length l at the join of a (length La)
// and b from the programmed pieces, at `samples` points.
double transition_deviation(const NaturalCurve& a, const NaturalCurve& b, double l, int samples) {
  const double La = a.length();
  const BezierSegment seg = g4_blend(a, La - l, b, l);
  double worst = 0.0;
  Jet jet;
  for (int i = 1; i < samples; ++i) {
    const double u = static_cast<double>(i) / samples;
    evaluate(seg, u, 0, jet);
    const double sigma = -l + 2.0 * l * u;  // the programmed point at the same fraction
    const double d = std::min(distance_to(a, La - l, La, jet[0], La + sigma), distance_to(b, 0.0, l, jet[0], sigma));
    worst = std::max(worst, d);
  }
  return worst;
}

// The transition's half-length [m]: the largest l <= l_max whose transition stays within
// `tolerance` of the pieces.
double transition_length(const NaturalCurve& a, const NaturalCurve& b, double l_max, double tolerance) {
  constexpr int kSearch = 64, kCheck = 512;
  const double target = 0.9 * tolerance;  // room for what lies between the search's points
  const auto fits = [&](double l, int samples, double tol) { return transition_deviation(a, b, l, samples) <= tol; };
  double lo = l_max;
  if (!fits(lo, kSearch, target)) {
    double hi = lo;
    for (int i = 0; i < 60 && !fits(lo, kSearch, target); ++i) hi = lo, lo *= 0.25;
    for (int i = 0; i < 24; ++i) {
      const double mid = 0.5 * (lo + hi);
      (fits(mid, kSearch, target) ? lo : hi) = mid;
    }
  }
  for (int i = 0; i < 60 && !fits(lo, kCheck, tolerance); ++i) lo *= 0.9;
  return lo;
}

// Renames a sub-path's `frames[j]` fields: frame 0 is `at0`, frame j >= 1 `pieces[first + j - 1].to`.
Violations renamed(Violations v, const std::string& at0, std::size_t first) {
  for (auto& e : v) {
    if (e.field.rfind("frames[", 0) != 0) continue;
    const std::size_t close = e.field.find(']');
    const std::size_t j = std::stoul(e.field.substr(7, close - 7));
    e.field = (j == 0 ? at0 : piece_field(first + j - 1) + ".to") + e.field.substr(close + 1);
  }
  return v;
}

}  // namespace

PieceProfile piece_profile(const PathPiece& piece, double start_curvature) {
  switch (piece.shape) {
    case PieceShape::kLine:
      return {};
    case PieceShape::kArc:
      return {{1.0 / piece.radius}, {}};
    case PieceShape::kHelix: {
      const CurvatureTorsion ct = helix_curvature_torsion(piece.radius, piece.pitch);
      return {{ct.kappa}, {ct.tau}};
    }
    case PieceShape::kClothoid:
      return {{start_curvature, (piece.end_curvature - start_curvature) / piece.length_m}, {}};
    case PieceShape::kProfile:
      return {piece.curvature, piece.torsion};
    case PieceShape::kTo:
      break;
  }
  return {};
}

Expected<Path> build_piece_path(const PathSpec& raw) {
  Violations v;
  const PathLimits limits;
  const auto add = [&](std::string field, std::string what) { v.push_back({std::move(field), std::move(what)}); };
  if (!raw.start) add("start", "is required with pieces: the frame the first piece starts from");
  if (raw.pieces.empty()) add("pieces", "a path with a start needs at least one piece");
  if (raw.pieces.size() > kMaxPieces)
    add("pieces", "at most " + std::to_string(kMaxPieces) + " pieces per path, got " + std::to_string(raw.pieces.size()));
  if (!raw.frames.empty()) add("frames", "a path is either key frames (frames) or a start and pieces, not both");
  if (raw.closed) add("closed", "a path of pieces is open (end it with a piece `to` the start's frame to return)");
  if (!raw.breakpoints.empty()) add("breakpoints", "apply to trapezoid blends of key frames, not to pieces");
  if (raw.blend != BlendMethod::kPolynomial)
    add("blend", "a path of pieces blends its `to` pieces and transitions with polynomials (BLEND_METHOD_POLYNOMIAL)");
  if (raw.convention != DerivativeConvention::kPerArcLength)
    add("derivativeConvention", "a path of pieces is written per arc length (DERIVATIVE_CONVENTION_PER_ARC_LENGTH)");
  const double tolerance = raw.transition_tolerance.value_or(0.0);
  if (!(std::isfinite(tolerance) && tolerance >= 0.0 && tolerance <= kMaxTransitionTolerance)) {
    add("transitionTolerance", "must be a distance in [0, " + number(kMaxTransitionTolerance) + "] m, got " +
                                   number(tolerance));
  }
  if (raw.max_curvature && !(std::isfinite(*raw.max_curvature) && *raw.max_curvature > 0.0))
    add("maxCurvature", "must be a positive, finite curvature in 1/m, got " + number(*raw.max_curvature));
  if (!v.empty()) return tl::unexpected(std::move(v));

  PathSpec spec = raw;
  KeyFrame& start = *spec.start;
  const bool first_natural = spec.pieces.front().shape != PieceShape::kTo;
  {
    auto sv = validate_key_frame("start", start, false, true, spec.unspecified);
    v.insert(v.end(), sv.begin(), sv.end());
  }
  if (first_natural) {
    const auto not_here = [&](bool given, const char* name) {
      if (given)
        add(std::string("start.") + name, "the first piece sets it where the path starts; give it only when pieces[0] "
                                          "blends `to` a key frame");
    };
    not_here(start.kappa.has_value(), "curvature");
    not_here(start.kappa_d.has_value(), "curvatureDerivative");
    not_here(start.tau.has_value(), "torsion");
    not_here(start.tau_d.has_value(), "torsionDerivative");
    not_here(start.tangent_scale.has_value(), "tangentScale");
    not_here(start.leave_tangent_scale.has_value(), "leaveTangentScale");
  }
  if (start.orientation && start.orientation_mode != OrientationMode::kFixed &&
      start.orientation_mode != OrientationMode::kCustom) {
    add("start.orientation", "is used with ORIENTATION_MODE_FIXED (the tool orientation held) or "
                             "ORIENTATION_MODE_CUSTOM (the target of the first piece)");
  }

  // Each piece's own fields.
  for (std::size_t i = 0; i < spec.pieces.size(); ++i) {
    const PathPiece& p = spec.pieces[i];
    const std::string at = piece_field(i);
    if (p.shape == PieceShape::kTo) {
      if (p.length_m != 0.0) add(at + ".lengthM", "is not used by a piece that blends `to` a key frame; leave it 0");
      auto kv = validate_key_frame(at + ".to", spec.pieces[i].to, true, i + 1 < spec.pieces.size(), spec.unspecified);
      v.insert(v.end(), kv.begin(), kv.end());
      if (p.to.cusp && i + 1 < spec.pieces.size() && spec.pieces[i + 1].shape != PieceShape::kTo)
        add(at + ".to.cusp", "a cusp is a rest between key frames; here a natural piece follows");
      continue;
    }
    if (!(std::isfinite(p.length_m) && p.length_m > 0.0 && p.length_m <= limits.max_coordinate))
      add(at + ".lengthM", "must be a length in (0, " + number(limits.max_coordinate) + "] m, got " + number(p.length_m));
    const auto radius_ok = [&] {
      if (std::isfinite(p.radius) && p.radius >= 1.0 / limits.max_abs_geometry && p.radius <= limits.max_coordinate)
        return true;
      add(at + ".radius", "must be a radius in [" + number(1.0 / limits.max_abs_geometry) + ", " +
                              number(limits.max_coordinate) + "] m, got " + number(p.radius));
      return false;
    };
    switch (p.shape) {
      case PieceShape::kArc:
        radius_ok();
        break;
      case PieceShape::kHelix:
        if (radius_ok() && !(std::isfinite(p.pitch) && std::abs(p.pitch) <= limits.max_coordinate))
          add(at + ".pitch", "must be a finite rise per turn within " + number(limits.max_coordinate) + " m, got " +
                                 number(p.pitch));
        break;
      case PieceShape::kClothoid:
        if (!(std::isfinite(p.end_curvature) && std::abs(p.end_curvature) <= limits.max_abs_geometry))
          add(at + ".endCurvature", "must be a finite curvature within " + number(limits.max_abs_geometry) +
                                        " 1/m, got " + number(p.end_curvature));
        break;
      case PieceShape::kProfile:
        if (p.curvature.empty() && p.torsion.empty())
          add(at + ".curvature", "a profile needs its curvature's coefficients (and torsion's, if it twists); for a "
                                 "straight piece use `line`");
        break;
      default:
        break;
    }
  }
  if (!v.empty()) return tl::unexpected(std::move(v));

  // Walk the pieces: natural curves from where the previous piece ends; runs of `to` pieces.
  std::vector<Item> items;
  FrenetFrame F = frenet(start.p_W, start.T_W, start.N_W.value_or(perpendicular(start.T_W)));
  bool have_normal = start.N_W.has_value();
  std::string normal_field = "start.normal";
  double kappa_end = start.kappa.value_or(0.0);  // signed, along F's N
  std::size_t total_steps = 0;
  for (std::size_t i = 0; i < spec.pieces.size();) {
    const PathPiece& p = spec.pieces[i];
    if (p.shape == PieceShape::kTo) {
      RunItem run{i, i};
      while (run.last + 1 < spec.pieces.size() && spec.pieces[run.last + 1].shape == PieceShape::kTo) ++run.last;
      const KeyFrame& k = spec.pieces[run.last].to;  // checked and normalised above
      const std::string at = piece_field(run.last) + ".to";
      F = frenet(k.p_W, k.T_W, k.N_W.value_or(perpendicular(k.T_W)));
      have_normal = k.N_W.has_value();
      normal_field = at + ".normal";
      kappa_end = k.kappa.value_or(0.0);
      items.emplace_back(run);
      i = run.last + 1;
      continue;
    }
    const PieceProfile prof = piece_profile(p, kappa_end);
    if (bends(prof) && !have_normal) {
      add(normal_field, "is required: " + piece_field(i) + " bends towards the normal where it starts");
      return tl::unexpected(std::move(v));
    }
    auto curve = NaturalCurve::build(F, p.length_m, prof.kappa, prof.tau);
    if (!curve) {
      v = prefixed(curve.error(), piece_field(i) + ".");
      return tl::unexpected(std::move(v));
    }
    total_steps += curve->steps();
    if (total_steps > kMaxPathNaturalSteps) {
      add(piece_field(i), "the pieces up to this one need " + std::to_string(total_steps) +
                              " integration steps; one path may take at most " + std::to_string(kMaxPathNaturalSteps) +
                              " (fewer or shorter pieces, or profiles that vary less)");
      return tl::unexpected(std::move(v));
    }
    NaturalItem item;
    item.piece = i;
    item.curve = std::make_shared<const NaturalCurve>(std::move(*curve));
    item.s1 = item.curve->length();
    F = item.curve->end();
    have_normal = true;  // the piece's own frame carries it on
    kappa_end = item.curve->kappa_at(item.s1);
    items.emplace_back(std::move(item));
    ++i;
  }

  // Joins of natural pieces: continuous, a transition, or a rest.
  const auto jumps = [&](std::size_t j) {
    const auto* a = std::get_if<NaturalItem>(&items[j]);
    const auto* b = std::get_if<NaturalItem>(&items[j + 1]);
    if (!a || !b) return false;
    const NaturalCurve& ca = *a->curve;
    const NaturalCurve& cb = *b->curve;
    const double ka = ca.kappa_at(ca.length()), kb = cb.kappa_at(0.0);
    const bool bent = !same(ka, 0.0) || !same(kb, 0.0);
    return !(same(ka, kb) && (!bent || same(ca.tau_at(ca.length()), cb.tau_at(0.0))));
  };
  std::vector<bool> rest_after(items.size(), false);
  std::size_t transitions = 0;
  for (std::size_t j = 0; j + 1 < items.size(); ++j) transitions += jumps(j) ? 1 : 0;
  if (tolerance > 0.0 && transitions > kMaxTransitions) {
    add("transitionTolerance", "asks for " + std::to_string(transitions) + " transitions; one path may have at most " +
                                   std::to_string(kMaxTransitions) + " (split the path, or join pieces of equal curvature)");
    return tl::unexpected(std::move(v));
  }
  for (std::size_t j = 0; j + 1 < items.size(); ++j) {
    if (!jumps(j)) continue;
    auto* a = std::get_if<NaturalItem>(&items[j]);
    auto* b = std::get_if<NaturalItem>(&items[j + 1]);
    const NaturalCurve& ca = *a->curve;
    const NaturalCurve& cb = *b->curve;
    const double ka = ca.kappa_at(ca.length()), kb = cb.kappa_at(0.0);
    if (!(tolerance > 0.0)) {
      rest_after[j] = true;
      continue;
    }
    // At most a third of either piece (so a piece between two transitions keeps a third of
    // its exact shape), and a quarter turn of the frame on either side (the distance search
    // is local).
    const double turn = std::max(std::hypot(ka, ca.tau_at(ca.length())), std::hypot(kb, cb.tau_at(0.0)));
    double l_max = kTransitionShare * std::min(ca.length(), cb.length());
    if (turn > 0.0) l_max = std::min(l_max, 0.25 * std::numbers::pi / turn);
    const double l = transition_length(ca, cb, l_max, tolerance);
    // A transition too short to turn the tangent in double precision (pieces of a few
    // nanometres, curvatures of 1e9 1/m): the join is a rest instead.
    const double chord = (cb.frame_at(l).p - ca.frame_at(ca.length() - l).p).norm();
    if (!(l >= kMinTransition && chord >= kMinTransition)) {
      rest_after[j] = true;
      continue;
    }
    a->s1 = ca.length() - l;
    b->s0 = l;
    b->transition_in = g4_blend(ca, a->s1, cb, b->s0);
  }

  // Assemble: segments, and the frame at the end of each.
  Path path;
  std::vector<KeyFrame> frames{start};
  std::vector<std::string> fields{"start"};
  std::vector<std::size_t> modes{0};
  const KeyFrame* governing = &start;
  std::size_t governing_frame = 0;
  const auto synthesized = [&](KeyFrame f, std::size_t piece) {
    inherit(f, *governing);
    frames.push_back(std::move(f));
    fields.push_back(piece_field(piece));
    modes.push_back(governing_frame);
  };
  for (std::size_t j = 0; j < items.size(); ++j) {
    if (const auto* n = std::get_if<NaturalItem>(&items[j])) {
      if (n->transition_in) {
        path.segments.emplace_back(*n->transition_in);
        path.origins.push_back({SegmentKind::kTransition, n->piece});
        synthesized(natural_frame(*n->curve, n->s0), n->piece);
      }
      path.segments.emplace_back(NaturalSegment{n->curve, n->s0, n->s1});
      path.origins.push_back({SegmentKind::kPiece, n->piece});
      KeyFrame end = natural_frame(*n->curve, n->s1);
      if (rest_after[j]) {  // the curvature jumps: neither side's state is the frame's
        end.kappa.reset(), end.kappa_d.reset(), end.tau.reset(), end.tau_d.reset();
        end.stop = true;
      }
      synthesized(std::move(end), n->piece);
      continue;
    }
    const RunItem& run = std::get<RunItem>(items[j]);
    PathSpec sub;
    sub.unspecified = spec.unspecified;
    sub.max_curvature = spec.max_curvature;
    sub.frames.push_back(run.first == 0 ? start : frames.back());
    const std::string at0 = run.first == 0 ? std::string("start") : piece_field(run.first - 1);
    for (std::size_t i = run.first; i <= run.last; ++i) sub.frames.push_back(spec.pieces[i].to);
    // The key frame a natural piece leaves: what it does not give, from that piece's start.
    const NaturalItem* next = j + 1 < items.size() ? std::get_if<NaturalItem>(&items[j + 1]) : nullptr;
    if (next) {
      KeyFrame& k = sub.frames.back();
      const KeyFrame b = natural_frame(*next->curve, 0.0);
      const double kb = next->curve->kappa_at(0.0);  // signed along k's normal
      if (!k.kappa && kb >= 0.0) k.kappa = kb;
      if (k.kappa && same(*k.kappa, kb) && kb > 0.0) {
        if (!k.kappa_d) k.kappa_d = b.kappa_d;
        if (!k.tau) k.tau = b.tau;
        if (!k.tau_d) k.tau_d = b.tau_d;
      }
      const bool continuous = k.kappa && same(*k.kappa, kb) && (!(kb > 0.0) || (k.tau && same(*k.tau, *b.tau)));
      if (!continuous) k.stop = true;
    }
    auto built = build_path(sub);
    if (!built) return tl::unexpected(renamed(std::move(built.error()), at0, run.first));
    for (std::size_t i = 0; i < built->segments.size(); ++i) {
      path.segments.push_back(std::move(built->segments[i]));
      path.origins.push_back({SegmentKind::kBlend, run.first + i});
    }
    for (std::size_t f = 1; f < built->spec.frames.size(); ++f) {
      frames.push_back(built->spec.frames[f]);
      fields.push_back(piece_field(run.first + f - 1) + ".to");
      modes.push_back(frames.size() - 1);  // a key frame's own mode
    }
    governing = &spec.pieces[run.last].to;
    governing_frame = frames.size() - 1;
  }

  // The frames' two sides, from the segments' own jets (G4 across natural joins by
  // construction; what a rest or the key frames make elsewhere).
  const std::size_t m = path.segments.size();
  path.frames.resize(frames.size());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    FrameConstraints& fc = path.frames[k];
    fc.p_W = frames[k].p_W;
    const auto side = [&](const Segment& seg, double u) {
      Jet jet;
      evaluate(seg, u, kMaxJetOrder, jet);
      SideConstraints sc;
      sc.order = kMaxJetOrder;
      for (int d = 1; d <= kMaxJetOrder; ++d) sc.d[d - 1] = jet[d];
      sc.T = jet[1].normalized();
      const Vector3d across = jet[2] - jet[2].dot(sc.T) * sc.T;
      sc.N = across.norm() > 1e-12 * jet[1].squaredNorm() ? Vector3d(across.normalized()) : Vector3d::Zero();
      return sc;
    };
    if (k > 0) fc.approach = side(path.segments[k - 1], 1.0);
    if (k < m) fc.leave = side(path.segments[k], 0.0);
    if (k == 0) fc.approach = fc.leave;
    if (k == m) fc.leave = fc.approach;
  }
  spec.start = start;
  spec.frames = std::move(frames);
  path.spec = std::move(spec);
  path.frame_fields = std::move(fields);
  path.mode_frames = std::move(modes);
  path.p_uu_noise.reserve(m);
  path.segment_lengths.reserve(m);
  path.cumulative_lengths.assign(1, 0.0);
  for (std::size_t i = 0; i < m; ++i) {
    path.p_uu_noise.push_back(segment_noise(path.segments[i]));
    path.segment_lengths.push_back(segment_arc_length(path.segments[i], 0.0, 1.0));
    path.cumulative_lengths.push_back(path.cumulative_lengths.back() + path.segment_lengths.back());
  }
  if (!std::isfinite(path.length()))
    return tl::unexpected(Violations{{"pieces", "the path is too long to measure in double precision"}});
  return path;
}

}  // namespace geotraj::core
