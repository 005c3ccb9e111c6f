#include "geotraj/core/constraints.hpp"

#include <cmath>

#include "geotraj/core/validate.hpp"

namespace geotraj::core {

using Eigen::Vector3d;

Vector3d second_derivative(const Vector3d& p_u, double kappa, const Vector3d& N) {
  return p_u.squaredNorm() * kappa * N;  // (5.10)
}

Vector3d third_derivative(const Vector3d& p_u, const Vector3d& p_uu, std::optional<double> tau,
                          std::optional<double> kappa_du) {
  const Vector3d C = p_u.cross(p_uu);  // (5.17)
  const double C2 = C.squaredNorm();
  GEOTRAJ_CHECK(C2 > 0.0);
  Vector3d p_uuu = Vector3d::Zero();
  if (tau) {
    // Row (5.14): tau = a0 . p_uuu with a0 = C / |C|^2. Its minimum-norm solution is
    // tau a0 / |a0|^2 = tau C.
    p_uuu += *tau * C;
  }
  if (kappa_du) {
    // Row (5.19): kappa_du kappa |p_u|^6 = a1 . p_uuu with a1 = C x p_u. Since p_u is
    // perpendicular to p_uu (5.10), kappa |p_u|^3 = |C|, so the left side is
    // kappa_du |C| |p_u|^3. a1 is orthogonal to a0, so the pseudo-inverse of the
    // two-row system (5.20) is the sum of each row's minimum-norm solution.
    const Vector3d a1 = C.cross(p_u);
    const double kappa = std::sqrt(C2) / std::pow(p_u.norm(), 3);  // (5.4)
    const double rhs = *kappa_du * kappa * std::pow(p_u.squaredNorm(), 3);  // (5.19)
    p_uuu += rhs / a1.squaredNorm() * a1;
  }
  return p_uuu;
}

Vector3d fourth_derivative(const Vector3d& p_u, const Vector3d& p_uu, const Vector3d& p_uuu, double tau,
                           double tau_du) {
  const Vector3d C = p_u.cross(p_uu);
  const double C2 = C.squaredNorm();
  GEOTRAJ_CHECK(C2 > 0.0);
  const double rhs = tau_du * C2 + 2.0 * tau * C.dot(p_u.cross(p_uuu));  // (5.22)
  return rhs / C2 * C;  // minimum-norm solution of C . p_uuuu = rhs
}

namespace {

SideConstraints make_side(const KeyFrame& f, DerivativeConvention convention, bool leaving) {
  SideConstraints side;
  const double scale = f.tangent_scale.value_or(1.0);
  side.T = (leaving && f.cusp) ? Vector3d(-f.T_W) : f.T_W;  // 5.6.2: the tangent inverts
  if (f.N_W) side.N = (leaving && f.inflection) ? Vector3d(-*f.N_W) : *f.N_W;  // 5.6.1

  const Vector3d p_u = scale * side.T;  // (5.3)
  side.d[0] = p_u;
  side.order = 1;
  if (!f.kappa) return side;

  side.d[1] = second_derivative(p_u, *f.kappa, side.N);  // (5.10)
  side.order = 2;
  if (!f.tau && !f.kappa_d) return side;

  // d/du = |dp/du| d/ds at the frame (chain rule), |dp/du| = scale.
  const double per_u = convention == DerivativeConvention::kPerArcLength ? scale : 1.0;
  const std::optional<double> kappa_du = f.kappa_d ? std::optional<double>(*f.kappa_d * per_u) : std::nullopt;
  side.d[2] = third_derivative(p_u, side.d[1], f.tau, kappa_du);  // (5.20)
  side.order = 3;
  if (!f.tau_d) return side;

  side.d[3] = fourth_derivative(p_u, side.d[1], side.d[2], *f.tau, *f.tau_d * per_u);  // (5.22)
  side.order = 4;
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
  auto valid = validate_path(spec);
  if (!valid) return tl::unexpected(std::move(valid.error()));
  std::vector<FrameConstraints> out;
  out.reserve(valid->frames.size());
  for (const auto& f : valid->frames) out.push_back(convert_frame(f, valid->convention));
  return out;
}

}  // namespace geotraj::core
