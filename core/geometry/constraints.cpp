#include "core/geometry/constraints.hpp"
#include "core/geometry/path.hpp"

#include <cmath>

#include "core/geometry/validate.hpp"

namespace geotraj::core {

using Eigen::Vector3d;

Vector3d second_derivative(const Vector3d& p_u, double kappa, const Vector3d& N) {
  return detail::second_derivative<double>(p_u, kappa, N);  // (5.10)
}

Vector3d third_derivative(const Vector3d& p_u, const Vector3d& p_uu, std::optional<double> tau,
                          std::optional<double> kappa_du) {
  GEOTRAJ_CHECK(p_u.cross(p_uu).squaredNorm() > 0.0);
  return detail::third_derivative<double>(p_u, p_uu, tau ? &*tau : nullptr, kappa_du ? &*kappa_du : nullptr);  // (5.20)
}

Vector3d fourth_derivative(const Vector3d& p_u, const Vector3d& p_uu, const Vector3d& p_uuu, double tau,
                           double tau_du) {
  GEOTRAJ_CHECK(p_u.cross(p_uu).squaredNorm() > 0.0);
  return detail::fourth_derivative<double>(p_u, p_uu, p_uuu, tau, tau_du);  // (5.22)
}

namespace {

SideConstraints make_side(const KeyFrame& f, DerivativeConvention convention, bool leaving) {
  SideConstraints side;
  side.T = (leaving && f.cusp) ? Vector3d(-f.T_W) : f.T_W;  // 5.6.2: the tangent inverts
  if (f.N_W) side.N = (leaving && f.inflection) ? Vector3d(-*f.N_W) : *f.N_W;  // 5.6.1
  side.order = side_derivatives<double>(f, convention, side.T, side.N, side_scale(f, leaving), side.d);
  return side;
}

}  // namespace

FrameConstraints convert_frame(const KeyFrame& frame, DerivativeConvention convention) {
  FrameConstraints out;
  out.p_W = frame.p_W;
  out.approach = make_side(frame, convention, /*leaving=*/false);
  out.leave = make_side(frame, convention, /*leaving=*/true);
  return out;
}

Expected<std::vector<FrameConstraints>> convert_path(const PathSpec& spec) {
  if (spec.start || !spec.pieces.empty()) {  // a path of pieces: its joins, from the curves built
    auto path = build_path(spec);
    if (!path) return tl::unexpected(std::move(path.error()));
    return std::move(path->frames);
  }
  auto valid = validate_path(spec);
  if (!valid) return tl::unexpected(std::move(valid.error()));
  std::vector<FrameConstraints> out;
  out.reserve(valid->frames.size());
  for (const auto& f : valid->frames) out.push_back(convert_frame(f, valid->convention));
  return out;
}

}  // namespace geotraj::core
