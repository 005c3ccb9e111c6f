// Thesis Appendix B.3: the path of Table B.1 and the breakpoints of Eqs. (B.10), (B.11) and
// (B.13), shared by the breakpoint optimiser's tests and its benchmark.
//
// Table B.1 gives kappa' = tau' = 0 at frame 2. The thesis blends it with a 4th-order
// trapezoid (ten breakpoints, B.10-B.13) whose 4th derivative is zero at both ends, which is
// what Table B.2's all-zero 4th-order row asks. geotraj blends a frame whose given
// constraints fix derivatives up to k with an order-(k + 1) trapezoid, so tau' is left out
// here (order 3 at frame 2, a 4th-order trapezoid): the 4th derivative is then zero there,
// as B.2 prints, and the curve still has tau' = 0 at frame 2 (the tests check it).
// Frames 1 and 3 give kappa = 0 only (thesis footnote 5: no torsion where kappa = 0).
// The printed 0.707 tangent is reproduced as in tests/core/golden (tangent scale |T|).
#pragma once

#include <cmath>
#include <vector>

#include "core/geometry/key_frame.hpp"

namespace geotraj::testing {

inline core::PathSpec table_b1_path() {
  core::PathSpec spec;
  spec.unspecified = core::UnspecifiedConstraints::kLowestDegree;  // Appendix B.3's order-4 trapezoids
  spec.convention = core::DerivativeConvention::kPerParameter;
  spec.blend = core::BlendMethod::kTrapezoidal;
  core::KeyFrame f1, f2, f3;
  f1.p_W = {0, 0, 0};
  f1.T_W = {1, 0, 0};
  f1.N_W = Eigen::Vector3d(0, 1, 0);
  f1.B_W = Eigen::Vector3d(0, 0, 1);
  f1.kappa = 0.0;
  f1.tangent_scale = 1.0;  // the thesis's |dp/du| = 1 where Table B.1 prints none
  f2.p_W = {2, 1, 1};
  f2.T_W = {0.0, 0.707, -0.707};
  f2.N_W = Eigen::Vector3d(-1, 0, 0);
  f2.B_W = Eigen::Vector3d(0.0, 0.707, 0.707);
  f2.kappa = 5.0;
  f2.kappa_d = 0.0;
  f2.tau = 1.0;
  f2.tangent_scale = 0.707 * std::sqrt(2.0);  // |printed T|
  f3.p_W = {1, 3, -1};
  f3.T_W = {0, 1, 0};
  f3.N_W = Eigen::Vector3d(-1, 0, 0);
  f3.B_W = Eigen::Vector3d(0, 0, 1);
  f3.kappa = 0.0;
  f3.tangent_scale = 1.0;
  spec.frames = {f1, f2, f3};
  return spec;
}

/// (B.10): uniform, u_k = k / 9.
inline const std::vector<double> kB10 = {0, 1.0 / 9, 2.0 / 9, 3.0 / 9, 4.0 / 9, 5.0 / 9, 6.0 / 9, 7.0 / 9, 8.0 / 9, 1};
/// (B.11): narrow ramps, hand-tuned to lower the peak parametric derivatives.
inline const std::vector<double> kB11 = {0, 0.02, 0.24, 0.26, 0.49, 0.51, 0.74, 0.76, 0.98, 1.00};
/// (B.13): staggered per axis on the second segment (printed on u in [1, 2]; local u here).
inline const std::vector<double> kB13x = {0, 0.02, 0.34, 0.36, 0.69, 0.71, 0.84, 0.86, 0.98, 1.00};
inline const std::vector<double> kB13y = {0, 0.02, 0.24, 0.26, 0.49, 0.51, 0.74, 0.86, 0.98, 1.00};
inline const std::vector<double> kB13z = {0, 0.02, 0.14, 0.16, 0.39, 0.41, 0.74, 0.86, 0.98, 1.00};

/// Table B.1 with B.11 on both segments.
inline core::PathSpec table_b1_with_b11() {
  auto spec = table_b1_path();
  core::SegmentBreakpoints s0, s1;
  s0.segment = 0;
  s0.all = kB11;
  s1.segment = 1;
  s1.all = kB11;
  spec.breakpoints = {s0, s1};
  return spec;
}

/// Table B.1 with B.11 on the first segment and B.13 on the second (where the thesis
/// staggers the axes to lower the torsion peak).
inline core::PathSpec table_b1_with_b13() {
  auto spec = table_b1_path();
  core::SegmentBreakpoints s0, s1;
  s0.segment = 0;
  s0.all = kB11;
  s1.segment = 1;
  s1.x = kB13x;
  s1.y = kB13y;
  s1.z = kB13z;
  spec.breakpoints = {s0, s1};
  return spec;
}

}  // namespace geotraj::testing
