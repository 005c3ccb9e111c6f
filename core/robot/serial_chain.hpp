// Private to geotraj_core (ik.cpp, ik_search.cpp, joint_motion.cpp): the serial chain of a RobotModel
// (robot.hpp) with its per-joint constants precomputed, evaluated with 3 x 3 rotations and
// 3-vectors (no 4 x 4 products), and the projected Newton iteration on the 6-D pose error
// that solve_ik and JointTracker share. Same conventions as kinematics.hpp (robot.hpp's chain formula, the
// geometric Jacobian, rows [v; omega] in W); fixed-size storage only, no heap allocation.
#pragma once

#include <array>
#include <cstdint>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "core/robot/ik.hpp"
#include "core/robot/robot.hpp"

namespace geotraj::core::detail {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
/// One 3-vector per joint (joint axes z_i, points o_i on them), in W.
using JointAxes = Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::ColMajor, 3, static_cast<int>(kMaxJoints)>;

/// The chain of robot.hpp, X_WT = base * O_1 M_1(q_1) ... O_n M_n(q_n) * flange * tool,
/// rewritten so that every joint moves about or along the z axis of its frame: with A_i a
/// fixed rotation taking z to the axis a_i (A_0 = I), O_i' = A_{i-1}^T O_i A_i and
/// flange' = A_n^T flange tool give the same poses with M_i about z. A revolute joint whose
/// O_i' rotation is RotX(alpha) RotZ(phi) (every DH chain, most URDF joints) carries phi
/// into its angle and turns the frame by RotX alone (4 products instead of a 3 x 3 product).
/// Built without trigonometry (for every model that a per-call entry point meets: cached_chain).
class SerialChain {
 public:
  SerialChain() = default;
  explicit SerialChain(const RobotModel& model);

  Eigen::Index dof() const { return n_; }

  /// Tool pose (R_WT, p_WT [m]) at q.
  void pose(const JointVector& q, Eigen::Matrix3d& R_WT, Eigen::Vector3d& p_WT) const;
  /// Tool pose, joint axes z_i (unit) and points o_i (W), and the geometric Jacobian
  /// (kinematics.hpp, Eq. 1.9): revolute [z_i x (p_WT - o_i); z_i], prismatic [z_i; 0].
  void jacobian(const JointVector& q, Eigen::Matrix3d& R_WT, Eigen::Vector3d& p_WT, JointAxes& z, JointAxes& o,
                JointJacobian& J) const;
  /// The full time derivative J_dot = sum_j q_dot_j dJ/dq_j (Eqs. 1.10, 1.11) from the axes
  /// and Jacobian of jacobian() at the same q, in O(n): axis i rides on the frame before it,
  /// whose angular velocity omega_i and point velocity v_o are accumulated joint by joint:
  ///   revolute column i:  [z_dot_i x (p - o_i) + z_i x (p_dot - o_dot_i); z_dot_i],
  ///   prismatic column i: [z_dot_i; 0],   z_dot_i = omega_i x z_i.
  void jacobian_dot(const Eigen::Vector3d& p_WT, const JointAxes& z, const JointAxes& o, const JointJacobian& J,
                    const JointVector& q_dot, JointJacobian& J_dot) const;

  bool revolute(Eigen::Index i) const { return links_[static_cast<std::size_t>(i)].revolute; }

 private:
  template <class OnAxis>
  void walk(const JointVector& q, Eigen::Matrix3d& R, Eigen::Vector3d& p, OnAxis&& on_axis) const;

  enum class Turn : std::uint8_t { kNone, kX, kGeneral };
  struct Link {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  ///< O_i' rotation (kGeneral)
    Eigen::Vector3d p = Eigen::Vector3d::Zero();      ///< O_i' translation [m]
    double ca = 1.0, sa = 0.0;                         ///< cos, sin of alpha (kX)
    double cphi = 1.0, sphi = 0.0;                     ///< cos, sin of phi, added to q (revolute)
    bool phi = false;                                  ///< phi is not 0
    Turn turn = Turn::kNone;
    bool revolute = true;
  };
  std::array<Link, kMaxJoints> links_{};
  Eigen::Index n_ = 0;
  Eigen::Matrix3d R_base_ = Eigen::Matrix3d::Identity(), R_tool_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_base_ = Eigen::Vector3d::Zero(), p_tool_ = Eigen::Vector3d::Zero();
};

/// The chain of `model`, as SerialChain(model) builds it, kept per thread: built again only
/// when `model`'s chain (its joints' types, origins and axes, base, flange and tool) differs
/// bit for bit from the one of the previous call on this thread, so the per-call entry
/// points (forward_kinematics, solve_ik, ...) do not rebuild it (a copy of the model
/// matches). No heap allocation. The reference is valid until the next call on this thread:
/// take it, use it, and do not hold it across another call.
const SerialChain& cached_chain(const RobotModel& model);

/// Position limits of every joint, and their midpoints and ranges (the null-space cost).
struct JointBounds {
  std::array<double, kMaxJoints> lo{}, hi{}, mid{}, range{};
  std::array<bool, kMaxJoints> revolute{};
  JointBounds() = default;
  explicit JointBounds(const RobotModel& model);
};

/// The JointBounds of `model`, kept per thread as cached_chain keeps its chain (built again
/// when the joints' types or position limits differ bit for bit from the previous call's).
/// The reference is valid until the next call on this thread.
const JointBounds& cached_bounds(const RobotModel& model);

/// The rotation vector (angle [rad] in [0, pi] times the unit axis) of R, by the quaternion
/// (Shepperd's method inside Eigen): accurate near 0 and near pi.
Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& R);

/// Scratch of the Newton iteration; after newton() it holds the pose, axes and Jacobian at
/// the returned q.
struct NewtonWorkspace {
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  JointAxes z, o;
  JointJacobian J;
  Matrix6d A;
  Eigen::LLT<Matrix6d> llt;
};

struct NewtonOutcome {
  bool converged = false;
  int iterations = 0;
  double position_error = 0.0;     ///< [m]
  double orientation_error = 0.0;  ///< [rad]
};

/// Factors A = J W J^T (W = diag(active), 0 for joints held at a bound) into ws.llt,
/// damped with lambda^2 = kSingularPivot (1 - p_min / kSingularPivot)^2 I only where the
/// smallest Cholesky pivot p_min of the undamped matrix falls below kSingularPivot
/// (a pivot bounds the smallest eigenvalue from above: pivots >= lambda_min(A)).
/// Returns the product of the undamped pivots' square roots, sqrt(det(J W J^T)) (0 when
/// the undamped factorisation fails).
double factor(const JointJacobian& J, const std::array<bool, kMaxJoints>* active, NewtonWorkspace& ws);

/// Smallest Cholesky pivot of J J^T [m^2 / rad^2 mixed, the arm being ~1 m] below which the
/// steps are damped: sigma_min ~ 1e-4.
inline constexpr double kSingularPivot = 1e-8;
/// Halvings of a step that does not reduce the error before it is taken anyway.
inline constexpr int kMaxHalvings = 4;

/// Newton-Raphson on the pose error e = [p_target - p; rotation_vector(R_target R^T)] from q
/// (in/out): steps dq = W J^T (J W J^T)^-1 e (minimum norm; damped only near singularities,
/// see factor()), scaled so that max |dq_i| <= max_step, then projected onto the bounds.
/// A joint at a bound whose step points outwards is held there for that step (W_ii = 0).
/// A step that increases |e|^2 (m^2 + rad^2, the arm being ~1 m) is halved, at most
/// kMaxHalvings times, then taken anyway; every evaluation counts as an iteration.
/// `wrap`: a revolute joint whose range spans at least 2 pi (every angle has a
/// representative inside) and that leaves it is first moved by 2 pi back inside (cold
/// solves only; never while tracking, where it would be a jump). A narrower range is a
/// wall: the joint is held at it (wrapping across the excluded gap would strand it far
/// from the solution on the other side).
NewtonOutcome newton(const SerialChain& chain, const JointBounds& bounds, const Eigen::Matrix3d& R_target,
                     const Eigen::Vector3d& p_target, const IkOptions& options, bool wrap, JointVector& q,
                     NewtonWorkspace& ws);

/// Deterministic uniform numbers in [0, 1) (SplitMix64): the same restarts on every platform.
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  double uniform() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * 0x1.0p-53;
  }

 private:
  std::uint64_t state_;
};

/// q (its size set) uniform within the bounds.
void random_configuration(const JointBounds& bounds, SplitMix64& random, JointVector& q);

/// closest_pose's Levenberg-Marquardt on a prepared chain (ik.hpp), from q (within bounds).
NewtonOutcome refine_closest_pose(const SerialChain& chain, const JointBounds& bounds, const Eigen::Matrix3d& R_target,
                                  const Eigen::Vector3d& p_target, int max_iterations, JointVector& q,
                                  NewtonWorkspace& ws);

/// search_ik on a prepared chain (ik.hpp).
IkSearchResult search(const SerialChain& chain, const JointBounds& bounds, const Eigen::Matrix3d& R_target,
                      const Eigen::Vector3d& p_target, const JointVector& seed, const IkSearchOptions& options);

/// A cold solve: newton() from the seed (clamped into the bounds, wrap on), then, while it
/// fails, from up to options.restarts configurations uniform within the bounds (fixed
/// seed). The best attempt (smallest position + orientation error) is returned in q.
NewtonOutcome solve_cold(const SerialChain& chain, const JointBounds& bounds, const Eigen::Matrix3d& R_target,
                         const Eigen::Vector3d& p_target, const JointVector& seed, const IkOptions& options,
                         JointVector& q, NewtonWorkspace& ws);

}  // namespace geotraj::core::detail
