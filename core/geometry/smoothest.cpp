#include "core/geometry/smoothest.hpp"

#include <array>
#include <cmath>
#include <string>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "core/geometry/bezier.hpp"

namespace geotraj::core {

using Eigen::Vector3d;

namespace {

constexpr int kDegree = 9;     // n0 = n1 = 4 (App. B.2)
constexpr int kSlots = 10;     // end data of one segment: p, p', .., p'''' at u = 0, then at u = 1
constexpr int kDenseUnknowns = 64;  // up to this many unknowns, a dense LDLT (see fill_smoothest)
using SlotMatrix = Eigen::Matrix<double, kSlots, kSlots>;

// M with  integral_0^1 |d^r p/du^r|^2 du = sum_ab M_ab J_a . J_b  for the degree 9 segment
// whose end data are J_0..J_4 (p and its derivatives at u = 0) and J_5..J_9 (at u = 1).
// The Bernstein coefficients are linear in the end data (hermite_control_points), the r-th
// derivative has the coefficients d!/(d-r)! Delta^r b on the degree m = d - r basis, whose
// Gram matrix is exact: integral B_i,m B_j,m = C(m,i) C(m,j) / ((2m+1) C(2m, i+j)).
SlotMatrix energy_matrix(int r) {
  const int m = kDegree - r;
  // A: end data (one axis) -> control points.
  Eigen::Matrix<double, kSlots, kSlots> A;
  for (int a = 0; a < kSlots; ++a) {
    std::array<double, kMaxJetOrder + 1> start{}, end{};
    (a < 5 ? start[a] : end[a - 5]) = 1.0;
    std::array<double, kMaxBezierDegree + 1> b{};
    hermite_control_points(start, 4, end, 4, b);
    for (int i = 0; i < kSlots; ++i) A(i, a) = b[i];
  }
  // D: control points -> coefficients of the r-th derivative.
  Eigen::MatrixXd D = Eigen::MatrixXd::Identity(kSlots, kSlots);
  for (int k = 0; k < r; ++k) {
    const int rows = static_cast<int>(D.rows()) - 1;
    Eigen::MatrixXd next(rows, kSlots);
    for (int i = 0; i < rows; ++i) next.row(i) = (kDegree - k) * (D.row(i + 1) - D.row(i));
    D = next;
  }
  Eigen::MatrixXd G(m + 1, m + 1);
  for (int i = 0; i <= m; ++i)
    for (int j = 0; j <= m; ++j) G(i, j) = binomial(m, i) * binomial(m, j) / ((2 * m + 1) * binomial(2 * m, i + j));
  const Eigen::MatrixXd Q = D.transpose() * G * D;
  SlotMatrix M = A.transpose() * Q * A;
  return 0.5 * (M + M.transpose());
}

const SlotMatrix& energy_matrix_cached(int r) {
  static const std::array<SlotMatrix, 3> kMatrices = {energy_matrix(2), energy_matrix(3), energy_matrix(4)};
  GEOTRAJ_CHECK(r >= 2 && r <= 4);
  return kMatrices[static_cast<std::size_t>(r - 2)];
}

// One scalar component of one derivative: c + sum coef * x[var].
struct Affine {
  double c = 0.0;
  std::array<std::pair<int, double>, 2> terms{};
  int count = 0;
  void add(int var, double coef) {
    GEOTRAJ_CHECK(count < 2);
    terms[static_cast<std::size_t>(count++)] = {var, coef};
  }
};

// The unknown parts of one side: derivative k = 2..4 (index k - 2), component along e1, e2.
struct SideUnknowns {
  Vector3d e1 = Vector3d::Zero(), e2 = Vector3d::Zero();
  std::array<std::array<Affine, 2>, 3> slot;
  std::array<std::array<bool, 2>, 3> free{};
  Vector3d tangential[3];  // the fixed tangential part of each derivative (zero from Chapter 5)
};

// Which components of one side the frame's constraints leave free (see the header).
SideUnknowns classify(const KeyFrame& f, const SideConstraints& side) {
  SideUnknowns s;
  const Vector3d& T = side.T;
  if (side.N.squaredNorm() > 0.0) {
    s.e1 = side.N;
  } else {
    s.e1 = T.unitOrthogonal();
  }
  s.e2 = T.cross(s.e1);
  const bool curved = f.kappa && *f.kappa > 0.0;
  // p''
  s.free[0][0] = !f.kappa;
  s.free[0][1] = !f.kappa && !f.N_W;
  // p'''
  s.free[1][0] = !(curved && f.kappa_d);
  // A normal without a curvature also holds the osculating plane at the frame: B . p''' = 0,
  // so tau = B . p''' / (kappa |p'|^3) = 0 there (see the header).
  s.free[1][1] = !(curved && f.tau) && !(f.N_W && !f.kappa);
  // p''''
  s.free[2][0] = true;
  s.free[2][1] = !(curved && f.tau_d);
  for (int k = 0; k < 3; ++k) {
    const Vector3d d = side.order >= k + 2 ? side.d[static_cast<std::size_t>(k + 1)] : Vector3d::Zero();
    s.tangential[k] = T * T.dot(d);
    s.slot[k][0].c = s.e1.dot(d);
    s.slot[k][1].c = s.e2.dot(d);
  }
  return s;
}

bool breaks(const KeyFrame& f) { return f.cusp || f.inflection || f.stop; }

}  // namespace

void fill_thesis_zeros(std::vector<FrameConstraints>& frames) {
  for (auto& f : frames) {
    for (SideConstraints* side : {&f.approach, &f.leave}) {
      for (int k = side->order; k < 4; ++k) side->d[static_cast<std::size_t>(k)].setZero();
      side->order = 4;
    }
  }
}

Expected<void> fill_smoothest(const PathSpec& spec, std::vector<FrameConstraints>& frames, int energy_order) {
  const std::size_t n = frames.size();
  const std::size_t m = segment_count(n, spec.closed);
  GEOTRAJ_CHECK(spec.frames.size() == n && m > 0);

  // Unknowns of every side. Side 2i is the approach side of frame i, 2i + 1 its leaving side.
  std::vector<SideUnknowns> sides(2 * n);
  int vars = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const KeyFrame& f = spec.frames[i];
    const bool has_approach = spec.closed || i > 0;
    const bool has_leave = spec.closed || i + 1 < n;
    SideUnknowns& A = sides[2 * i];
    SideUnknowns& L = sides[2 * i + 1];
    A = classify(f, frames[i].approach);
    L = classify(f, frames[i].leave);
    if (!has_approach) A.free = {};
    if (!has_leave) L.free = {};
    const bool tied = has_approach && has_leave && !breaks(f);
    const double beta1 = frames[i].leave.d[0].norm() / frames[i].approach.d[0].norm();
    for (int k = 0; k < 3; ++k) {
      for (int j = 0; j < 2; ++j) {
        if (A.free[k][j]) A.slot[k][j].add(vars++, 1.0);
        if (!L.free[k][j]) continue;
        if (tied && A.free[k][j]) {
          // beta-constraints with beta2 = beta3 = beta4 = 0: the leaving derivative of order
          // k + 2 is beta1^(k+2) times the approaching one.
          L.slot[k][j].add(A.slot[k][j].terms[0].first, std::pow(beta1, k + 2));
        } else {
          L.slot[k][j].add(vars++, 1.0);
        }
      }
    }
    // Row (5.22) couples e2 . p'''' to e1 . p''' where kappa' is free:
    //   e2 . p'''' = tau'_u |C| + 2 tau |p'| (e1 . p'''),  |C| = kappa |p'|^3,
    // with C = |C| e2 and C . (p' x p''') = |C| |p'| (e1 . p''').
    // The thesis's value of e2 . p'''' took e1 . p''' = 0 there (no kappa' row), so only the
    // coupling terms are added.
    if (f.tau_d && f.kappa && *f.kappa > 0.0 && f.tau) {
      const auto couple = [&](SideUnknowns& side, const SideConstraints& constraints) {
        if (!side.free[1][0]) return;
        const double coupling = 2.0 * *f.tau * constraints.d[0].norm();
        const Affine& source = side.slot[1][0];
        for (int t = 0; t < source.count; ++t) {
          const auto& [var, coef] = source.terms[static_cast<std::size_t>(t)];
          side.slot[2][1].add(var, coupling * coef);
        }
      };
      if (has_approach) couple(A, frames[i].approach);
      if (has_leave) couple(L, frames[i].leave);
    }
  }
  if (vars == 0) {
    fill_thesis_zeros(frames);
    return {};
  }

  // Assemble H x = -g from E = sum_ab M_ab (f_a + W_a x) . (f_b + W_b x).
  const SlotMatrix& M = energy_matrix_cached(energy_order);
  struct Term {
    int var = 0;
    Vector3d w = Vector3d::Zero();
  };
  struct SlotData {
    Vector3d f = Vector3d::Zero();
    std::array<Term, 4> terms{};
    int count = 0;
  };
  // Small systems (the usual few frames) are assembled dense and factorised by a dense LDLT:
  // the sparse path's ordering and symbolic analysis cost more than the whole dense solve
  // below about 64 unknowns (bench_core's BuildDemoPath, docs/performance.md).
  const bool dense = vars <= kDenseUnknowns;
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::MatrixXd Hd;
  if (dense) {
    Hd = Eigen::MatrixXd::Zero(vars, vars);
  } else {
    triplets.reserve(m * 400);
  }
  Eigen::VectorXd g = Eigen::VectorXd::Zero(vars);
  std::array<SlotData, kSlots> slot;
  for (std::size_t s = 0; s < m; ++s) {
    const std::size_t to = (s + 1) % n;
    const auto fill_end = [&](int base, const FrameConstraints& fc, const SideConstraints& side,
                              const SideUnknowns& u) {
      slot[static_cast<std::size_t>(base)] = SlotData{fc.p_W, {}, 0};
      slot[static_cast<std::size_t>(base + 1)] = SlotData{side.d[0], {}, 0};
      for (int k = 0; k < 3; ++k) {
        SlotData& sd = slot[static_cast<std::size_t>(base + 2 + k)];
        sd = SlotData{};
        sd.f = u.tangential[k];
        for (int j = 0; j < 2; ++j) {
          const Affine& a = u.slot[k][j];
          const Vector3d& e = j == 0 ? u.e1 : u.e2;
          sd.f += a.c * e;
          for (int t = 0; t < a.count; ++t) {
            const auto& [var, coef] = a.terms[static_cast<std::size_t>(t)];
            sd.terms[static_cast<std::size_t>(sd.count++)] = Term{var, coef * e};
          }
        }
      }
    };
    fill_end(0, frames[s], frames[s].leave, sides[2 * s + 1]);
    fill_end(5, frames[to], frames[to].approach, sides[2 * to]);
    for (int a = 0; a < kSlots; ++a) {
      const SlotData& sa = slot[static_cast<std::size_t>(a)];
      for (int t = 0; t < sa.count; ++t) {
        const Term& ta = sa.terms[static_cast<std::size_t>(t)];
        for (int b = 0; b < kSlots; ++b) {
          const SlotData& sb = slot[static_cast<std::size_t>(b)];
          const double mab = M(a, b);
          g(ta.var) += mab * ta.w.dot(sb.f);
          for (int q = 0; q < sb.count; ++q) {
            const Term& tb = sb.terms[static_cast<std::size_t>(q)];
            if (dense) {
              Hd(ta.var, tb.var) += mab * ta.w.dot(tb.w);
            } else {
              triplets.emplace_back(ta.var, tb.var, mab * ta.w.dot(tb.w));
            }
          }
        }
      }
    }
  }
  const auto singular = [] {
    return tl::unexpected(Violations{{"unspecified",
                                      "the smoothest curve through these frames cannot be computed in double precision "
                                      "(its linear system is singular); choose THESIS_ZEROS or LOWEST_DEGREE"}});
  };
  // Jacobi scaling: the unknowns are derivatives of orders 2 to 4 of segments of any
  // length, so the diagonal spans many decades; unscaled, the factorisation loses digits.
  Eigen::VectorXd scale(vars);
  Eigen::VectorXd y;
  if (dense) {
    for (int v = 0; v < vars; ++v) {
      const double d = Hd(v, v);
      scale(v) = d > 0.0 && std::isfinite(d) ? 1.0 / std::sqrt(d) : 1.0;
    }
    const Eigen::MatrixXd Hs = scale.asDiagonal() * Hd * scale.asDiagonal();
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(Hs);
    const Eigen::VectorXd rhs = -scale.cwiseProduct(g);
    // A zero pivot is a singular system (the sparse factorisation divides by it; the dense
    // one would quietly drop the direction): refused alike.
    const bool ok = ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > 0.0;
    if (ok) y = ldlt.solve(rhs);
    if (!ok || !y.allFinite()) return singular();
    y += ldlt.solve(rhs - Hs * y);  // one step of iterative refinement
  } else {
    Eigen::SparseMatrix<double> H(vars, vars);
    H.setFromTriplets(triplets.begin(), triplets.end());
    for (int v = 0; v < vars; ++v) {
      const double d = H.coeff(v, v);
      scale(v) = d > 0.0 && std::isfinite(d) ? 1.0 / std::sqrt(d) : 1.0;
    }
    const Eigen::SparseMatrix<double> Hs = scale.asDiagonal() * H * scale.asDiagonal();
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Hs);
    const Eigen::VectorXd rhs = -scale.cwiseProduct(g);
    if (ldlt.info() == Eigen::Success) y = ldlt.solve(rhs);
    if (ldlt.info() != Eigen::Success || !y.allFinite()) return singular();
    y += ldlt.solve(rhs - Hs * y);  // one step of iterative refinement
  }
  const Eigen::VectorXd x = scale.cwiseProduct(y);

  for (std::size_t i = 0; i < n; ++i) {
    for (int which = 0; which < 2; ++which) {
      SideConstraints& side = which == 0 ? frames[i].approach : frames[i].leave;
      const SideUnknowns& u = sides[2 * i + static_cast<std::size_t>(which)];
      for (int k = 0; k < 3; ++k) {
        Vector3d d = u.tangential[k];
        for (int j = 0; j < 2; ++j) {
          const Affine& a = u.slot[k][j];
          double value = a.c;
          for (int t = 0; t < a.count; ++t) value += a.terms[static_cast<std::size_t>(t)].second * x(a.terms[static_cast<std::size_t>(t)].first);
          d += value * (j == 0 ? u.e1 : u.e2);
        }
        side.d[static_cast<std::size_t>(k + 1)] = d;
      }
      side.order = 4;
    }
  }
  return {};
}

double path_energy(const PathSpec& spec, const std::vector<FrameConstraints>& frames, int energy_order) {
  const SlotMatrix& M = energy_matrix_cached(energy_order);
  const std::size_t n = frames.size();
  const std::size_t m = segment_count(n, spec.closed);
  double e = 0.0;
  for (std::size_t s = 0; s < m; ++s) {
    const FrameConstraints& a = frames[s];
    const FrameConstraints& b = frames[(s + 1) % n];
    std::array<Vector3d, kSlots> J;
    J[0] = a.p_W;
    J[5] = b.p_W;
    for (int k = 0; k < 4; ++k) {
      J[static_cast<std::size_t>(1 + k)] = a.leave.order > k ? a.leave.d[static_cast<std::size_t>(k)] : Vector3d::Zero();
      J[static_cast<std::size_t>(6 + k)] = b.approach.order > k ? b.approach.d[static_cast<std::size_t>(k)] : Vector3d::Zero();
    }
    for (int i = 0; i < kSlots; ++i)
      for (int j = 0; j < kSlots; ++j) e += M(i, j) * J[static_cast<std::size_t>(i)].dot(J[static_cast<std::size_t>(j)]);
  }
  return e;
}

}  // namespace geotraj::core
