// core::blend_chain: corners of lines (and of a line and a path) replaced by blends built by
// the geometry engine, checked on the built path independently of how the cuts were chosen:
// the distance of dense samples from the unblended route within the tolerance, the lines
// straight beyond the cuts, the curvature 0 on both sides of every cut, the cut scaling
// with the tolerance between lines, the 45 % cap, and the corners it refuses.
#include "core/planning/corner_blend.hpp"

#include <cmath>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/geometry/analysis.hpp"
#include "core/geometry/differential_geometry.hpp"
#include "core/geometry/path.hpp"

namespace geotraj::test {
namespace {

using Eigen::Vector3d;
using ::testing::HasSubstr;

core::BlendLine line(const Vector3d& a, const Vector3d& b) {
  core::BlendLine l;
  l.p0 = a;
  l.p1 = b;
  return l;
}

// The path of a chain, built.
core::Path built(const core::BlendedChain& chain) {
  auto path = core::build_path(chain.spec);
  EXPECT_TRUE(path) << (path ? "" : path.error().front().field + ": " + path.error().front().description);
  return std::move(*path);
}

TEST(CornerBlend, LinesKeepStraightAndTheBlendStaysWithinTheTolerance) {
  const Vector3d A(0, 0, 0), B(1, 0, 0), C(1, 0.8, 0.3), D(0.2, 1.2, 0.3);
  const std::vector<core::BlendPiece> pieces{line(A, B), line(B, C), line(C, D)};
  const std::vector<std::string> names{"s[0]", "s[1]", "s[2]"};
  for (const double tol : {0.001, 0.01, 0.05}) {
    SCOPED_TRACE("tolerance " + std::to_string(tol));
    auto chain = core::blend_chain(pieces, {tol, tol}, names);
    ASSERT_TRUE(chain) << chain.error().front().description;
    const core::Path path = built(*chain);
    ASSERT_EQ(path.segment_count(), 5u) << "line, blend, line, blend, line";
    EXPECT_THAT(chain->segment_piece, ::testing::ElementsAre(0u, 0u, 1u, 1u, 2u));
    ASSERT_EQ(chain->corners.size(), 2u);
    const Vector3d route[] = {A, B, C, D};
    for (std::size_t j = 0; j < 2; ++j) {
      const auto& c = chain->corners[j];
      EXPECT_EQ(c.segment, 2 * j + 1);
      EXPECT_LE(c.deviation, tol);
      // Independently: 4001 points of the blend against the two lines it replaces.
      const double d = core::deviation_from(path, c.segment, {route[j], route[j + 1], route[j + 2]}, 4000);
      EXPECT_LE(d, tol * (1 + 1e-9));
      EXPECT_GT(d, 0.9 * tol) << "the blend uses the room it is given (no cap here)";
      EXPECT_NEAR(c.cut_before, c.cut_after, 1e-15);
    }
    // The straight parts are straight: their curvature is zero everywhere.
    for (std::size_t seg : {0u, 2u, 4u}) {
      for (int k = 0; k <= 100; ++k) {
        core::Jet jet;
        core::evaluate(path.segments[seg], k / 100.0, 4, jet);
        EXPECT_LT(core::local_geometry(jet, path.p_uu_noise[seg]).kappa, 1e-9) << "segment " << seg;
      }
    }
    // G2 where a blend meets a line: curvature 0 on both sides of every cut frame.
    const auto achieved = core::achieved_geometry(path);
    for (std::size_t f = 1; f + 1 < achieved.size(); ++f) {
      ASSERT_TRUE(achieved[f].approach && achieved[f].leave);
      EXPECT_LT(achieved[f].approach->kappa, 1e-9) << "frame " << f;
      EXPECT_LT(achieved[f].leave->kappa, 1e-9) << "frame " << f;
    }
  }
  // Between lines a blend is a scaled copy: the cut is proportional to the tolerance.
  auto small = core::blend_chain(pieces, {0.001, 0.001}, names);
  auto large = core::blend_chain(pieces, {0.01, 0.01}, names);
  ASSERT_TRUE(small && large);
  EXPECT_NEAR(large->corners[0].cut_before / small->corners[0].cut_before, 10.0, 1e-9);
}

TEST(CornerBlend, ABlendTakesAtMostFortyFivePercentOfALine) {
  const Vector3d A(0, 0, 0), B(0.1, 0, 0), C(0.1, 1, 0);
  auto chain = core::blend_chain({line(A, B), line(B, C)}, {1.0}, {"s[0]", "s[1]"});
  ASSERT_TRUE(chain);
  EXPECT_NEAR(chain->corners[0].cut_before, 0.045, 1e-15);
  EXPECT_NEAR(chain->corners[0].cut_after, 0.045, 1e-15);
  EXPECT_LT(chain->corners[0].deviation, 1.0);
}

TEST(CornerBlend, ALineBlendsIntoAPathThatKeepsItsFrames) {
  core::PathSpec bend;
  core::KeyFrame a, b;
  a.p_W = Vector3d(1, 0, 0);
  a.T_W = Vector3d(0, 1, 0);
  b.p_W = Vector3d(1.5, 0.5, 0);
  b.T_W = Vector3d(1, 0, 0);
  bend.frames = {a, b};
  auto chain = core::blend_chain({line(Vector3d::Zero(), Vector3d(1, 0, 0)), bend}, {0.02}, {"s[0]", "s[1]"});
  ASSERT_TRUE(chain) << chain.error().front().description;
  const core::Path path = built(*chain);
  const auto& c = chain->corners[0];
  EXPECT_GT(c.cut_before, 0.0);
  EXPECT_EQ(c.cut_after, 0.0);
  EXPECT_LE(core::deviation_from(path, c.segment, {Vector3d(1 - c.cut_before, 0, 0), Vector3d(1, 0, 0)}, 4000), 0.02);
  // The path's frames are there, with their tangents.
  const auto achieved = core::achieved_geometry(path);
  ASSERT_EQ(achieved.size(), 4u);
  EXPECT_LT((achieved[2].leave->T - Vector3d(0, 1, 0)).norm(), 1e-9);
  EXPECT_LT((achieved[3].approach->T - Vector3d(1, 0, 0)).norm(), 1e-9);
}

TEST(CornerBlend, CornersThatCannotBeBlendedAreNamed) {
  const std::vector<std::string> names{"s[0]", "s[1]"};
  {  // back on itself
    auto chain = core::blend_chain({line({0, 0, 0}, {1, 0, 0}), line({1, 0, 0}, {0, 0.01, 0})}, {0.01}, names);
    ASSERT_FALSE(chain);
    EXPECT_EQ(chain.error().front().field, "s[0].blendTolerance");
    EXPECT_THAT(chain.error().front().description, HasSubstr("more than 170 degrees"));
  }
  {  // a pure rotation
    auto chain = core::blend_chain({line({0, 0, 0}, {1, 0, 0}), line({1, 0, 0}, {1, 0, 0})}, {0.01}, names);
    ASSERT_FALSE(chain);
    EXPECT_EQ(chain.error().front().field, "s[1].blendTolerance");
  }
  {  // two paths
    core::PathSpec p;
    core::KeyFrame a, b;
    a.T_W = b.T_W = Vector3d::UnitX();
    b.p_W = Vector3d(1, 0, 0);
    p.frames = {a, b};
    core::PathSpec q = p;
    q.frames[0].p_W = Vector3d(1, 0, 0);
    q.frames[1].p_W = Vector3d(2, 0, 0);
    auto chain = core::blend_chain({p, q}, {0.01}, names);
    ASSERT_FALSE(chain);
    EXPECT_THAT(chain.error().front().description, HasSubstr("two paths"));
  }
}

}  // namespace
}  // namespace geotraj::test
