// Paths of pieces (core/geometry/pieces.hpp): the shapes asked for are the shapes built
// (helices of many radii and pitches, arcs, clothoids), measured on the built path's own
// jets; seams straight and round outside their transitions and within the tolerance inside;
// key frames met from the state a piece ends in; errors named by field.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "core/geometry/arc_length.hpp"
#include "core/geometry/differential_geometry.hpp"
#include "core/geometry/path.hpp"
#include "core/geometry/pieces.hpp"

namespace geotraj::core {
namespace {

using Eigen::Vector3d;
constexpr double kPi = std::numbers::pi;

KeyFrame start_frame(Vector3d p = Vector3d::Zero(), Vector3d T = Vector3d::UnitX(),
                     std::optional<Vector3d> N = Vector3d::UnitY()) {
  KeyFrame f;
  f.p_W = p;
  f.T_W = T;
  f.N_W = N;
  return f;
}

PathPiece line(double length) {
  PathPiece p;
  p.shape = PieceShape::kLine;
  p.length_m = length;
  return p;
}
PathPiece arc(double length, double radius) {
  PathPiece p = line(length);
  p.shape = PieceShape::kArc;
  p.radius = radius;
  return p;
}
PathPiece helix(double length, double radius, double pitch) {
  PathPiece p = arc(length, radius);
  p.shape = PieceShape::kHelix;
  p.pitch = pitch;
  return p;
}
PathPiece clothoid(double length, double end_curvature) {
  PathPiece p = line(length);
  p.shape = PieceShape::kClothoid;
  p.end_curvature = end_curvature;
  return p;
}
PathPiece to(const KeyFrame& k) {
  PathPiece p;
  p.shape = PieceShape::kTo;
  p.to = k;
  return p;
}

PathSpec pieces_spec(std::vector<PathPiece> pieces, std::optional<double> tolerance = std::nullopt,
                     KeyFrame start = start_frame()) {
  PathSpec spec;
  spec.start = start;
  spec.pieces = std::move(pieces);
  spec.transition_tolerance = tolerance;
  return spec;
}

// The point and the Frenet apparatus at arc length s of the path.
struct Point {
  Vector3d p;
  LocalGeometry g;
};
Point at_s(const Path& path, double s) {
  const double u = parameter_at(path, s);
  const auto [i, ul] = locate(path, u);
  Jet jet;
  evaluate(path.segments[i], ul, kMaxJetOrder, jet);
  return {jet[0], local_geometry(jet, path.p_uu_noise[i])};
}

// The weld seam in the plane z = 0: a line along x from the origin, a quarter arc of radius
// r turning left (+y), a line along y.
struct Seam {
  double a = 0.2, r = 0.05, b = 0.2;
  Vector3d centre() const { return {a, r, 0.0}; }
  // Distance from q to the programmed seam [m].
  double distance(const Vector3d& q) const {
    double d = std::hypot(std::max({0.0, q.x() - a, -q.x()}), q.y(), q.z());  // the first line
    const Vector3d e(a + r, r, 0.0);
    d = std::min(d, std::hypot(q.x() - e.x(), std::max({0.0, q.y() - e.y() - b, e.y() - q.y()}), q.z()));
    const Vector3d c = q - centre();
    if (c.x() >= 0.0 && c.y() <= 0.0) d = std::min(d, std::hypot(std::hypot(c.x(), c.y()) - r, c.z()));
    return d;
  }
  std::vector<PathPiece> pieces() const { return {line(a), arc(0.5 * kPi * r, r), line(b)}; }
};

TEST(Pieces, HelicesOfManyRadiiAndPitchesAreTheirClosedForms) {
  for (const double r : {0.01, 0.05, 0.3}) {
    for (const double pitch : {-0.05, 0.0, 0.02, 0.4}) {
      const double c = pitch / (2 * kPi);
      const double turns = 3.5;
      const double length = turns * 2 * kPi * std::hypot(r, c);
      auto path = build_path(pieces_spec({helix(length, r, pitch)}));
      ASSERT_TRUE(path) << path.error().front().field << ": " << path.error().front().description;
      ASSERT_EQ(path->segment_count(), 1u);
      EXPECT_NEAR(path->length(), length, 1e-12 * length);
      // The axis: along the Darboux vector (tau T + kappa B) through p0 + r N at the start.
      const double kappa = r / (r * r + c * c), tau = c / (r * r + c * c);
      const Vector3d axis = (tau * Vector3d::UnitX() + kappa * Vector3d::UnitZ()).normalized();
      const Vector3d centre = Vector3d::Zero() + r * Vector3d::UnitY();
      for (int k = 0; k <= 400; ++k) {
        const double s = length * k / 400.0;
        const Point q = at_s(*path, s);
        const Vector3d d = q.p - centre;
        const Vector3d radial = d - d.dot(axis) * axis;
        ASSERT_NEAR(radial.norm(), r, 1e-12) << "r " << r << " pitch " << pitch << " s " << s;
        // The rise: pitch per turn, the turn measured as the arc length over one turn's.
        ASSERT_NEAR(d.dot(axis), c * s / std::hypot(r, c), 1e-12);
        ASSERT_NEAR(q.g.kappa, kappa, 1e-9 * kappa);
        ASSERT_NEAR(q.g.tau, tau, 1e-9 * std::max(1.0, std::abs(tau)));
      }
      const RadiusPitch back = helix_radius_pitch(kappa, tau);  // (4.20-4.21)
      EXPECT_NEAR(back.radius, r, 1e-14);
      EXPECT_NEAR(back.pitch, pitch, 1e-14);
    }
  }
}

TEST(Pieces, AClothoidsCurvatureIsLinearInArcLength) {
  // From the arc's curvature 20 1/m down to 5 1/m over 0.1 m: the first derivative
  // continuous where it starts (G2 at the arc), curvature linear throughout.
  auto path = build_path(pieces_spec({arc(0.05, 0.05), clothoid(0.1, 5.0)}));
  ASSERT_TRUE(path);
  ASSERT_EQ(path->segment_count(), 2u);
  EXPECT_FALSE(path->spec.frames[1].stop) << "the clothoid starts with the arc's curvature";
  for (int k = 0; k <= 200; ++k) {
    const double s = 0.1 * k / 200.0;
    const Point q = at_s(*path, 0.05 + s);
    ASSERT_NEAR(q.g.kappa, 20.0 + (5.0 - 20.0) * s / 0.1, 1e-8) << s;
    ASSERT_NEAR(q.g.kappa_ds, -150.0, 1e-6) << s;
    ASSERT_NEAR(q.p.z(), 0.0, 1e-15);  // planar
  }
}

TEST(Pieces, ASeamWithoutToleranceIsExactAndRestsWhereTheCurvatureJumps) {
  const Seam seam;
  auto path = build_path(pieces_spec(seam.pieces()));
  ASSERT_TRUE(path);
  ASSERT_EQ(path->segment_count(), 3u);
  EXPECT_TRUE(path->spec.frames[1].stop);
  EXPECT_TRUE(path->spec.frames[2].stop);
  EXPECT_NEAR(path->length(), seam.a + 0.5 * kPi * seam.r + seam.b, 1e-15);
  for (int k = 0; k <= 1000; ++k) {
    const Point q = at_s(*path, path->length() * k / 1000.0);
    ASSERT_LE(seam.distance(q.p), 1e-15) << k;
  }
  const Point end = at_s(*path, path->length());
  EXPECT_LE((end.p - Vector3d(seam.a + seam.r, seam.r + seam.b, 0.0)).norm(), 1e-15);
  EXPECT_LE((end.g.T - Vector3d::UnitY()).norm(), 1e-15);
}

TEST(Pieces, ASeamsTransitionsStayWithinTheToleranceAndKeepItG4) {
  const Seam seam;
  for (const double tolerance : {1e-3, 1e-4, 1e-6}) {
    auto path = build_path(pieces_spec(seam.pieces(), tolerance));
    ASSERT_TRUE(path);
    ASSERT_EQ(path->segment_count(), 5u);  // line, transition, arc, transition, line
    ASSERT_EQ(path->origins.size(), 5u);
    EXPECT_EQ(path->origins[1].kind, SegmentKind::kTransition);
    EXPECT_EQ(path->origins[2].kind, SegmentKind::kPiece);
    EXPECT_EQ(path->origins[2].piece, 1u);
    for (const auto& f : path->spec.frames) EXPECT_FALSE(f.stop);
    // Outside the transitions: straight and round to rounding; inside: within tolerance.
    double worst_inside = 0.0;
    for (std::size_t i = 0; i < path->segment_count(); ++i) {
      for (int k = 0; k <= 400; ++k) {
        Jet jet;
        evaluate(path->segments[i], k / 400.0, 2, jet);
        const double d = seam.distance(jet[0]);
        if (path->origins[i].kind == SegmentKind::kPiece) {
          ASSERT_LE(d, 1e-15) << "segment " << i;
        } else {
          worst_inside = std::max(worst_inside, d);
        }
      }
    }
    EXPECT_LE(worst_inside, tolerance);
    // As large as the tolerance allows, or as a third of the arc (what it keeps of its exact shape).
    const auto& kept = std::get<NaturalSegment>(path->segments[2]);
    const bool capped = std::abs(kept.s0 - kTransitionShare * kept.curve->length()) <= 1e-12;
    if (!capped) {
      EXPECT_GE(worst_inside, 0.5 * tolerance) << "the transition is as large as the tolerance allows";
    }
    EXPECT_GE(kept.length(), kTransitionShare * kept.curve->length() - 1e-12);
    EXPECT_EQ(capped, tolerance == 1e-3) << tolerance;
    // G4 at every join: the jets in s on both sides agree (curvature, torsion and their
    // derivatives continuous; the tool's acceleration and jerk continuous).
    for (std::size_t k = 1; k < path->segment_count(); ++k) {
      const LocalGeometry in = local_geometry([&] {
        Jet j;
        evaluate(path->segments[k - 1], 1.0, kMaxJetOrder, j);
        return j;
      }());
      const LocalGeometry out = local_geometry([&] {
        Jet j;
        evaluate(path->segments[k], 0.0, kMaxJetOrder, j);
        return j;
      }());
      EXPECT_NEAR(in.kappa, out.kappa, 1e-7 * std::max(1.0, out.kappa)) << "join " << k;
      EXPECT_NEAR(in.kappa_ds, out.kappa_ds, 1e-5 * std::max(1.0, std::abs(out.kappa_ds))) << "join " << k;
      EXPECT_LE((in.T - out.T).norm(), 1e-12) << "join " << k;
    }
  }
}

TEST(Pieces, AHelixAfterALineTransitionsIntoItsTorsionToo) {
  // A dispensing path: approach along x, then 5 turns of a helix (r 0.05 m, pitch 0.02 m).
  const double r = 0.05, pitch = 0.02, c = pitch / (2 * kPi);
  const double turn = 2 * kPi * std::hypot(r, c);
  auto path = build_path(pieces_spec({line(0.1), helix(5 * turn, r, pitch), line(0.1)}, 1e-4));
  ASSERT_TRUE(path);
  ASSERT_EQ(path->segment_count(), 5u);
  const double kappa = r / (r * r + c * c), tau = c / (r * r + c * c);
  const auto& helix_part = std::get<NaturalSegment>(path->segments[2]);
  for (int k = 0; k <= 100; ++k) {
    Jet jet;
    evaluate(path->segments[2], k / 100.0, kMaxJetOrder, jet);
    const LocalGeometry g = local_geometry(jet);
    ASSERT_NEAR(g.kappa, kappa, 1e-9 * kappa);
    ASSERT_NEAR(g.tau, tau, 1e-9 * tau);
  }
  EXPECT_GT(helix_part.s0, 0.0);
  // The transition meets the helix's torsion where it enters it (G4).
  Jet j;
  evaluate(path->segments[1], 1.0, kMaxJetOrder, j);
  EXPECT_NEAR(local_geometry(j).tau, tau, 1e-6 * tau);
}

TEST(Pieces, AKeyFrameAfterAPieceIsBlendedFromThePiecesFullState) {
  // An arc, then a blend to a key frame, then an arc again: the frame met, the curvature
  // continuous on both sides of the blend (G4 from the arc's end state; the key frame takes
  // the next arc's curvature).
  KeyFrame k;
  k.p_W = Vector3d(0.3, 0.2, 0.05);
  k.T_W = Vector3d(0.0, 1.0, 0.0);
  k.N_W = Vector3d(-1.0, 0.0, 0.0);
  auto path = build_path(pieces_spec({arc(0.1, 0.2), to(k), arc(0.1, 0.1)}));
  ASSERT_TRUE(path) << path.error().front().field << ": " << path.error().front().description;
  ASSERT_EQ(path->segment_count(), 3u);
  EXPECT_EQ(path->origins[1].kind, SegmentKind::kBlend);
  EXPECT_EQ(path->frame_fields[2], "pieces[1].to");
  Jet a, b;
  evaluate(path->segments[1], 1.0, kMaxJetOrder, a);
  EXPECT_LE((a[0] - k.p_W).norm(), 1e-12);
  for (std::size_t join = 1; join <= 2; ++join) {
    evaluate(path->segments[join - 1], 1.0, kMaxJetOrder, a);
    evaluate(path->segments[join], 0.0, kMaxJetOrder, b);
    const LocalGeometry in = local_geometry(a), out = local_geometry(b);
    EXPECT_NEAR(in.kappa, out.kappa, 1e-9 * out.kappa) << join;
    EXPECT_NEAR(in.tau, out.tau, 1e-9) << join;
    EXPECT_LE((in.N - out.N).norm(), 1e-9) << join;
    EXPECT_FALSE(path->spec.frames[join].stop) << join;
  }
  EXPECT_NEAR(local_geometry(b).kappa, 10.0, 1e-12);
}

TEST(Pieces, AKeyFrameThatDisagreesWithTheNextPieceIsARest) {
  KeyFrame k;
  k.p_W = Vector3d(0.3, 0.0, 0.0);
  k.T_W = Vector3d::UnitX();
  k.N_W = Vector3d::UnitY();
  k.kappa = 0.0;
  auto path = build_path(pieces_spec({line(0.1), to(k), arc(0.1, 0.1)}));
  ASSERT_TRUE(path);
  EXPECT_TRUE(path->spec.frames[2].stop);
}

std::string errors(const Expected<Path>& path) {
  std::string out;
  if (path) return out;
  for (const auto& v : path.error()) out += v.field + ": " + v.description + "\n";
  return out;
}

TEST(Pieces, BadPiecesAreRefusedByField) {
  EXPECT_NE(errors(build_path(pieces_spec({line(0.1), arc(0.1, -1.0)}))).find("pieces[1].radius: must be a radius"),
            std::string::npos);
  EXPECT_NE(errors(build_path(pieces_spec({line(0.0)}))).find("pieces[0].lengthM"), std::string::npos);
  EXPECT_NE(errors(build_path(pieces_spec({line(std::nan(""))}))).find("pieces[0].lengthM"), std::string::npos);
  EXPECT_NE(errors(build_path(pieces_spec({arc(0.1, 0.1)}, std::nullopt, start_frame(Vector3d::Zero(),
                                                                                      Vector3d::UnitX(), std::nullopt))))
                .find("start.normal: is required: pieces[0] bends"),
            std::string::npos);
  EXPECT_NE(errors(build_path(pieces_spec({line(0.1)}, -1.0))).find("transitionTolerance"), std::string::npos);
  PathPiece h = helix(0.1, 0.05, std::numeric_limits<double>::infinity());
  EXPECT_NE(errors(build_path(pieces_spec({h}))).find("pieces[0].pitch"), std::string::npos);
  PathPiece prof = line(0.1);
  prof.shape = PieceShape::kProfile;
  EXPECT_NE(errors(build_path(pieces_spec({prof}))).find("pieces[0].curvature"), std::string::npos);
  prof.curvature = {1.0, std::nan("")};
  EXPECT_NE(errors(build_path(pieces_spec({prof}))).find("pieces[0].curvature"), std::string::npos);
  KeyFrame k;
  k.p_W = Vector3d(1, 0, 0);
  k.T_W = Vector3d(0.5, 0, 0);  // not unit
  PathPiece t = to(k);
  EXPECT_NE(errors(build_path(pieces_spec({line(0.1), t}))).find("pieces[1].to.tangent"), std::string::npos);
  t.to.T_W = Vector3d::UnitX();
  t.length_m = 1.0;
  EXPECT_NE(errors(build_path(pieces_spec({line(0.1), t}))).find("pieces[1].lengthM"), std::string::npos);
  PathSpec both = pieces_spec({line(0.1)});
  both.frames = {start_frame(), start_frame(Vector3d(1, 0, 0))};
  EXPECT_NE(errors(build_path(both)).find("frames: a path is either"), std::string::npos);
  PathSpec no_start = pieces_spec({line(0.1)});
  no_start.start.reset();
  EXPECT_NE(errors(build_path(no_start)).find("start: is required"), std::string::npos);
  PathSpec curved_start = pieces_spec({line(0.1)});
  curved_start.start->kappa = 3.0;
  EXPECT_NE(errors(build_path(curved_start)).find("start.curvature"), std::string::npos);
  // A helix that turns more than the integrator's bound is refused, not integrated for ever.
  EXPECT_FALSE(build_path(pieces_spec({helix(1e6, 1e-3, 0.0)})));
  // More transitions than a path may have: refused by the field that asks for them.
  std::vector<PathPiece> zigzag;
  for (int i = 0; i < 1002; ++i) zigzag.push_back(i % 2 ? arc(0.01, 1.0) : line(0.01));
  EXPECT_NE(errors(build_path(pieces_spec(zigzag, 1e-4))).find("transitionTolerance: asks for 1001 transitions"),
            std::string::npos);
  EXPECT_TRUE(build_path(pieces_spec(zigzag)));  // resting at each join instead
  // Many pieces that each take many steps: refused when the path's total would be too much.
  PathPiece wavy = line(10.0);
  wavy.shape = PieceShape::kProfile;
  wavy.curvature = {0.0, 0.0, 30.0};  // kappa = 30 s^2: up to 3000 1/m, 22,688 steps each
  auto many = build_path(pieces_spec(std::vector<PathPiece>(10, wavy)));
  ASSERT_FALSE(many);
  EXPECT_NE(errors(many).find("integration steps; one path may take at most"), std::string::npos) << errors(many);
}

}  // namespace
}  // namespace geotraj::core

namespace geotraj::core {
namespace {

// Random paths of pieces over wide ranges (lengths from a micrometre to 10 m, radii from
// 0.1 mm, curvatures of either sign, torsion, transitions or rests): each is refused with a
// named field or built, and a built one is finite everywhere, continuous where its segments
// meet, and as long as its segments.
TEST(Pieces, RandomPiecesAreBuiltFiniteOrRefusedByField) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const auto log_uniform = [&](double lo, double hi) { return lo * std::pow(hi / lo, uni(rng)); };
  int built = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<PathPiece> pieces;
    const int count = 1 + static_cast<int>(uni(rng) * 6);
    for (int i = 0; i < count; ++i) {
      const double length = log_uniform(1e-6, 10.0);
      switch (static_cast<int>(uni(rng) * 6)) {
        case 0: pieces.push_back(line(length)); break;
        case 1: pieces.push_back(arc(length, log_uniform(1e-4, 10.0))); break;
        case 2: pieces.push_back(helix(length, log_uniform(1e-4, 10.0), (uni(rng) - 0.5) * 2.0)); break;
        case 3: pieces.push_back(clothoid(length, (uni(rng) - 0.5) * 200.0)); break;
        case 4: {
          PathPiece p = line(length);
          p.shape = PieceShape::kProfile;
          p.curvature = {(uni(rng) - 0.5) * 40.0, (uni(rng) - 0.5) * 40.0};
          p.torsion = {(uni(rng) - 0.5) * 20.0};
          pieces.push_back(p);
          break;
        }
        default: {
          KeyFrame k;
          k.p_W = Vector3d(uni(rng), uni(rng), uni(rng));
          k.T_W = Vector3d(uni(rng) - 0.5, uni(rng) - 0.5, uni(rng) - 0.5).normalized();
          pieces.push_back(to(k));
          break;
        }
      }
    }
    const std::optional<double> tolerance =
        uni(rng) < 0.5 ? std::optional<double>(log_uniform(1e-8, 1e-2)) : std::nullopt;
    auto path = build_path(pieces_spec(pieces, tolerance));
    if (!path) {
      for (const auto& v : path.error()) {
        EXPECT_FALSE(v.field.empty()) << v.description;
        EXPECT_FALSE(v.description.empty()) << v.field;
      }
      continue;
    }
    ++built;
    ASSERT_TRUE(std::isfinite(path->length()));
    double sum = 0.0;
    for (std::size_t i = 0; i < path->segment_count(); ++i) {
      sum += path->segment_lengths[i];
      for (int k = 0; k <= 16; ++k) {
        Jet jet;
        evaluate(path->segments[i], k / 16.0, kMaxJetOrder, jet);
        for (const auto& d : jet) ASSERT_TRUE(d.allFinite()) << "trial " << trial << " segment " << i;
      }
      if (i == 0) continue;
      Jet a, b;
      evaluate(path->segments[i - 1], 1.0, 1, a);
      evaluate(path->segments[i], 0.0, 1, b);
      ASSERT_LE((a[0] - b[0]).norm(), 1e-9 * std::max(1.0, a[0].norm())) << "trial " << trial << " join " << i;
    }
    EXPECT_NEAR(sum, path->length(), 1e-12 * std::max(1.0, sum));
  }
  EXPECT_GT(built, 100) << "most random paths are valid";
}

}  // namespace
}  // namespace geotraj::core
