#include "optim/timing/time_optimal_jerk.hpp"

#include "core/format.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <IpIpoptApplication.hpp>
#include <IpSolveStatistics.hpp>
#include <IpTNLP.hpp>

#include "optim/common/ipopt_lock.hpp"
#include "optim/common/second_order.hpp"
#include "optim/timing/banded_ipm.hpp"

namespace geotraj::optim {

namespace {

using Ipopt::Index;
using Ipopt::Number;
constexpr double kInf = std::numeric_limits<double>::infinity();
// Joint jerk rows per joint and grid point: with the ramp's jerk at either end of the ramp,
// without it either side (the header).
constexpr int kJerkFamilies = 4;
constexpr double kIpoptInf = 1e19;
/// Relative room an implied jerk row keeps below its limit (JerkTimingNlp::select_jerk_rows):
/// the rows that imply it hold to Ipopt's tolerance only.
constexpr double kImpliedMargin = 1e-6;

double finite_or(double x) { return std::isfinite(x) ? x : kIpoptInf; }

/// A value with its gradient and Hessian in the three local variables (b_{i-1}, b_i,
/// b_{i+1}) of grid point i: forward-mode second derivatives of the per-point terms
/// (second_order.hpp; the Hessian's lower triangle at tri(r, c)).
using D3 = detail::SecondOrder<3>;
using detail::tri;

D3 constant(double c) { return D3(c); }
D3 variable(double x, int l) { return D3::variable(x, l); }

/// The NLP of time_optimal_jerk.hpp. Variables x_k = b_{k+1}, k = 0 .. N - 2.
class JerkTimingNlp : public Ipopt::TNLP {
 public:
  JerkTimingNlp(const std::vector<core::GridPoint>& grid, const core::TimeOptimalLimits& lim,
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

  Index n_var() const { return N_ - 1; }
  double ds(Index i) const { return g_[static_cast<std::size_t>(i + 1)].s - g_[static_cast<std::size_t>(i)].s; }
  /// The variable of grid point p, or -1 for the rests.
  Index var(Index p) const { return p >= 1 && p <= N_ - 1 ? p - 1 : -1; }

  /// The objective T + w sum j^2 tau at x [s]; +infinity where some b <= 0.
  double objective(const Number* x) {
    if (!update(x)) return kInf;
    double f = 0.0;
    for (const Terms& t : terms_) f += t.obj.f;
    return f;
  }

  // The rows handed to Ipopt (select_jerk_rows): Ipopt's row k is full row active_[k], full
  // rows numbered linear rows first, then (N + 1) x jerk_rows_per_point_ jerk rows by point.
  Index n_rows() const { return n_lin() + (N_ + 1) * jerk_rows_per_point_; }
  std::size_t n_active() const { return active_.size(); }
  std::size_t n_jerk_rows() const { return static_cast<std::size_t>((N_ + 1) * jerk_rows_per_point_); }
  std::size_t n_implied() const { return static_cast<std::size_t>(n_rows()) - active_.size(); }

  /// The value and bounds of full row r at x (update(x) true).
  double row_value(Index r, const Number* x) const {
    if (r < n_lin()) {
      double v = 0.0;
      for (Index e = lin_begin_[r]; e < lin_begin_[r + 1]; ++e) v += lin_coef_[e] * x[lin_col_[e]];
      return v;
    }
    return jerk_rows_[static_cast<std::size_t>(r - n_lin())].f;
  }
  void row_bounds(Index r, double& lo, double& hi) const {
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
  /// The jerk limits' factor at grid point p (JerkTimingOptions::jerk_scale; 1 without).
  double jerk_sigma(Index p) const {
    return opt_.jerk_scale.empty() ? 1.0 : opt_.jerk_scale[static_cast<std::size_t>(p)];
  }
  /// Largest excess of x over any bound or row, the left-out jerk rows included, in the
  /// limit's unit (0: feasible).
  double full_violation(const Number* x) {
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

  bool get_nlp_info(Index& n, Index& m, Index& nnz_jac, Index& nnz_h, IndexStyleEnum& style) override {
    n = n_var();
    m = static_cast<Index>(active_.size());
    nnz_jac = 0;
    for (const Index r : active_) nnz_jac += row_nnz(r);
    nnz_h = hess_offset_.back();
    style = C_STYLE;
    return true;
  }

  bool get_bounds_info(Index n, Number* xl, Number* xu, Index m, Number* gl, Number* gu) override {
    for (Index p = 1; p <= N_ - 1; ++p) {
      xl[var(p)] = 0.0;
      xu[var(p)] = finite_or(point_cap(p));
    }
    for (Index k = 0; k < m; ++k) row_bounds(active_[static_cast<std::size_t>(k)], gl[k], gu[k]);
    (void)n;
    return true;
  }

  bool get_starting_point(Index n, bool init_x, Number* x, bool, Number*, Number*, Index, bool, Number*) override {
    if (init_x) std::copy(x0_.begin(), x0_.begin() + n, x);
    return true;
  }

  bool eval_f(Index, const Number* x, bool, Number& f) override {
    f = objective(x);
    return std::isfinite(f);
  }

  bool eval_grad_f(Index n, const Number* x, bool, Number* gf) override {
    if (!update(x)) return false;
    std::fill(gf, gf + n, 0.0);
    for (Index p = 0; p <= N_; ++p)
      for (int l = 0; l < 3; ++l)
        if (const Index k = var(p - 1 + l); k >= 0) gf[k] += terms_[static_cast<std::size_t>(p)].obj.g[l];
    return true;
  }

  bool eval_g(Index, const Number* x, bool, Index m, Number* g) override {
    if (!update(x)) return false;
    for (Index k = 0; k < m; ++k) g[k] = row_value(active_[static_cast<std::size_t>(k)], x);
    return true;
  }

  bool eval_jac_g(Index, const Number* x, bool, Index m, Index, Index* row, Index* col, Number* val) override {
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

  bool eval_h(Index, const Number* x, bool, Number sigma, Index m, const Number* lambda, bool, Index, Index* row,
              Index* col, Number* val) override {
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

  // A cancelled call stops Ipopt at its next iteration (User_Requested_Stop).
  bool intermediate_callback(Ipopt::AlgorithmMode, Index, Number, Number, Number, Number, Number, Number, Number,
                             Number, Index, const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override {
    return !opt_.stop.stop_requested();
  }

  void finalize_solution(Ipopt::SolverReturn, Index n, const Number* x, const Number*, const Number*, Index,
                         const Number*, const Number*, Number, const Ipopt::IpoptData*,
                         Ipopt::IpoptCalculatedQuantities*) override {
    x_.assign(x, x + n);
  }

  /// The jerk j_i at every grid point [m/s^3] of x (update(x) true).
  std::vector<double> jerk(const Number* x) {
    std::vector<double> j;
    if (update(x))
      for (const Terms& t : terms_) j.push_back(t.j);
    return j;
  }

  std::vector<double> x0_, x_;  ///< Ipopt's start and its result

 private:
  /// Per grid point: the objective's share tau + w j^2 tau [s] with derivatives, and j.
  struct Terms {
    D3 obj;
    double j = 0.0;
  };

  Index n_lin() const { return static_cast<Index>(lin_lo_.size()); }
  Index point_vars(Index p) const {
    Index c = 0;
    for (int l = 0; l < 3; ++l) c += var(p - 1 + l) >= 0 ? 1 : 0;
    return c;
  }
  Index row_nnz(Index r) const {
    return r < n_lin() ? lin_begin_[r + 1] - lin_begin_[r] : point_vars((r - n_lin()) / jerk_rows_per_point_);
  }

  /// sigma of grid point p (JerkTimingOptions::limit_scale; 1 without).
  double sigma(Index p) const {
    return opt_.limit_scale.empty() ? 1.0 : opt_.limit_scale[static_cast<std::size_t>(p)];
  }

  /// The largest b the point's own limits allow (the sweep's point cap, with sigma) [m^2/s^2].
  double point_cap(Index p) const {
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
  void select_jerk_rows() {
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
  void build_linear_rows() {
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
  bool update(const Number* x) {
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
      // min(t_{p-1}, t_p) (the header).
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

  const std::vector<core::GridPoint>& g_;
  const core::TimeOptimalLimits& lim_;
  const JerkTimingOptions& opt_;
  Index N_ = 0;
  std::vector<core::JointVector> q_sss_;
  std::vector<Index> jerk_joints_;
  bool cart_jerk_ = false;
  Index jerk_rows_per_point_ = 0;
  // Linear rows (compressed by row): columns, coefficients, bounds.
  std::vector<Index> lin_begin_, lin_col_;
  std::vector<double> lin_coef_, lin_lo_, lin_hi_;
  std::vector<Index> hess_offset_;  ///< row k of the banded lower triangle starts here
  std::vector<Index> active_;       ///< the rows handed to Ipopt (full row ids, ascending)
  // Cache of update().
  std::vector<double> cached_x_;
  bool have_ = false, ok_ = false;
  std::vector<Terms> terms_;
  std::vector<D3> jerk_rows_;
};

/// The profile of b: one constant-acceleration piece per interval with its exact time.
core::SpeedProfile profile_of(const std::vector<core::GridPoint>& grid, const std::vector<double>& b,
                              std::vector<double>& u, std::vector<double>& dt) {
  core::SpeedProfile p;
  const std::size_t N = grid.size() - 1;
  u.assign(N, 0.0);
  dt.assign(N, 0.0);
  double t = 0.0;
  for (std::size_t i = 0; i < N; ++i) {
    const double ds = grid[i + 1].s - grid[i].s, v0 = std::sqrt(b[i]), v1 = std::sqrt(b[i + 1]);
    u[i] = (b[i + 1] - b[i]) / (2.0 * ds);
    dt[i] = 2.0 * ds / (v0 + v1);
    p.pieces.push_back({t, grid[i].s, v0, u[i], 0.0});
    t += dt[i];
  }
  p.duration = t;
  p.length = grid.back().s;
  return p;
}

}  // namespace

JerkTiming optimise_jerk_timing(const std::vector<core::GridPoint>& grid, const core::TimeOptimalLimits& limits,
                                const core::TimeOptimalSolution& start, const JerkTimingOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n_pts = grid.size(), N = n_pts - 1;
  GEOTRAJ_CHECK(n_pts >= 3 && start.b.size() == n_pts && start.u.size() == N);

  GEOTRAJ_CHECK(options.limit_scale.empty() || options.limit_scale.size() == n_pts);
  GEOTRAJ_CHECK(options.jerk_scale.empty() || options.jerk_scale.size() == n_pts);
  GEOTRAJ_CHECK(options.start_scale > 0.0 && options.start_scale <= 1.0);
  // The start: `start`'s b times start_scale, off zero (the sweep may stop at an interior
  // point, b_i = 0, where sqrt(b) has no derivative). The scaled profile is the same motion,
  // slower: its velocities scale by sqrt(c), accelerations by c and jerks by c^(3/2), so it is
  // strictly inside every limit the start meets, and an interior point method starts well
  // from there (from the sweep's b itself, on dozens of active limits, Ipopt needed 100
  // iterations of tiny steps).
  std::vector<double> x_start(start.b.begin() + 1, start.b.end() - 1);
  const double b_floor = 1e-8 * std::max(1e-300, *std::max_element(x_start.begin(), x_start.end()));
  for (double& b : x_start) b = std::max(b, b_floor);
  std::vector<double> x0 = x_start;
  for (double& b : x0) b *= options.start_scale;
  JerkTiming out;

  Ipopt::SmartPtr<JerkTimingNlp> nlp = new JerkTimingNlp(grid, limits, options);
  out.report.objective_before = nlp->objective(x_start.data());

  nlp->x0_ = x0;

  // The banded interior point method first (unless Ipopt is asked for), Ipopt when it does
  // not converge; the deadline is shared.
  const auto deadline = t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                 std::chrono::duration<double>(std::max(0.0, options.time_budget_s)));
  bool run_ipopt = options.solver == JerkSolver::kIpopt || options.derivative_test;
  std::string prefix;
  if (!run_ipopt) {
    detail::BandedIpmOptions bo;
    bo.tol = options.tolerance;
    bo.constr_viol_tol = 1e-9;  // as Ipopt's below
    bo.max_iterations = options.max_iterations;
    bo.deadline = deadline;
    bo.stop = options.stop;
    const detail::BandedIpmResult r = detail::solve_banded_ipm(*nlp, bo);
    out.report.iterations = r.iterations;
    switch (r.status) {
      case detail::BandedIpmResult::Status::kConverged: out.report.status = OptimizerStatus::kConverged; break;
      case detail::BandedIpmResult::Status::kIterationLimit: out.report.status = OptimizerStatus::kIterationLimit; break;
      case detail::BandedIpmResult::Status::kTimeLimit: out.report.status = OptimizerStatus::kTimeLimit; break;
      case detail::BandedIpmResult::Status::kFailed: out.report.status = OptimizerStatus::kFailed; break;
    }
    out.report.message = "banded interior point: " + r.message + " after " + std::to_string(r.iterations) +
                         " iterations";
    nlp->x_ = r.x;
    if (options.solver == JerkSolver::kAuto && (out.report.status == OptimizerStatus::kFailed ||
                                                out.report.status == OptimizerStatus::kIterationLimit)) {
      run_ipopt = true;
      prefix = out.report.message + "; then ";
    }
  }
  // Held until the application is destroyed, at the end of this block (ipopt_lock.hpp).
  std::unique_lock<std::timed_mutex> ipopt;
  if (run_ipopt) {
    ipopt = detail::lock_ipopt(deadline, options.stop);
    if (!ipopt.owns_lock()) {
      run_ipopt = false;
      nlp->x_.clear();
      out.report.status = OptimizerStatus::kTimeLimit;
      out.report.message = prefix + "the time ran out while another optimisation held Ipopt";
    }
  }
  if (run_ipopt) {
    nlp->x_.clear();
    Ipopt::SmartPtr<Ipopt::IpoptApplication> app = IpoptApplicationFactory();
    Ipopt::OptionsList& o = *app->Options();
    o.SetIntegerValue("print_level", options.derivative_test ? 5 : 0);
    if (!options.derivative_test) o.SetStringValue("sb", "yes");
    o.SetNumericValue("tol", options.tolerance);
    o.SetNumericValue("acceptable_tol", 1e3 * options.tolerance);
    // Adaptive barrier. Mehrotra's predictor-corrector was measured and not taken: half the
    // iterations on a synthetic grid, ten times as many on the PA-10 (the jerk rows are not
    // convex).
    o.SetStringValue("mu_strategy", "adaptive");
    // MUMPS (Debian's only solver) with AMD ordering: the KKT matrix is banded, and AMD's
    // ordering factors it fastest here (against METIS, PORD and MUMPS's automatic choice).
    o.SetIntegerValue("mumps_pivot_order", 0);
    o.SetNumericValue("constr_viol_tol", 1e-9);
    // Ipopt relaxes every bound by 1e-8 relative by default; the jerk rows then end up to
    // 2e-5 relative beyond their limits (the straight-line test). 1e-10 keeps them to 1e-6.
    o.SetNumericValue("bound_relax_factor", 1e-10);
    if (options.derivative_test) {
      o.SetStringValue("derivative_test", "second-order");
      o.SetNumericValue("derivative_test_perturbation", 1e-8);
      o.SetNumericValue("derivative_test_tol", 1e-4);
    }

    o.SetIntegerValue("max_iter", options.max_iterations);
    const double left = options.time_budget_s - std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    o.SetNumericValue("max_cpu_time", std::max(1e-6, left));

    // No options file: a stray ipopt.opt in the working directory must not change the result.
    Ipopt::ApplicationReturnStatus status = app->Initialize("");
    if (status == Ipopt::Solve_Succeeded) status = app->OptimizeTNLP(nlp);
    if (Ipopt::SmartPtr<Ipopt::SolveStatistics> stats = app->Statistics(); Ipopt::IsValid(stats))
      out.report.iterations += stats->IterationCount();

    switch (status) {
      case Ipopt::Solve_Succeeded:
      case Ipopt::Solved_To_Acceptable_Level: out.report.status = OptimizerStatus::kConverged; break;
      case Ipopt::Maximum_Iterations_Exceeded: out.report.status = OptimizerStatus::kIterationLimit; break;
      case Ipopt::User_Requested_Stop:  // cancelled
      case Ipopt::Maximum_CpuTime_Exceeded: out.report.status = OptimizerStatus::kTimeLimit; break;
      default: out.report.status = OptimizerStatus::kFailed; break;
    }
    out.report.message = prefix + "Ipopt return status " + std::to_string(static_cast<int>(status));
  }
  if (ipopt.owns_lock()) ipopt.unlock();  // the application is gone with its block
  out.report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const bool have_point = nlp->x_.size() == x0.size() && out.report.status != OptimizerStatus::kFailed &&
                          std::all_of(nlp->x_.begin(), nlp->x_.end(), [](double b) { return b > 0.0; });
  if (!have_point) out.report.status = OptimizerStatus::kFailed;
  const std::vector<double>& xs = have_point ? nlp->x_ : x_start;
  out.b.assign(n_pts, 0.0);
  std::copy(xs.begin(), xs.end(), out.b.begin() + 1);
  out.profile = profile_of(grid, out.b, out.u, out.dt);
  // The acceleration steps at the grid points ramped over the NLP's tau (zero at the rests).
  if (auto smooth = core::continuous_acceleration_profile(out.dt, out.u, grid.back().s)) {
    out.profile = std::move(*smooth);
  } else {
    out.report.status = OptimizerStatus::kFailed;
    out.report.message += "; " + smooth.error().front().description;
  }
  out.jerk = nlp->jerk(xs.data());
  out.duration = out.profile.duration;
  out.jerk_rows = nlp->n_jerk_rows();
  out.implied_jerk_rows = nlp->n_implied();
  out.max_constraint_violation = have_point ? nlp->full_violation(xs.data()) : 0.0;
  out.report.objective_after = have_point ? nlp->objective(xs.data()) : out.report.objective_before;
  if (have_point && out.report.status != OptimizerStatus::kConverged)
    out.report.message += ", largest constraint violation " + core::number(out.max_constraint_violation, 6);
  return out;
}

core::Expected<JerkLimitedPlan> plan_time_optimal_jerk(const core::Path& path,
                                                       const core::OrientationPlan& orientation,
                                                       const core::MotionSpec& spec, const core::RobotModel* robot,
                                                       const core::JointVector& seed,
                                                       const core::TimeOptimalOptions& exact_options,
                                                       JerkTimingOptions options) {
  core::TimeOptimalOptions exact_stoppable = exact_options;
  if (!exact_stoppable.stop.stop_possible()) exact_stoppable.stop = options.stop;
  auto exact = core::plan_time_optimal(path, orientation, spec, robot, seed, exact_stoppable);
  if (!exact) return tl::make_unexpected(exact.error());
  const double sc = spec.speed_scale, sc3 = sc * sc * sc * spec.acceleration_scale;  // and the reserve
  if (robot && options.joint_jerk.size() == 0) {
    const auto n = static_cast<Eigen::Index>(robot->dof());
    options.joint_jerk = core::JointVector::Constant(n, kInf);
    for (Eigen::Index j = 0; j < n; ++j)
      if (const auto& mj = robot->limits[static_cast<std::size_t>(j)].max_jerk) options.joint_jerk(j) = *mj * sc3;
  }
  if (!options.max_jerk && spec.max_jerk) options.max_jerk = *spec.max_jerk * sc3;

  JerkLimitedPlan out;
  out.report.status = OptimizerStatus::kConverged;
  const double budget = options.time_budget_s;
  const auto t0 = std::chrono::steady_clock::now();
  // The NLP meets its limits to Ipopt's tolerance, not exactly: it works within limits
  // shrunk by kJerkLimitMargin, so that the samples stay within the real ones.
  core::TimeOptimalLimits limits = exact->limits;
  limits.joint_velocity *= 1.0 - kJerkLimitMargin;
  limits.joint_acceleration *= 1.0 - kJerkLimitMargin;
  limits.speed *= 1.0 - kJerkLimitMargin;
  limits.tangential *= 1.0 - kJerkLimitMargin;
  limits.centripetal *= 1.0 - kJerkLimitMargin;
  // The sample check is against the real jerk limits (`checked`, below).
  const core::JointVector joint_jerk = options.joint_jerk;
  const std::optional<double> max_jerk = options.max_jerk;
  options.joint_jerk *= 1.0 - kJerkLimitMargin;
  if (options.max_jerk) *options.max_jerk *= 1.0 - kJerkLimitMargin;
  const std::size_t P = exact->grids.size();
  std::vector<std::vector<double>> sigma(P), jerk_sigma(P);
  for (std::size_t p = 0; p < P; ++p) {
    sigma[p].assign(exact->grids[p].size(), 1.0);
    jerk_sigma[p].assign(exact->grids[p].size(), 1.0);
  }
  // The samples are checked against every limit, the jerk included.
  core::TimeOptimalLimits checked = exact->limits;
  checked.joint_jerk = joint_jerk;
  if (max_jerk) checked.jerk = *max_jerk;
  // The starts: the exact sweep's b (within the margin), then each round's result.
  std::vector<core::TimeOptimalSolution> starts = exact->solutions;
  for (auto& st : starts)
    for (double& b : st.b) b *= (1.0 - kJerkLimitMargin) * (1.0 - kJerkLimitMargin);
  const double first_scale = options.start_scale;
  // The call's cancellation or deadline (the token) ends the work between any two steps: a
  // degenerate limit (maxJerk 1e-10 m/s^3) makes a motion of hours whose every sample the
  // check below visits, round after round.
  const auto cancelled = [&] { return options.stop.stop_requested() || exact_stoppable.stop.stop_requested(); };
  const auto stopped = [] {
    return core::Violations{{"motion", "stopped: the call was cancelled (or its deadline passed) while the "
                                       "jerk-limited timing ran"}};
  };
  for (int round = 0;; ++round) {
    if (cancelled()) return tl::make_unexpected(stopped());
    out.portions.clear();
    std::vector<core::SpeedProfile> profiles;
    for (std::size_t p = 0; p < P; ++p) {
      options.time_budget_s =
          std::max(1e-3, budget - std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      options.limit_scale = sigma[p];
      options.jerk_scale = jerk_sigma[p];
      // A re-solve starts from the last result within the tightened limits: scaled by the
      // smallest sigma^2 of the portion (velocities by sigma, accelerations by sigma^2).
      options.start_scale =
          round == 0 ? first_scale : std::pow(*std::min_element(sigma[p].begin(), sigma[p].end()), 2) * first_scale;
      JerkTiming jt = optimise_jerk_timing(exact->grids[p], limits, starts[p], options);
      if (round == 0) out.report.objective_before += jt.report.objective_before;
      out.report.iterations += jt.report.iterations;
      if (static_cast<int>(jt.report.status) > static_cast<int>(out.report.status)) {
        out.report.status = jt.report.status;
        out.report.message = "portion " + std::to_string(p) + ": " + jt.report.message;
      }
      if (jt.report.status != OptimizerStatus::kFailed) starts[p].b = jt.b, starts[p].u = jt.u;
      profiles.push_back(jt.profile);
      out.portions.push_back(std::move(jt));
    }
    auto motion = core::assemble_motion(spec, exact->motion.portions, profiles);
    if (!motion) return tl::make_unexpected(motion.error());
    out.motion = std::move(*motion);
    out.motion.spec.duration_s = 0.0;
    out.refinements = round;
    // Every sample at the cycle rate against the real limits, as plan_time_optimal checks
    // the sweep's; where one breaks a limit, that interval's limits tighten and the NLP runs
    // again from its last result.
    if (cancelled()) return tl::make_unexpected(stopped());
    // With the call's token (exact_stoppable): the check stops within 256 samples of it.
    auto check = core::check_time_optimal_samples(path, orientation, out.motion, exact->grids, checked, robot, seed,
                                                  exact_stoppable);
    if (!check) return tl::make_unexpected(check.error());
    out.worst_sample_usage = check->worst_usage;
    out.check_rate_hz = check->check_rate_hz;
    if (!check->broken) break;
    if (round >= exact_options.max_refinements)
      return tl::make_unexpected(core::Violations{core::unattainable(
          "motion", "the sampled jerk-limited motion still exceeds a limit by " +
                        core::number(100.0 * (check->worst_usage - 1.0), 6) + " % after " + std::to_string(round) +
                        " refinements (" + check->worst + "): use a finer grid")});
    for (std::size_t p = 0; p < P; ++p)
      for (std::size_t i = 0; i < sigma[p].size(); ++i) {
        sigma[p][i] *= check->shrink[p][i];
        jerk_sigma[p][i] *= check->jerk_shrink[p][i];
      }
  }
  out.report.objective_after = 0.0;
  for (const JerkTiming& jt : out.portions) out.report.objective_after += jt.report.objective_after;
  // The grid error of the duration: the same programme, limits and tightenings on every
  // second grid point (no sample check), against the result.
  double half_duration = 0.0;
  for (std::size_t p = 0; p < P && std::isfinite(half_duration); ++p) {
    if (cancelled()) return tl::make_unexpected(stopped());
    const auto& grid = exact->grids[p];
    std::vector<core::GridPoint> half;
    JerkTimingOptions ho = options;
    ho.limit_scale.clear();
    ho.jerk_scale.clear();
    for (const std::size_t i : core::every_second_point(grid.size())) {
      half.push_back(grid[i]);
      ho.limit_scale.push_back(sigma[p][i]);
      ho.jerk_scale.push_back(jerk_sigma[p][i]);
    }
    auto start = half.size() >= 3 ? core::solve_time_optimal(half, limits) : core::Expected<core::TimeOptimalSolution>();
    if (half.size() < 3 || !start) {
      half_duration = kInf;
      break;
    }
    ho.start_scale = std::pow(*std::min_element(ho.limit_scale.begin(), ho.limit_scale.end()), 2) * first_scale;
    ho.time_budget_s =
        std::max(1e-3, budget - std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    const JerkTiming jt = optimise_jerk_timing(half, limits, *start, ho);
    half_duration = jt.report.status == OptimizerStatus::kConverged ? half_duration + jt.duration : kInf;
  }
  out.duration_grid_error = std::isfinite(half_duration) ? std::abs(half_duration - out.motion.duration_s) : 0.0;
  out.report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.exact = std::move(*exact);
  return out;
}

}  // namespace geotraj::optim
