// Random closed-loop properties. Each case is a valid random PathSpec: 2-6 key frames of
// order 1 m, open or closed, a random subset of the constraints given (kappa, kappa', tau,
// tau', tangent scale, normal, binormal), cusps and inflections where they are allowed,
// both derivative conventions, both blends (the trapezoid with the default breakpoints
// (B.10) or random valid ones). Fixed seed; GEOTRAJ_PROPERTY_CASES sets the count (default
// 1000). A failure prints the case as JSON-like text (17 digits) to replay it.
//
// Properties:
//  - the curve has the geometry that was asked: closed_loop_error < 1e-9 (met by the
//    polynomial blend; the trapezoid misses it on a few cases today, see below);
//  - analyze's Frenet frames are orthonormal and right-handed (B = T x N), to 1e-9;
//  - arc length is additive (s at the end = the sum of the segment lengths, and
//    arc_length_at at each frame = the cumulative length) and s increases monotonically
//    along analyze's points, where it agrees with arc_length_at.
#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/geometry/analysis.hpp"
#include "core/geometry/arc_length.hpp"
#include "core/geometry/path.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::BlendMethod;
using core::DerivativeConvention;

class CaseGenerator {
 public:
  explicit CaseGenerator(std::uint64_t seed) : rng_(seed) {}

  core::PathSpec next() {
    core::PathSpec spec;
    const int count = uniform_int(2, 6);
    spec.closed = chance(0.3);
    spec.convention = chance(0.5) ? DerivativeConvention::kPerArcLength : DerivativeConvention::kPerParameter;
    spec.blend = chance(0.5) ? BlendMethod::kPolynomial : BlendMethod::kTrapezoidal;
    // Every reading of unspecified constraints, the default most often.
    const double r = uniform(0, 1);
    spec.unspecified = r < 0.5 ? core::UnspecifiedConstraints::kSmoothest
                               : (r < 0.75 ? core::UnspecifiedConstraints::kThesisZeros
                                           : core::UnspecifiedConstraints::kLowestDegree);
    Vector3d p(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
    for (int i = 0; i < count; ++i) {
      const bool both_sides = spec.closed || (i > 0 && i + 1 < count);
      spec.frames.push_back(frame(p, both_sides));
      // A lowest-degree segment cannot honour a normal without a curvature (its closed loop
      // reports the angle, tested in readings_test.cpp): none in those cases.
      auto& f = spec.frames.back();
      if (spec.unspecified == core::UnspecifiedConstraints::kLowestDegree && !f.kappa) {
        f.N_W.reset();
        f.B_W.reset();
      }
      p += uniform(0.4, 1.5) * unit();
    }
    if (spec.blend == BlendMethod::kTrapezoidal) add_breakpoints(spec);
    return spec;
  }

 private:
  double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng_); }
  int uniform_int(int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng_); }
  bool chance(double p) { return uniform(0, 1) < p; }
  Vector3d unit() {
    std::normal_distribution<double> n;
    return Vector3d(n(rng_), n(rng_), n(rng_)).normalized();
  }

  core::KeyFrame frame(const Vector3d& p, bool both_sides) {
    core::KeyFrame f;
    f.p_W = p;
    const Vector3d T = unit();
    const Vector3d N = T.cross(unit()).normalized();
    // Within validate's 1e-3 of unit length sometimes: normalised by the validation.
    f.T_W = chance(0.2) ? Vector3d(T * uniform(0.9995, 1.0005)) : T;
    if (chance(0.3)) f.tangent_scale = uniform(0.3, 2.5);
    if (chance(0.75)) {
      f.kappa = chance(0.1) ? 0.0 : std::exp(uniform(std::log(0.2), std::log(5.0)));
      if (*f.kappa > 0.0) {
        if (chance(0.5)) f.tau = uniform(-5, 5);
        if (chance(0.4)) f.kappa_d = uniform(-10, 10);
        if (f.tau && chance(0.5)) f.tau_d = uniform(-20, 20);
      }
    }
    if ((f.kappa && *f.kappa > 0.0) || chance(0.3)) {
      f.N_W = N;
      if (chance(0.3)) f.B_W = T.cross(N);
    }
    if (both_sides && chance(0.15)) f.cusp = true;
    if (both_sides && f.kappa && chance(0.15)) f.inflection = true;
    return f;
  }

  // Highest derivative that a frame's constraints fix (the same on both sides).
  static int order(const core::KeyFrame& f) {
    if (!f.kappa) return 1;
    if (!f.tau && !f.kappa_d) return 2;
    return f.tau_d ? 4 : 3;
  }

  // 2n + 2 breakpoints: 0 and 1 at the ends, the first ramp at least 0.02 wide, sorted
  // uniform interior values with holds (u_{2j} - u_{2j-1}) of at least 0.01 so that no two
  // ramps coincide (which would make the level equations singular); sometimes an interior
  // ramp of zero width.
  std::vector<double> breakpoints(int n) {
    std::vector<double> u(2 * n + 2);
    for (auto& v : u) v = uniform(0.02, 0.98);
    std::sort(u.begin(), u.end());
    u.front() = 0.0;
    u.back() = 1.0;
    u[1] = std::max(u[1], 0.02);
    for (std::size_t k = 2; k + 1 < u.size(); ++k) u[k] = std::max(u[k], u[k - 1] + (k % 2 == 0 ? 0.01 : 0.0));
    if (n >= 2 && chance(0.2)) {
      const std::size_t j = static_cast<std::size_t>(uniform_int(2, n));  // ramp j: [u_{2j-2}, u_{2j-1}]
      u[2 * j - 1] = u[2 * j - 2];
    }
    for (auto& v : u) v = std::min(v, 1.0);
    return u;
  }

  void add_breakpoints(core::PathSpec& spec) {
    const std::size_t m = core::segment_count(spec.frames.size(), spec.closed);
    if (chance(0.5)) return;  // default uniform breakpoints (B.10) everywhere
    for (std::size_t s = 0; s < m; ++s) {
      if (!chance(0.7)) continue;  // default uniform breakpoints (B.10) on this segment
      const int n = spec.unspecified == core::UnspecifiedConstraints::kLowestDegree
                        ? core::trapezoid_order(order(spec.frames[s]), order(spec.frames[(s + 1) % spec.frames.size()]))
                        : core::trapezoid_order(4, 4);  // the other readings fix orders 1-4 everywhere
      core::SegmentBreakpoints bp;
      bp.segment = static_cast<std::uint32_t>(s);
      if (chance(0.5)) {
        bp.all = breakpoints(n);
      } else {
        bp.x = breakpoints(n);
        bp.y = breakpoints(n);
        bp.z = breakpoints(n);
      }
      spec.breakpoints.push_back(std::move(bp));
    }
  }

  std::mt19937_64 rng_;
};

/// The random cases, generated once for every test of this file.
const std::vector<core::PathSpec>& cases() {
  static const std::vector<core::PathSpec> all = [] {
    CaseGenerator gen(kPropertySeed);
    std::vector<core::PathSpec> v;
    const int n = property_case_count(1000);
    for (int i = 0; i < n; ++i) v.push_back(gen.next());
    return v;
  }();
  return all;
}

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(6);
  os << v;
  return os.str();
}

std::string replay(std::size_t index, const core::PathSpec& spec) {
  return "case " + std::to_string(index) + " (seed " + std::to_string(kPropertySeed) + "):\n" + describe(spec);
}

/// Every case built once (build_path, with its arc lengths, is the costly part).
const std::vector<core::Expected<core::Path>>& built() {
  static const std::vector<core::Expected<core::Path>> all = [] {
    std::vector<core::Expected<core::Path>> v;
    v.reserve(cases().size());
    for (const auto& spec : cases()) v.push_back(core::build_path(spec));
    return v;
  }();
  return all;
}

/// Hands every built case to `check`, which returns "" or what went wrong. Stops after 10
/// failing cases.
template <class Check>
void for_each_case(Check check) {
  int failures = 0;
  for (std::size_t i = 0; i < cases().size() && failures < 10; ++i) {
    const auto& spec = cases()[i];
    const auto& path = built()[i];
    if (!path) {
      std::string why;
      for (const auto& v : path.error()) why += "\n  " + v.field + ": " + v.description;
      ADD_FAILURE() << "a valid random case was rejected:" << why << "\n" << replay(i, spec);
      ++failures;
      continue;
    }
    const std::string problem = check(*path);
    if (!problem.empty()) {
      ADD_FAILURE() << problem << "\n" << replay(i, spec);
      ++failures;
    }
  }
}

TEST(ClosedLoopProperty, GeneratorCoversTheSpace) {
  int closed = 0, trapezoid = 0, custom_bp = 0, cusps = 0, inflections = 0, tau_d = 0, per_u = 0;
  for (const auto& s : cases()) {
    closed += s.closed;
    trapezoid += s.blend == BlendMethod::kTrapezoidal;
    custom_bp += !s.breakpoints.empty();
    per_u += s.convention == DerivativeConvention::kPerParameter;
    for (const auto& f : s.frames) {
      cusps += f.cusp;
      inflections += f.inflection;
      tau_d += f.tau_d.has_value();
    }
  }
  const int n = static_cast<int>(cases().size());
  if (n < 100) GTEST_SKIP() << "too few cases (" << n << ") to check the coverage";
  EXPECT_GT(closed, n / 10);
  EXPECT_GT(trapezoid, n / 4);
  EXPECT_GT(custom_bp, n / 10);
  EXPECT_GT(trapezoid - custom_bp, n / 10);
  EXPECT_GT(per_u, n / 4);
  EXPECT_GT(cusps, n / 20);
  EXPECT_GT(inflections, n / 20);
  EXPECT_GT(tau_d, n / 20);
}

bool is_trapezoid(const core::Path& path) { return path.spec.blend == BlendMethod::kTrapezoidal; }

std::string closed_loop_problem(const core::Path& path, double tol) {
  const auto err = core::closed_loop_error(path, core::achieved_geometry(path));
  if (err.max_error < tol) return {};
  return "closed-loop error " + fmt(err.max_error) + " at " + err.worst_field + " (tolerance " + fmt(tol) + ")";
}

TEST(ClosedLoopProperty, AchievedGeometryMatchesRequestPolynomial) {
  for_each_case([](const core::Path& path) -> std::string {
    return is_trapezoid(path) ? std::string() : closed_loop_problem(path, 1e-9);
  });
}

// Trapezoids (default (B.10) and random valid breakpoints) at the target 1e-9. Regression: before the fix below, 2 of the default 1000 cases miss it (case 119: 6.5e-9 at
// frames[0].approach.torsionDerivative; case 299: 1.4e-9 at frames[5].approach.torsionDerivative),
// always on an approach side (u = 1). Narrow ramps make the ramp heights large (2.6e6 on case
// 119's last segment); evaluate() sums them up to u = 1, so the end state carries their
// cancellation (1.4e-10 there; the leaving side, u = 0, is exact), and tau' divides it by
// |p' x p''|^2 (kappa = 0.28 there). Over 20000 cases the worst is 9.9e-9 with random
// breakpoints and 3.5e-9 with the default ones (5 of 5369 miss 1e-9; GEOTRAJ_PROPERTY_CASES
// = 5000 reaches one). Fixed by: evaluate the trapezoid from the nearer end (see
// Regimes.LargeCurvatureAndTorsionTrapezoid); with it the worst of 20000 cases is 2.2e-13.
TEST(ClosedLoopProperty, AchievedGeometryMatchesRequestTrapezoid) {
  for_each_case([](const core::Path& path) -> std::string {
    return is_trapezoid(path) ? closed_loop_problem(path, 1e-9) : std::string();
  });
}

// Samples per segment for analyze.
constexpr std::size_t kSamplesPerSegment = 40;

TEST(ClosedLoopProperty, FrenetFramesOrthonormalAndRightHanded) {
  for_each_case([](const core::Path& path) -> std::string {
    for (const auto& pt : core::analyze(path, kSamplesPerSegment * path.segment_count() + 1)) {
      const auto& g = pt.geometry;
      const std::string at = "at u = " + fmt(pt.u) + ": ";
      if (!g.regular) continue;
      if (std::abs(g.T.norm() - 1) > 1e-12) return at + "|T| = " + fmt(g.T.norm());
      if (!g.has_normal) continue;
      const double worst = std::max({std::abs(g.N.norm() - 1), std::abs(g.B.norm() - 1), std::abs(g.T.dot(g.N)),
                                     std::abs(g.T.dot(g.B)), std::abs(g.N.dot(g.B)), (g.B - g.T.cross(g.N)).norm()});
      if (worst > 1e-9) {
        std::ostringstream os;
        os << at << "Frenet frame off by " << worst << ": T = " << g.T.transpose() << ", N = " << g.N.transpose()
           << ", B = " << g.B.transpose();
        return os.str();
      }
    }
    return {};
  });
}

TEST(ClosedLoopProperty, ArcLengthAdditiveAndMonotone) {
  for_each_case([](const core::Path& path) -> std::string {
    const double L = path.length();
    double sum = 0.0;
    for (std::size_t i = 0; i < path.segment_count(); ++i) {
      const double at_frame = core::arc_length_at(path, static_cast<double>(i));
      if (std::abs(at_frame - sum) > 1e-12 * L)
        return "arc_length_at(" + std::to_string(i) + ") = " + fmt(at_frame) + " != " + fmt(sum);
      if (!(path.segment_lengths[i] > 0.0)) return "segment " + std::to_string(i) + " has no length";
      sum += path.segment_lengths[i];
    }
    if (std::abs(L - sum) > 1e-12 * L) return "length " + fmt(L) + " != sum of segments " + fmt(sum);
    if (std::abs(core::arc_length_at(path, path.u_max()) - L) > 1e-12 * L) return "arc_length_at(M) != length";
    const auto pts = core::analyze(path, kSamplesPerSegment * path.segment_count() + 1);
    if (pts.front().s != 0.0) return "s(0) = " + fmt(pts.front().s);
    if (pts.back().s != L) return "s(M) = " + fmt(pts.back().s) + " != length";
    for (std::size_t i = 1; i < pts.size(); ++i) {
      if (!(pts[i].s >= pts[i - 1].s))
        return "s decreases at u = " + fmt(pts[i].u) + ": " + fmt(pts[i - 1].s) + " -> " + fmt(pts[i].s);
    }
    return {};
  });
}

// analyze's s (a sum of short integrals) against arc_length_at (one integral from the
// segment's start), both meant to 1e-12 relative; checked to 1e-11 of the length. (A case
// of an earlier generator missed it: see ArcLength.Gk15ErrorEstimateCanBeFooled.)
TEST(ClosedLoopProperty, ArcLengthAtAgreesWithAnalyze) {
  for_each_case([](const core::Path& path) -> std::string {
    const double L = path.length();
    const auto pts = core::analyze(path, kSamplesPerSegment * path.segment_count() + 1);
    for (std::size_t i = 0; i < pts.size(); i += 4) {  // every 4th point: each integral starts at the segment's start
      const auto& pt = pts[i];
      const double direct = core::arc_length_at(path, pt.u);
      if (std::abs(pt.s - direct) > 1e-11 * L)
        return "analyze's s = " + fmt(pt.s) + " at u = " + fmt(pt.u) + " differs from arc_length_at = " + fmt(direct) +
               " by " + fmt(pt.s - direct) + " (length " + fmt(L) + ")";
    }
    return {};
  });
}

}  // namespace
}  // namespace geotraj::test
