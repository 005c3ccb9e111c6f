// Shared by the golden tests of the Chapter 5 conversion (Tables 5.2-5.15, 7.9-7.20, B.2).
//
// The thesis's tables are in the PER_PARAMETER convention (kappa' and tau' per unit u).
//
// Printed 0.707: the thesis computed with the printed, unnormalised components, e.g.
// |(0, 0.707, -0.707)| = 0.99985, whereas geotraj normalises a tangent that is within 1e-3
// of unit length. Giving tangentScale = |printed tangent| together with the printed tangent
// makes dp/du = scale * T/|T| equal the printed vector exactly, and then the higher rows
// reproduce the thesis's digits (e.g. Table 5.7 d3 = (0, 7.0679, 7.0679), not 7.0711).
// See kPrinted707Scale.
//
// Cusps (geotraj's convention, thesis 5.6.2): the leaving side uses -T, so its own Frenet
// frame is (-T, N, -B), and each side meets the frame's kappa, tau, kappa' and tau' as
// measured along increasing u on that side. Inflections (5.6.1): the leaving side uses -N.
#pragma once

#include <cmath>
#include <initializer_list>
#include <string>
#include <vector>

#include "core/geometry/constraints.hpp"
#include "test_support.hpp"

namespace geotraj::test {

/// |(0.707, 0.707)|: the length of a printed "unit" vector with two 0.707 components.
inline const double kPrinted707Scale = 0.707 * std::sqrt(2.0);

/// convert_path in the PER_PARAMETER convention; fails the test on violations.
inline std::vector<core::FrameConstraints> convert_or_fail(core::PathSpec spec) {
  spec.convention = core::DerivativeConvention::kPerParameter;
  auto frames = core::convert_path(spec);
  if (!frames) {
    std::string all;
    for (const auto& v : frames.error()) all += "\n  " + v.field + ": " + v.description;
    ADD_FAILURE() << "convert_path rejected the spec:" << all << "\nspec: " << describe(spec);
    return std::vector<core::FrameConstraints>(spec.frames.size());
  }
  return *frames;
}

/// Converts `middle` as frame 1 of a three-frame open path, for the tables that print one
/// frame only. The neighbours only make the path valid; they do not enter frame 1's
/// conversion, which is local to the frame.
inline core::FrameConstraints convert_middle(const core::KeyFrame& middle) {
  const core::KeyFrame before = Frame(middle.p_W - Vector3d(1, 0, 0), Vector3d::UnitX());
  const core::KeyFrame after = Frame(middle.p_W + Vector3d(1, 0, 0), Vector3d::UnitX());
  return convert_or_fail(make_spec({before, middle, after}))[1];
}

/// The position and the printed derivative rows d^1p/du^1 .. d^kp/du^k of one side; `order`
/// is the highest derivative that the frame's given constraints fix. Rows that the thesis
/// prints above `order` (zeros at frames where only kappa = 0 is given) are free in geotraj
/// and not checked here (the trapezoid blend takes them as zero, like the thesis).
inline void ExpectSide(const core::SideConstraints& side, int order, std::initializer_list<PrintedVec> rows,
                       double min_tol = 0.0) {
  EXPECT_EQ(side.order, order);
  ASSERT_LE(static_cast<int>(rows.size()), order);
  int k = 0;
  for (const auto& row : rows) {
    EXPECT_TRUE(MatchesPrinted(side.d[k], row, min_tol)) << "d^" << k + 1 << "p/du^" << k + 1;
    ++k;
  }
}

inline void ExpectPosition(const core::FrameConstraints& frame, const PrintedVec& printed) {
  EXPECT_TRUE(MatchesPrinted(frame.p_W, printed)) << "position";
}

}  // namespace geotraj::test
