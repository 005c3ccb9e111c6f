// The jerk-limited timing's NLP (jerk_timing_nlp.hpp): its linear rows and the jerk rows that
// can bind, the per-point terms with exact derivatives, and Ipopt's callbacks on them.
#include "optim/timing/jerk_timing_nlp.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

namespace geotraj::optim::detail {

namespace {

using Ipopt::Index;
using Ipopt::Number;
constexpr double kInf = std::numeric_limits<double>::infinity();
// Joint jerk rows per joint and grid point: with the ramp's jerk at either end of the ramp,
// without it either side (time_optimal_jerk.hpp).
constexpr int kJerkFamilies = 4;
constexpr double kIpoptInf = 1e19;
/// Relative room an implied jerk row keeps below its limit (JerkTimingNlp::select_jerk_rows):
/// the rows that imply it hold to Ipopt's tolerance only.
constexpr double kImpliedMargin = 1e-6;

double finite_or(double x) { return std::isfinite(x) ? x : kIpoptInf; }

D3 constant(double c) { return D3(c); }
D3 variable(double x, int l) { return D3::variable(x, l); }

}  // namespace

JerkTimingNlp::JerkTimingNlp(const std::vector<core::GridPoint>& grid, const core::TimeOptimalLimits& lim,
                             const JerkTimingOptions& opt)
    : g_(grid), lim_(lim), opt_(opt) {
  N_ = static_cast<Index>(grid.size()) - 1;
  const Index nj = static_cast<Index>(lim.joint_velocity.size());
  q_sss_.resize(grid.size());
  for (std::size_t i = 0; i < grid.size(); ++i) {
    const std::size_t a = i == 0 ? 0 : i - 1, b = std::min(grid.size() - 1, i + 1);
    q_sss_[i] = (grid[b].q_ss - grid[a].q_ss) / (grid[b].s - grid[a].s);
  }
  for (Index j = 0; j < nj; ++j)
    if (opt.joint_jerk.size() == nj && std::isfinite(opt.joint_jerk(j))) jerk_joints_.push_back(j);
  cart_jerk_ = opt.max_jerk.has_value() && std::isfinite(*opt.max_jerk);
  build_linear_rows();
  // Per joint four rows (families): s_ddot at the ramp's start (u_{p-1}) and at its end
  // (u_p), with the ramp's jerk j_p and without it (the constant accelerations either side).
  jerk_rows_per_point_ = kJerkFamilies * static_cast<Index>(jerk_joints_.size()) + (cart_jerk_ ? 1 : 0);
  select_jerk_rows();
  hess_offset_.resize(static_cast<std::size_t>(n_var()) + 1, 0);
  for (Index k = 0; k < n_var(); ++k) hess_offset_[k + 1] = hess_offset_[k] + std::min<Index>(k, 2) + 1;
  terms_.resize(grid.size());
  jerk_rows_.resize(grid.size() * static_cast<std::size_t>(jerk_rows_per_point_));
}

double JerkTimingNlp::objective(const Number* x) {
  if (!update(x)) return kInf;
  double f = 0.0;
  for (const Terms& t : terms_) f += t.obj.f;
  return f;
}

double JerkTimingNlp::row_value(Index r, const Number* x) const {
  if (r < n_lin()) {
    double v = 0.0;
    for (Index e = lin_begin_[r]; e < lin_begin_[r + 1]; ++e) v += lin_coef_[e] * x[lin_col_[e]];
    return v;
  }
  return jerk_rows_[static_cast<std::size_t>(r - n_lin())].f;
}

void JerkTimingNlp::row_bounds(Index r, double& lo, double& hi) const {
  if (r < n_lin()) {
    lo = lin_lo_[r], hi = lin_hi_[r];
    return;
  }
  const Index p = (r - n_lin()) / jerk_rows_per_point_;
  Index c = (r - n_lin()) % jerk_rows_per_point_;
  if (cart_jerk_ && c-- == 0) {
    hi = *opt_.max_jerk * jerk_sigma(p);
    lo = -hi;
    return;
  }
  const Index j = jerk_joints_[static_cast<std::size_t>(c) % jerk_joints_.size()];
  hi = opt_.joint_jerk(j) * jerk_sigma(p);
  lo = -hi;
}

double JerkTimingNlp::full_violation(const Number* x) {
  if (!update(x)) return kInf;
  double v = 0.0;
  for (Index p = 1; p <= N_ - 1; ++p) v = std::max({v, x[var(p)] - point_cap(p), -x[var(p)]});
  for (Index r = 0; r < n_rows(); ++r) {
    double lo, hi;
    row_bounds(r, lo, hi);
    const double g = row_value(r, x);
    v = std::max({v, g - hi, lo - g});
  }
  return v;
}

bool JerkTimingNlp::get_nlp_info(Index& n, Index& m, Index& nnz_jac, Index& nnz_h, IndexStyleEnum& style) {
  n = n_var();
  m = static_cast<Index>(active_.size());
  nnz_jac = 0;
  for (const Index r : active_) nnz_jac += row_nnz(r);
  nnz_h = hess_offset_.back();
  style = C_STYLE;
  return true;
}

bool JerkTimingNlp::get_bounds_info(Index n, Number* xl, Number* xu, Index m, Number* gl, Number* gu) {
  for (Index p = 1; p <= N_ - 1; ++p) {
    xl[var(p)] = 0.0;
    xu[var(p)] = finite_or(point_cap(p));
  }
  for (Index k = 0; k < m; ++k) row_bounds(active_[static_cast<std::size_t>(k)], gl[k], gu[k]);
  (void)n;
  return true;
}

bool JerkTimingNlp::get_starting_point(Index n, bool init_x, Number* x, bool, Number*, Number*, Index, bool,
                                       Number*) {
  if (init_x) std::copy(x0_.begin(), x0_.begin() + n, x);
  return true;
}

bool JerkTimingNlp::eval_f(Index, const Number* x, bool, Number& f) {
  f = objective(x);
  return std::isfinite(f);
}

bool JerkTimingNlp::eval_grad_f(Index n, const Number* x, bool, Number* gf) {
  if (!update(x)) return false;
  std::fill(gf, gf + n, 0.0);
  for (Index p = 0; p <= N_; ++p)
    for (int l = 0; l < 3; ++l)
      if (const Index k = var(p - 1 + l); k >= 0) gf[k] += terms_[static_cast<std::size_t>(p)].obj.g[l];
  return true;
}

bool JerkTimingNlp::eval_g(Index, const Number* x, bool, Index m, Number* g) {
  if (!update(x)) return false;
  for (Index k = 0; k < m; ++k) g[k] = row_value(active_[static_cast<std::size_t>(k)], x);
  return true;
}

bool JerkTimingNlp::eval_jac_g(Index, const Number* x, bool, Index m, Index, Index* row, Index* col,
                               Number* val) {
  if (val == nullptr) {
    Index e = 0;
    for (Index k = 0; k < m; ++k) {
      const Index r = active_[static_cast<std::size_t>(k)];
      if (r < n_lin()) {
        for (Index c = lin_begin_[r]; c < lin_begin_[r + 1]; ++c) row[e] = k, col[e] = lin_col_[c], ++e;
        continue;
      }
      const Index p = (r - n_lin()) / jerk_rows_per_point_;
      for (int l = 0; l < 3; ++l)
        if (const Index v = var(p - 1 + l); v >= 0) row[e] = k, col[e] = v, ++e;
    }
    return true;
  }
  if (!update(x)) return false;
  Index e = 0;
  for (Index k = 0; k < m; ++k) {
    const Index r = active_[static_cast<std::size_t>(k)];
    if (r < n_lin()) {
      for (Index c = lin_begin_[r]; c < lin_begin_[r + 1]; ++c) val[e++] = lin_coef_[c];
      continue;
    }
    const Index p = (r - n_lin()) / jerk_rows_per_point_;
    const D3& d = jerk_rows_[static_cast<std::size_t>(r - n_lin())];
    for (int l = 0; l < 3; ++l)
      if (var(p - 1 + l) >= 0) val[e++] = d.g[l];
  }
  return true;
}

bool JerkTimingNlp::eval_h(Index, const Number* x, bool, Number sigma, Index m, const Number* lambda, bool, Index,
                           Index* row, Index* col, Number* val) {
  if (val == nullptr) {
    for (Index k = 0; k < n_var(); ++k)
      for (Index c = std::max<Index>(0, k - 2); c <= k; ++c) {
        row[hess_offset_[k] + (k - c)] = k;
        col[hess_offset_[k] + (k - c)] = c;
      }
    return true;
  }
  if (!update(x)) return false;
  std::fill(val, val + hess_offset_.back(), 0.0);
  // Per grid point: sigma times the objective's term plus the active jerk rows' lambda times theirs.
  std::size_t k = 0;
  while (k < active_.size() && active_[k] < n_lin()) ++k;
  for (Index p = 0; p <= N_; ++p) {
    std::array<double, 6> h = (sigma * terms_[static_cast<std::size_t>(p)].obj).h;
    const Index end = n_lin() + (p + 1) * jerk_rows_per_point_;
    for (; k < active_.size() && active_[k] < end; ++k) {
      const D3& d = jerk_rows_[static_cast<std::size_t>(active_[k] - n_lin())];
      for (int e = 0; e < 6; ++e) h[e] += lambda[k] * d.h[e];
    }
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j <= i; ++j) {
        const Index ki = var(p - 1 + i), kj = var(p - 1 + j);
        if (ki >= 0 && kj >= 0) val[hess_offset_[ki] + (ki - kj)] += h[tri(i, j)];
      }
  }
  (void)m;
  return true;
}

bool JerkTimingNlp::intermediate_callback(Ipopt::AlgorithmMode, Index, Number, Number, Number, Number, Number,
                                          Number, Number, Number, Index, const Ipopt::IpoptData*,
                                          Ipopt::IpoptCalculatedQuantities*) {
  return !opt_.stop.stop_requested();
}

void JerkTimingNlp::finalize_solution(Ipopt::SolverReturn, Index n, const Number* x, const Number*, const Number*,
                                      Index, const Number*, const Number*, Number, const Ipopt::IpoptData*,
                                      Ipopt::IpoptCalculatedQuantities*) {
  x_.assign(x, x + n);
}

std::vector<double> JerkTimingNlp::jerk(const Number* x) {
  std::vector<double> j;
  if (update(x))
    for (const Terms& t : terms_) j.push_back(t.j);
  return j;
}

Index JerkTimingNlp::point_vars(Index p) const {
  Index c = 0;
  for (int l = 0; l < 3; ++l) c += var(p - 1 + l) >= 0 ? 1 : 0;
  return c;
}

/// The largest b the point's own limits allow (the sweep's point cap, with sigma) [m^2/s^2].
double JerkTimingNlp::point_cap(Index p) const {
  const core::GridPoint& gp = g_[static_cast<std::size_t>(p)];
  const double sig = sigma(p);
  double cap = kInf;
  for (Eigen::Index j = 0; j < gp.q_s.size(); ++j) {
    const double qs = std::abs(gp.q_s(j)), v = lim_.joint_velocity(j) * sig;
    if (qs > 0.0 && v < kInf) cap = std::min(cap, (v / qs) * (v / qs));
  }
  if (lim_.speed < kInf) cap = std::min(cap, lim_.speed * lim_.speed);
  if (gp.kappa > 0.0 && lim_.centripetal < kInf) cap = std::min(cap, lim_.centripetal * sig * sig / gp.kappa);
  return cap;
}

/// The jerk rows that can bind (active_: every linear row and these). At grid point p the
/// rows are linear in (j, A, C) = (j_p, s_dot s_ddot, s_dot^3):
///   row_k = q_s,k j + 3 q_ss,k A + q_sss,k C  in [-J_k, J_k]   (Cartesian: j in [-J, J])
/// and every feasible point has 0 <= b_p <= cap_p (the point cap), |u| <= U_p on both
/// sides of p (the tangential limit and each joint acceleration row at p:
/// |u| <= (a_k + |q_ss,k| cap_p) / |q_s,k|), so |A| <= sqrt(cap_p) U_p = A_max and
/// 0 <= C <= cap_p^(3/2) = C_max. A row r is implied by a kept row k: with rho = q_s,r / q_s,k,
/// row_r = rho row_k + (3 q_ss,r - rho 3 q_ss,k) A + (q_sss,r - rho q_sss,k) C, so
///   |row_r| <= |rho| J_k + |3 q_ss,r - 3 rho q_ss,k| A_max + |q_sss,r - rho q_sss,k| C_max
/// and where that is within J_r (1 - kImpliedMargin) row r cannot bind and is left out: the
/// feasible set is unchanged. Greedy, the tightest rows on j first (the Cartesian row, then
/// by (J_k + R_k) / |q_s,k|, R_k the bound of the A and C terms), a row only ever implied
/// by rows kept before it.
void JerkTimingNlp::select_jerk_rows() {
  active_.clear();
  for (Index r = 0; r < n_lin(); ++r) active_.push_back(r);
  std::vector<std::pair<double, Index>> order;  // (bound on |j|, c) per row c of the point
  std::vector<Index> kept;
  for (Index p = 0; p <= N_; ++p) {
    const Index base = n_lin() + p * jerk_rows_per_point_;
    const core::GridPoint& gp = g_[static_cast<std::size_t>(p)];
    const double cap = p == 0 || p == N_ ? 0.0 : point_cap(p), sig2 = sigma(p) * sigma(p);
    double U = lim_.tangential;
    for (Eigen::Index k = 0; k < gp.q_s.size(); ++k)
      if (gp.q_s(k) != 0.0 && lim_.joint_acceleration(k) < kInf)
        U = std::min(U, (lim_.joint_acceleration(k) * sig2 + std::abs(gp.q_ss(k)) * cap) / std::abs(gp.q_s(k)));
    const double a_max = std::sqrt(cap) * U, c_max = cap * std::sqrt(cap);
    if (!opt_.drop_implied_jerk_rows || !std::isfinite(a_max) || !std::isfinite(c_max)) {  // keep every row
      for (Index c = 0; c < jerk_rows_per_point_; ++c) active_.push_back(base + c);
      continue;
    }
    // A joint row's family (the constructor; -1: the Cartesian row, whose implications hold
    // in any); two rows imply one another only in one family (the same s_dot s_ddot).
    auto family = [&](Index c) {
      return cart_jerk_ && c == 0 ? Index{-1}
                                  : static_cast<Index>(static_cast<std::size_t>(c - (cart_jerk_ ? 1 : 0)) /
                                                       jerk_joints_.size());
    };
    // Row c as (q_s, 3 q_ss, q_sss, J).
    auto coef = [&](Index c, int w) {
      if (cart_jerk_ && c == 0) return w == 0 ? 1.0 : w == 3 ? *opt_.max_jerk * jerk_sigma(p) : 0.0;
      const Index k = jerk_joints_[static_cast<std::size_t>(c - (cart_jerk_ ? 1 : 0)) % jerk_joints_.size()];
      if (w == 0 && family(c) >= 2) return 0.0;  // no ramp: no j term
      return w == 0 ? gp.q_s(k) : w == 1 ? 3.0 * gp.q_ss(k) : w == 2 ? q_sss_[static_cast<std::size_t>(p)](k)
                                                                      : opt_.joint_jerk(k) * jerk_sigma(p);
    };
    order.clear();
    for (Index c = 0; c < jerk_rows_per_point_; ++c) {
      const double qs = std::abs(coef(c, 0));
      const double rest = std::abs(coef(c, 1)) * a_max + std::abs(coef(c, 2)) * c_max;
      order.push_back({qs > 0.0 ? (coef(c, 3) + rest) / qs : kInf, c});
    }
    std::sort(order.begin(), order.end());
    kept.clear();
    for (const auto& [bound, r] : order) {
      bool implied = false;
      for (const Index k : kept) {
        if (family(r) >= 0 && family(k) >= 0 && family(r) % 2 != family(k) % 2) continue;
        const double rho = coef(r, 0) / coef(k, 0);
        const double worst = std::abs(rho) * coef(k, 3) + std::abs(coef(r, 1) - rho * coef(k, 1)) * a_max +
                             std::abs(coef(r, 2) - rho * coef(k, 2)) * c_max;
        if (worst <= coef(r, 3) * (1.0 - kImpliedMargin)) implied = true;
      }
      if (!implied && coef(r, 0) == 0.0)  // no j term: implied by the box alone
        implied = std::abs(coef(r, 1)) * a_max + std::abs(coef(r, 2)) * c_max <= coef(r, 3) * (1.0 - kImpliedMargin);
      if (!implied && coef(r, 0) != 0.0) kept.push_back(r);
      if (!implied) active_.push_back(base + r);
    }
  }
  std::sort(active_.begin(), active_.end());
}

/// The limits linear in b: the joint accelerations at both ends of every interval and the
/// tangential acceleration of every interval (the sweep's interval polygon). Rows that
/// cannot bind are left out: per interval, the feasible polygon in (b_i, b_{i+1}) of all
/// its rows and the point caps is built by clipping, and a row is kept only where one of
/// its two sides touches that polygon (to 1e-9 relative), so the feasible set is unchanged.
void JerkTimingNlp::build_linear_rows() {
  struct Row {
    double c0, c1, lo, hi;  // lo <= c0 b_i + c1 b_{i+1} <= hi
  };
  std::vector<Row> rows;
  std::vector<std::array<double, 2>> poly, next;
  double big = 1.0;  // a cap for b where none is given [m^2/s^2]
  for (Index p = 0; p <= N_; ++p)
    if (std::isfinite(point_cap(p))) big = std::max(big, point_cap(p));
  big *= 1e3;
  lin_begin_.push_back(0);
  for (Index i = 0; i < N_; ++i) {
    rows.clear();
    const double h = 1.0 / (2.0 * ds(i));  // u_i = h (b_{i+1} - b_i)
    for (int end = 0; end < 2; ++end) {
      const core::GridPoint& gp = g_[static_cast<std::size_t>(i + end)];
      for (Eigen::Index j = 0; j < gp.q_s.size(); ++j) {
        const double a = lim_.joint_acceleration(j) * sigma(i + end) * sigma(i + end);
        if (!(a < kInf)) continue;
        // q_s u_i + q_ss b_k, k = i + end.
        rows.push_back({-gp.q_s(j) * h + (end == 0 ? gp.q_ss(j) : 0.0),
                        gp.q_s(j) * h + (end == 1 ? gp.q_ss(j) : 0.0), -a, a});
      }
      // The joint torques, tau_a u_i + tau_b b_k + tau_c within +-maxTorque (the sweep's rows,
      // time_optimal.hpp): the part beyond gravity's scaled as an acceleration.
      if (lim_.joint_torque.size() == gp.q_s.size() && gp.tau_a.size() == gp.q_s.size()) {
        const double f = sigma(i + end) * sigma(i + end) * lim_.torque_dynamic_scale;
        for (Eigen::Index j = 0; j < gp.q_s.size(); ++j) {
          const double T = lim_.joint_torque(j);
          if (!(T < kInf)) continue;
          rows.push_back({-gp.tau_a(j) * h + (end == 0 ? gp.tau_b(j) : 0.0),
                          gp.tau_a(j) * h + (end == 1 ? gp.tau_b(j) : 0.0), (-T - gp.tau_c(j)) * f,
                          (T - gp.tau_c(j)) * f});
        }
      }
    }
    if (lim_.tangential < kInf) rows.push_back({-h, h, -lim_.tangential, lim_.tangential});
    // The polygon: the box of the point caps (the rests: 0), clipped by every side of every row.
    const double x_hi = var(i) >= 0 ? std::min(big, point_cap(i)) : 0.0;
    const double y_hi = var(i + 1) >= 0 ? std::min(big, point_cap(i + 1)) : 0.0;
    poly = {{0.0, 0.0}, {x_hi, 0.0}, {x_hi, y_hi}, {0.0, y_hi}};
    auto clip = [&](double a0, double a1, double c) {  // keep a0 x + a1 y <= c
      next.clear();
      for (std::size_t k = 0; k < poly.size(); ++k) {
        const auto& P = poly[k];
        const auto& Q = poly[(k + 1) % poly.size()];
        const double fp = a0 * P[0] + a1 * P[1] - c, fq = a0 * Q[0] + a1 * Q[1] - c;
        if (fp <= 0.0) next.push_back(P);
        if ((fp < 0.0 && fq > 0.0) || (fp > 0.0 && fq < 0.0)) {
          const double t = fp / (fp - fq);
          next.push_back({P[0] + t * (Q[0] - P[0]), P[1] + t * (Q[1] - P[1])});
        }
      }
      poly.swap(next);
    };
    for (const Row& r : rows) {
      clip(r.c0, r.c1, r.hi);
      clip(-r.c0, -r.c1, -r.lo);
    }
    for (const Row& r : rows) {
      bool keep = poly.empty();  // numerically empty: keep every row
      for (const auto& P : poly) {
        const double v = r.c0 * P[0] + r.c1 * P[1];
        const double tol = 1e-9 * (std::abs(r.c0 * P[0]) + std::abs(r.c1 * P[1]) + std::abs(r.hi));
        keep = keep || v >= r.hi - tol || v <= r.lo + tol;
      }
      if (!keep) continue;
      const std::size_t before = lin_col_.size();
      if (const Index k = var(i); k >= 0 && r.c0 != 0.0) lin_col_.push_back(k), lin_coef_.push_back(r.c0);
      if (const Index k = var(i + 1); k >= 0 && r.c1 != 0.0) lin_col_.push_back(k), lin_coef_.push_back(r.c1);
      if (lin_col_.size() == before) continue;  // no variable: 0 in [lo, hi]
      lin_begin_.push_back(static_cast<Index>(lin_col_.size()));
      lin_lo_.push_back(r.lo);
      lin_hi_.push_back(r.hi);
    }
  }
}

/// The per-point terms and jerk rows at x (cached on x); false where some b <= 0.
bool JerkTimingNlp::update(const Number* x) {
  const Index n = n_var();
  if (have_ && std::equal(x, x + n, cached_x_.begin())) return ok_;
  cached_x_.assign(x, x + n);
  have_ = true;
  ok_ = false;
  for (Index k = 0; k < n; ++k)
    if (!(x[k] > 0.0)) return false;
  const double w = opt_.smoothness_weight;
  for (Index p = 0; p <= N_; ++p) {
    std::array<D3, 3> b, r;
    for (int l = 0; l < 3; ++l) {
      const Index k = var(p - 1 + l);
      b[l] = k >= 0 ? variable(x[k], l) : constant(0.0);
      r[l] = k >= 0 ? sqrt(b[l]) : constant(0.0);
    }
    D3 tau, u_prev, u_next, half_prev, half_next;
    if (p >= 1) {
      half_prev = ds(p - 1) * reciprocal(r[0] + r[1]);  // t_{p-1} / 2
      u_prev = (0.5 / ds(p - 1)) * (b[1] - b[0]);
    }
    if (p <= N_ - 1) {
      half_next = ds(p) * reciprocal(r[1] + r[2]);  // t_p / 2
      u_next = (0.5 / ds(p)) * (b[2] - b[1]);
    }
    tau = half_prev + half_next;
    // The ramp's width: at a rest the one half there; inside, the smooth lower bound of
    // min(t_{p-1}, t_p) (time_optimal_jerk.hpp).
    D3 width = tau;
    if (p >= 1 && p <= N_ - 1) {
      const D3 d = half_prev - half_next;
      width = tau - sqrt(d * d + kJerkWindowSmoothing * (half_prev * half_next));
    }
    const D3 j = (u_next - u_prev) / width;
    Terms& t = terms_[static_cast<std::size_t>(p)];
    t.j = j.f;
    t.obj = w > 0.0 ? tau + w * (j * j * tau) : tau;
    D3* rows = jerk_rows_.data() + p * jerk_rows_per_point_;
    if (cart_jerk_) *rows++ = j;
    if (!jerk_joints_.empty()) {
      const core::GridPoint& gp = g_[static_cast<std::size_t>(p)];
      // s_dot s_ddot at either end of the ramp (the joint jerk is linear in s_ddot there, so
      // its extremes over the ramp are at the ends), s_dot^3.
      const D3 v3 = r[1] * b[1];
      const std::array<D3, 2> v_a{r[1] * u_prev, r[1] * u_next};
      for (int f = 0; f < kJerkFamilies; ++f)
        for (const Index jj : jerk_joints_) {
          const D3 rest = (3.0 * gp.q_ss(jj)) * v_a[f % 2] + q_sss_[static_cast<std::size_t>(p)](jj) * v3;
          *rows++ = f < 2 ? gp.q_s(jj) * j + rest : rest;
        }
    }
  }
  ok_ = true;
  return true;
}

}  // namespace geotraj::optim::detail
