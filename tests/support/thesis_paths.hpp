// The thesis's demonstration geometry (Section 7.2): the key frames of Table 7.8 (with the
// erratum B1 = T1 x N1 = (0, 0, -1)), tangent scale 0.25 at every frame, and the curvature
// and torsion of Table 7.18 at frames 2 and 3 for paths A, B and C. The thesis's tables use
// derivatives per unit of u (DERIVATIVE_CONVENTION_PER_PARAMETER).
#pragma once

#include <stdexcept>

#include "core/geometry/key_frame.hpp"

namespace geotraj::testing {

inline core::KeyFrame demo_frame(const Eigen::Vector3d& p, const Eigen::Vector3d& T, const Eigen::Vector3d& N) {
  core::KeyFrame f;
  f.p_W = p;
  f.T_W = T;
  f.N_W = N;
  f.tangent_scale = 0.25;  // 7.2.3
  return f;
}

/// Path 'A', 'B' or 'C' of Table 7.18, under the reading `reading`. Under the thesis's and
/// the smoothest readings frames 2 and 3 also give kappa' = tau' = 0 (7.2.8: "kappa' and
/// tau' are also set to zero"). The lowest-degree reading keeps the frames as Table 7.18
/// prints them (the machinery tests of the optimisers and the timing were measured on it).
inline core::PathSpec thesis_demo_path(char which, core::BlendMethod blend = core::BlendMethod::kPolynomial,
                                       core::UnspecifiedConstraints reading = core::UnspecifiedConstraints::kLowestDegree) {
  struct Row {
    double kappa2, tau2, kappa3, tau3;
  };
  Row row{};
  switch (which) {
    case 'A': row = {5, -50, 1, 0}; break;
    case 'B': row = {10, -50, 10, 100}; break;
    case 'C': row = {20, -50, 10, -100}; break;
    default: throw std::invalid_argument("thesis_demo_path: path is A, B or C");
  }
  core::PathSpec spec;
  spec.convention = core::DerivativeConvention::kPerParameter;
  spec.blend = blend;
  auto f1 = demo_frame({0.106, 0.0, 0.975}, {1, 0, 0}, {0, -1, 0});  // home, tangent only
  auto f2 = demo_frame({0.4, 0.15, 0.5}, {0, -1, 0}, {0, 0, -1});    // on the sphere
  f2.kappa = row.kappa2;
  f2.tau = row.tau2;
  auto f3 = demo_frame({0.5, -0.3, 0.525}, {1, 0, 0}, {0, 1, 0});    // tray pick-up
  f3.kappa = row.kappa3;
  f3.tau = row.tau3;
  f3.cusp = true;
  auto f4 = demo_frame({0.2, -0.5, 0.6}, {0, -1, 0}, {0, 0, -1});    // final, tangent only
  if (reading != core::UnspecifiedConstraints::kLowestDegree) {
    for (auto* f : {&f2, &f3}) {
      f->kappa_d = 0.0;
      f->tau_d = 0.0;
    }
  }
  spec.unspecified = reading;
  spec.frames = {f1, f2, f3, f4};
  return spec;
}

}  // namespace geotraj::testing
