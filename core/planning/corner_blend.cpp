// Corner blending of a chain of lines and paths. See corner_blend.hpp.
#include "core/planning/corner_blend.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "core/format.hpp"

namespace geotraj::core {
namespace {

using Eigen::Vector3d;

// Share of a line that one blend may take: a line between two blends keeps 10 % straight.
constexpr double kMaxCutShare = 0.45;
// Bisection of the cut next to a path aims below the tolerance by this factor, so that the
// path's coupling seldom needs a second round.
constexpr double kBisectionMargin = 0.95;
constexpr int kBisectionSteps = 40;
constexpr int kRefinementRounds = 8;

double distance_to_segment(const Vector3d& p, const Vector3d& a, const Vector3d& b) {
  const Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

// A key frame on a line: its tangent, curvature 0 (so the blend meets it G2), an
// inflection when it is interior (the sides independent: the line stays straight).
KeyFrame line_frame(const Vector3d& p, const Vector3d& d, bool interior) {
  KeyFrame f;
  f.p_W = p;
  f.T_W = d;
  f.kappa = 0.0;
  f.inflection = interior;
  f.orientation_mode = OrientationMode::kFixed;
  return f;
}

// The geometry a path's end frame gives (no flags, scales or orientation): what a blend
// must meet there.
KeyFrame geometric_copy(const KeyFrame& f) {
  KeyFrame g;
  g.p_W = f.p_W;
  g.T_W = f.T_W;
  g.N_W = f.N_W;
  g.B_W = f.B_W;
  g.kappa = f.kappa;
  g.kappa_d = f.kappa_d;
  g.tau = f.tau;
  g.tau_d = f.tau_d;
  return g;
}

struct Reading {
  DerivativeConvention convention = DerivativeConvention::kPerArcLength;
  UnspecifiedConstraints unspecified = UnspecifiedConstraints::kSmoothest;
  std::optional<double> max_curvature;
};

PathSpec spec_of(std::vector<KeyFrame> frames, const Reading& reading) {
  PathSpec spec;
  spec.frames = std::move(frames);
  spec.convention = reading.convention;
  spec.unspecified = reading.unspecified;
  spec.max_curvature = reading.max_curvature;
  return spec;
}

// The deviation of a lone blend (a two-frame path) from `route`, or infinity when it does
// not build.
double lone_deviation(const KeyFrame& a, const KeyFrame& b, const Reading& reading,
                      const std::vector<Vector3d>& route) {
  auto path = build_path(spec_of({a, b}, reading));
  if (!path) return std::numeric_limits<double>::infinity();
  return deviation_from(*path, 0, route);
}

const KeyFrame& first_frame(const PathSpec& p) { return p.frames.front(); }
const KeyFrame& last_frame(const PathSpec& p) { return p.frames.back(); }

}  // namespace

double deviation_from(const Path& path, std::size_t segment, const std::vector<Vector3d>& route, int samples) {
  double worst = 0.0;
  Jet jet;
  for (int k = 0; k <= samples; ++k) {
    evaluate(path.segments[segment], static_cast<double>(k) / samples, 0, jet);
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i + 1 < route.size(); ++i) {
      nearest = std::min(nearest, distance_to_segment(jet[0], route[i], route[i + 1]));
    }
    worst = std::max(worst, nearest);
  }
  return worst;
}

Expected<BlendedChain> blend_chain(const std::vector<BlendPiece>& pieces, const std::vector<double>& tolerances,
                                   const std::vector<std::string>& names) {
  const std::size_t n = pieces.size();
  GEOTRAJ_CHECK(n >= 2 && tolerances.size() == n - 1 && names.size() == n);
  Violations violations;

  // The pieces on their own: lines with a length, paths open, polynomial, of one reading.
  std::optional<Reading> reading;
  std::vector<Vector3d> direction(n, Vector3d::Zero());
  std::vector<double> length(n, 0.0);
  for (std::size_t k = 0; k < n; ++k) {
    if (const auto* line = std::get_if<BlendLine>(&pieces[k])) {
      length[k] = (line->p1 - line->p0).norm();
      if (!(length[k] > 0.0)) {
        violations.push_back({names[k] + ".blendTolerance",
                              "a line without length (a pure rotation) has no corner to blend: rest before and after "
                              "it (blendTolerance 0 here and on the step before)"});
        continue;
      }
      direction[k] = (line->p1 - line->p0) / length[k];
      continue;
    }
    const auto& path = std::get<PathSpec>(pieces[k]);
    if (path.closed || path.blend != BlendMethod::kPolynomial) {
      violations.push_back({names[k] + ".path", std::string("a blended path must be open and POLYNOMIAL-blended; this one is ") +
                                                    (path.closed ? "closed" : "TRAPEZOIDAL")});
      continue;
    }
    if (auto built = build_path(path); !built) {
      auto named = prefixed(std::move(built.error()), names[k] + ".path.");
      violations.insert(violations.end(), named.begin(), named.end());
      continue;
    }
    const Reading r{path.convention, path.unspecified, path.max_curvature};
    if (reading && (reading->convention != r.convention || reading->unspecified != r.unspecified)) {
      violations.push_back({names[k] + ".path", "the paths of one blended chain must share their derivative "
                                                "convention and their reading of unspecified constraints"});
      continue;
    }
    if (!reading) reading = r;
  }
  for (std::size_t j = 0; j + 1 < n; ++j) {
    if (std::holds_alternative<PathSpec>(pieces[j]) && std::holds_alternative<PathSpec>(pieces[j + 1])) {
      violations.push_back({names[j] + ".blendTolerance",
                            "a corner between two paths is not blended: give their key frames as one path (which "
                            "the engine joins as smoothly as the frames allow), or rest between them"});
    }
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  const Reading read = reading.value_or(Reading{});

  // The tangent either side of each corner and the corner's point.
  const auto tangent_out = [&](std::size_t k) {  // leaving the end of piece k
    if (std::holds_alternative<BlendLine>(pieces[k])) return direction[k];
    return Vector3d(last_frame(std::get<PathSpec>(pieces[k])).T_W.normalized());
  };
  const auto tangent_in = [&](std::size_t k) {  // entering the start of piece k
    if (std::holds_alternative<BlendLine>(pieces[k])) return direction[k];
    return Vector3d(first_frame(std::get<PathSpec>(pieces[k])).T_W.normalized());
  };
  const auto corner_point = [&](std::size_t j) {
    if (const auto* line = std::get_if<BlendLine>(&pieces[j])) return line->p1;
    return Vector3d(last_frame(std::get<PathSpec>(pieces[j])).p_W);
  };

  // The cut of each corner from its lone blend.
  std::vector<CornerBlend> corners(n - 1);
  for (std::size_t j = 0; j + 1 < n; ++j) {
    CornerBlend& c = corners[j];
    c.after = j;
    c.tolerance = tolerances[j];
    const Vector3d d_in = tangent_out(j), d_out = tangent_in(j + 1);
    c.corner = std::acos(std::clamp(d_in.dot(d_out), -1.0, 1.0));
    if (c.corner > kMaxBlendedCorner) {
      violations.push_back({names[j] + ".blendTolerance",
                            "the corner after this step turns by " + number(c.corner * 180.0 / 3.14159265358979323846, 4) +
                                " degrees, more than " + number(kMaxBlendedCorner * 180.0 / 3.14159265358979323846, 4) +
                                " degrees: a blend within a tolerance cannot round it; rest there (blendTolerance 0)"});
      continue;
    }
    const bool line_in = std::holds_alternative<BlendLine>(pieces[j]);
    const bool line_out = std::holds_alternative<BlendLine>(pieces[j + 1]);
    const Vector3d B = corner_point(j);
    if (line_in && line_out) {
      const double unit = lone_deviation(line_frame(B - d_in, d_in, false), line_frame(B + d_out, d_out, false), read,
                                         {B - d_in, B, B + d_out});
      const double cap = kMaxCutShare * std::min(length[j], length[j + 1]);
      const double l = unit > 0.0 ? std::min(c.tolerance / unit, cap) : cap;
      c.cut_before = c.cut_after = l;
      continue;
    }
    // Next to a path: bisection on the line's cut.
    const double cap = kMaxCutShare * length[line_in ? j : j + 1];
    const auto deviation = [&](double l) {
      if (line_in) {
        const KeyFrame E = geometric_copy(first_frame(std::get<PathSpec>(pieces[j + 1])));
        return lone_deviation(line_frame(B - l * d_in, d_in, false), E, read, {B - l * d_in, B});
      }
      const KeyFrame E = geometric_copy(last_frame(std::get<PathSpec>(pieces[j])));
      return lone_deviation(E, line_frame(B + l * d_out, d_out, false), read, {B, B + l * d_out});
    };
    double l = cap;
    if (!(deviation(cap) <= kBisectionMargin * c.tolerance)) {
      double lo = 0.0, hi = cap;
      for (int step = 0; step < kBisectionSteps; ++step) {
        const double mid = 0.5 * (lo + hi);
        (deviation(mid) <= kBisectionMargin * c.tolerance ? lo : hi) = mid;
      }
      l = lo;
    }
    if (!(l > 0.0)) {
      violations.push_back({names[j] + ".blendTolerance", "no blend of the corner after this step stays within " +
                                                              number(c.tolerance) + " m of it"});
      continue;
    }
    (line_in ? c.cut_before : c.cut_after) = l;
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));

  // The chain as one path; every blend measured on it, and its cut shrunk where the
  // neighbouring path's coupling moved it beyond its tolerance.
  BlendedChain chain;
  for (int round = 0; round < kRefinementRounds; ++round) {
    std::vector<KeyFrame> frames;
    std::vector<std::size_t> arriving;  // per frame after the first: the piece of the segment that arrives
    std::vector<std::size_t> blend_end(n - 1, 0);  // per corner: the frame its blend arrives at
    const auto add = [&](KeyFrame f, std::size_t piece) {
      if (!frames.empty()) arriving.push_back(piece);
      frames.push_back(std::move(f));
    };
    for (std::size_t k = 0; k < n; ++k) {
      const bool blended_in = k > 0, blended_out = k + 1 < n;
      if (const auto* line = std::get_if<BlendLine>(&pieces[k])) {
        const Vector3d S = blended_in ? Vector3d(line->p0 + corners[k - 1].cut_after * direction[k]) : line->p0;
        const Vector3d E = blended_out ? Vector3d(line->p1 - corners[k].cut_before * direction[k]) : line->p1;
        KeyFrame start = line_frame(S, direction[k], blended_in);
        // The line's whole turn on its straight part, eased: the blends either side hold.
        start.orientation_mode = OrientationMode::kCustom;
        start.orientation = line->q1.normalized();
        start.ease_orientation = true;
        if (blended_in) blend_end[k - 1] = frames.size();
        add(std::move(start), k - 1 + (blended_in ? 0 : 1));
        add(line_frame(E, direction[k], blended_out), k);
        continue;
      }
      PathSpec path = std::get<PathSpec>(pieces[k]);
      for (std::size_t i = 0; i < path.frames.size(); ++i) {
        KeyFrame f = path.frames[i];
        if (i == 0 && blended_in) {
          // Its leaving scale as the path had it; its arriving side (the blend) takes the blend's chord.
          if (!f.leave_tangent_scale) f.leave_tangent_scale = f.tangent_scale;
          f.tangent_scale.reset();
          blend_end[k - 1] = frames.size();
        }
        if (i + 1 == path.frames.size() && blended_out) {
          f.leave_tangent_scale = corners[k].cut_after;  // the blend's chord, whatever the path's scale
          f.orientation_mode = OrientationMode::kFixed;  // the blend holds the path's end orientation
          f.orientation.reset();
          f.ease_orientation = false;
        }
        add(std::move(f), i == 0 ? (blended_in ? k - 1 : k) : k);
      }
    }
    // A line's start frame after a path's blend: the blend arrives at it.
    chain.spec = spec_of(std::move(frames), read);
    auto built = build_path(chain.spec);
    if (!built) {
      Violations v;
      for (const auto& e : built.error()) {
        v.push_back({names.front() + ".blendTolerance", "the blended chain does not build: " + e.field + ": " + e.description});
      }
      return tl::unexpected(std::move(v));
    }
    chain.segment_piece = arriving;
    bool within = true;
    for (std::size_t j = 0; j + 1 < n; ++j) {
      CornerBlend& c = corners[j];
      c.segment = blend_end[j] - 1;
      const Vector3d B = corner_point(j);
      std::vector<Vector3d> route;
      if (c.cut_before > 0.0) route.push_back(B - c.cut_before * tangent_out(j));
      route.push_back(B);
      if (c.cut_after > 0.0) route.push_back(B + c.cut_after * tangent_in(j + 1));
      c.deviation = deviation_from(*built, c.segment, route);
      if (c.deviation > c.tolerance) {
        within = false;
        const double shrink = std::clamp(kBisectionMargin * c.tolerance / c.deviation, 0.1, kBisectionMargin);
        c.cut_before *= shrink;
        c.cut_after *= shrink;
      }
    }
    if (within) {
      chain.corners = corners;
      return chain;
    }
  }
  Violations v;
  for (const auto& c : corners) {
    if (c.deviation > c.tolerance) {
      v.push_back({names[c.after] + ".blendTolerance", "the blend of the corner after this step stays " +
                                                           number(c.deviation, 6) + " m from it, beyond " +
                                                           number(c.tolerance) + " m, after " +
                                                           std::to_string(kRefinementRounds) + " rounds"});
    }
  }
  return tl::unexpected(std::move(v));
}

}  // namespace geotraj::core
