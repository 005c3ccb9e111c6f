// Hostile input: random frame sets whose numbers are drawn from the values that break
// numerical code (NaN, infinities, signed zeros, the largest and smallest doubles, values
// just off the tolerances). Whatever comes in, build_path either names what is wrong or
// returns a path whose every reported number (lengths, achieved geometry, profile) is
// finite. Never a crash, a hang or a NaN. Count: GEOTRAJ_PROPERTY_CASES (default 1000).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "core/geometry/analysis.hpp"
#include "core/geometry/path.hpp"
#include "test_support.hpp"

namespace geotraj::test {
namespace {

using core::LocalGeometry;

int case_count() {
  const char* env = std::getenv("GEOTRAJ_PROPERTY_CASES");
  return env ? std::max(1, std::atoi(env)) : 1000;
}

class Hostile {
 public:
  explicit Hostile(std::uint32_t seed) : rng_(seed) {}

  // A plausible value of the field's sign, or (at the case's rate) a hostile one.
  double value(double lo, double hi) {
    if (std::bernoulli_distribution(nasty_rate_)(rng_)) return number();
    return std::uniform_real_distribution<double>(lo, hi)(rng_);
  }

  double number() {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    static constexpr double kNasty[] = {std::numeric_limits<double>::quiet_NaN(), kInf, -kInf, 0.0, -0.0,
                                        std::numeric_limits<double>::max(), -std::numeric_limits<double>::max(),
                                        std::numeric_limits<double>::min(), std::numeric_limits<double>::denorm_min(),
                                        1e-300, 1e300, 1e-9, 1e9, 1.0005, 0.9995, 1.002};
    std::uniform_int_distribution<int> pick(0, 3);
    if (pick(rng_) == 0) return kNasty[std::uniform_int_distribution<std::size_t>(0, std::size(kNasty) - 1)(rng_)];
    return std::uniform_real_distribution<double>(-2.0, 2.0)(rng_);
  }
  bool coin() { return std::bernoulli_distribution(0.5)(rng_); }
  Vector3d vector() { return {number(), number(), number()}; }
  Vector3d unit() {
    Vector3d v(std::normal_distribution<double>()(rng_), std::normal_distribution<double>()(rng_),
               std::normal_distribution<double>()(rng_));
    return v.normalized();
  }

  // Mostly plausible frames with a few hostile numbers, so that both outcomes occur.
  core::PathSpec spec() {
    static constexpr double kRates[] = {0.0, 0.02, 0.1, 0.5};
    nasty_rate_ = kRates[std::uniform_int_distribution<int>(0, 3)(rng_)];
    const auto nasty = [&] { return std::bernoulli_distribution(nasty_rate_)(rng_); };
    core::PathSpec spec;
    const int n = std::uniform_int_distribution<int>(nasty() ? 0 : 2, 5)(rng_);
    for (int i = 0; i < n; ++i) {
      core::KeyFrame f;
      f.p_W = nasty() ? vector() : Vector3d(unit() * 0.3 + Vector3d(0.4 * i, 0, 0));
      f.T_W = nasty() ? vector() : unit();
      if (nasty()) f.B_W = vector();
      // Mostly consistent: a normal with a curvature, higher orders only above a curvature.
      if (coin()) {
        f.kappa = value(0.0, 30.0);
        f.N_W = nasty() ? vector() : Vector3d(f.T_W.unitOrthogonal());
        if (coin()) f.kappa_d = value(-100.0, 100.0);
        if (coin()) f.tau = value(-100.0, 100.0);
        if (f.tau && coin()) f.tau_d = value(-1000.0, 1000.0);
      } else if (nasty()) {
        f.tau = number();
      }
      if (coin()) f.tangent_scale = value(0.05, 2.0);
      f.cusp = coin() && coin() && coin();
      f.inflection = coin() && coin() && coin();
      spec.frames.push_back(f);
    }
    spec.closed = coin();
    spec.blend = coin() ? core::BlendMethod::kPolynomial : core::BlendMethod::kTrapezoidal;
    spec.convention = coin() ? core::DerivativeConvention::kPerArcLength : core::DerivativeConvention::kPerParameter;
    if (nasty()) {
      core::SegmentBreakpoints bp;
      bp.segment = static_cast<std::uint32_t>(std::uniform_int_distribution<int>(0, 4)(rng_));
      for (int k = 0, m = std::uniform_int_distribution<int>(0, 12)(rng_); k < m; ++k) bp.all.push_back(number());
      spec.breakpoints.push_back(bp);
    }
    return spec;
  }

 private:
  std::mt19937 rng_;
  double nasty_rate_ = 0.0;
};

bool finite(const LocalGeometry& g) {
  return std::isfinite(g.speed) && g.T.allFinite() && std::isfinite(g.kappa) && g.N.allFinite() && g.B.allFinite() &&
         std::isfinite(g.tau) && std::isfinite(g.kappa_du) && std::isfinite(g.kappa_ds) && std::isfinite(g.tau_du) &&
         std::isfinite(g.tau_ds);
}

TEST(HostileInput, EitherNamedViolationsOrFiniteOutput) {
  const int cases = case_count();
  int accepted = 0;
  for (int c = 0; c < cases; ++c) {
    Hostile gen(static_cast<std::uint32_t>(9000 + c));
    const core::PathSpec spec = gen.spec();
    SCOPED_TRACE("case " + std::to_string(c) + ": " + describe(spec));
    if (std::getenv("GEOTRAJ_TRACE_CASES")) std::fprintf(stderr, "%s\n", describe(spec).c_str());
    const auto path = core::build_path(spec);
    if (!path) {
      ASSERT_FALSE(path.error().empty());
      for (const auto& v : path.error()) {
        EXPECT_FALSE(v.field.empty());
        EXPECT_FALSE(v.description.empty());
      }
      continue;
    }
    ++accepted;
    ASSERT_TRUE(std::isfinite(path->length())) << "arc length " << path->length();
    for (const auto& a : core::achieved_geometry(*path)) {
      ASSERT_TRUE(a.p_W.allFinite());
      if (a.approach) {
        ASSERT_TRUE(finite(*a.approach));
      }
      if (a.leave) {
        ASSERT_TRUE(finite(*a.leave));
      }
    }
    ASSERT_TRUE(std::isfinite(core::closed_loop_error(*path, core::achieved_geometry(*path)).max_error));
    for (const auto& pt : core::analyze(*path, 25)) {
      ASSERT_TRUE(std::isfinite(pt.s) && pt.p_W.allFinite() && finite(pt.geometry)) << "at u = " << pt.u;
    }
  }
  // The generator must exercise both outcomes to mean anything.
  EXPECT_GT(accepted, cases / 50) << "too few valid cases generated";
  EXPECT_LT(accepted, cases) << "no invalid case generated";
}

}  // namespace
}  // namespace geotraj::test
