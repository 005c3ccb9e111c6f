// The tool ORIENTATION along a blended path (thesis 6.3.3, Table 6.3, 7.3.2).
//
// Tool frame convention, thesis Eq. (6.21): R_WT = [-B N T]: the tool's z axis along the
// curve's unit tangent T, its y axis along the principal normal N, its x axis = y x z = -B.
// q_WT is the unit quaternion of R_WT (tool frame T expressed in the world frame W).
//
// Each segment i (frame i leaving -> frame i+1 approach, or frame 0 for the last segment of a
// closed path) turns the tool by frames[i].orientation_mode:
//   kFixed              keep the orientation the segment starts with; omega_W = alpha_W = 0.
//   kFrameBased         SLERP (6.18, errata of 6.2) from the start orientation to key frame
//                       i+1's [-B N T] (its tangent and normal; where the frame gives no
//                       normal, the normal measured on the blended curve there, see
//                       core::achieved_geometry; a straight curve there is an error).
//   kCustom             SLERP from the start orientation to KeyFrame::orientation.
//   kFrenet             the curve's Frenet frame [-B N T] (6.21) at every point; omega_W is
//                       the Darboux vector times the speed, s_dot (tau T + kappa B) (6.22).
//                       The curvature must not vanish anywhere on the segment.
//   kParallelTransport  a rotation-minimising frame (7.22): no twist about the tangent,
//                       omega_W = s_dot kappa B. Started from the orientation at the segment
//                       start, re-aligned by the minimal rotation so that its z axis is the
//                       tangent, and integrated as rotations (the double-reflection method of
//                       Wang, Juttler, Zheng and Liu, ACM TOG 27(1), 2008; erratum of Eq.
//                       2.35: no explicit Euler step) on an adaptive grid of u precomputed by
//                       plan_orientation (the tangent turns at most kOrientationGridTurn
//                       between grid points). orientation_at carries each neighbouring grid
//                       frame to the exact point and tangent at u by one more double
//                       reflection and SLERPs between the two (they differ by a tiny twist
//                       about the common z axis), so z is the tangent exactly, the result is
//                       continuous and does not depend on the sample rate. It does not flip
//                       where the curvature vanishes.
//
// SLERP progress follows the arc length, sigma = (s - s_i) / L_i (s_i: arc length at the
// segment start, L_i its length), so the tool turns at a rate proportional to the path
// speed: q(sigma) = exp(sigma theta a / 2) q_start with the world-frame axis a and angle
// theta in [0, pi] of q_end q_start^-1 (the shorter way round), and
// omega_W = a theta sigma_dot, sigma_dot = s_dot / L_i; the axis is fixed, so
// alpha_W = a theta sigma_ddot, sigma_ddot = s_ddot / L_i.
// Eased SLERP (KeyFrame::ease_orientation): the progress is h(sigma) = 10 sigma^3 -
// 15 sigma^4 + 6 sigma^5 (h' = 30 sigma^2 (1 - sigma)^2, h'' = 60 sigma (1 - sigma)(1 - 2 sigma)),
// q = exp(h theta a / 2) q_start, omega_W = a theta h' sigma_dot,
// alpha_W = a theta (h'' sigma_dot^2 + h' sigma_ddot): zero at both ends of the segment, so
// eased and fixed segments join with continuous omega and alpha (plain SLERP segments do not:
// omega changes at the frame while the path moves).
//
// Angular acceleration alpha_W = d omega_W / dt [rad/s^2] (needed for joint accelerations,
// joint_motion.hpp), analytic in every mode, with s_dot = ds/dt and s_ddot = d2s/dt2 of the
// motion and the Frenet apparatus of the curve (T, N, B, kappa, tau, kappa_s = dkappa/ds,
// tau_s = dtau/ds; Frenet-Serret T_s = kappa N, N_s = -kappa T + tau B, B_s = -tau N):
//   SLERP modes         alpha_W = s_ddot (theta / L_i) a
//   kFrenet             alpha_W = s_ddot (tau T + kappa B) + s_dot^2 (tau_s T + kappa_s B)
//                       (d/ds of the Darboux vector: the tau kappa N terms cancel)
//   kParallelTransport  alpha_W = s_ddot kappa B + s_dot^2 (kappa_s B - kappa tau N)
//                       (d/ds of kappa B); where the curve is straight to rounding (no
//                       normal) kappa B = p' x p'' / |p'|^3 vanishes and its arc-length
//                       derivative is its limit (p' x p''') / |p'|^4, finite through an
//                       inflection.
//   kFixed              0.
//
// The orientation at the start of the path is key frame 0's [-B N T] (normal as for
// kFrameBased). Deviation: when segment 0 is kFrenet the path starts in the curve's Frenet
// frame, as that mode defines (the frames differ when frame 0 gives a normal but no
// curvature). Where frame 0 defines no [-B N T] (no normal, and the curve is straight
// there) and segment 0 is kFixed, kFrameBased or kCustom (modes that take any start), the
// tool starts in `start_W`: the robot's tool orientation at its initial joints, or the
// world axes (identity) without a robot. kParallelTransport needs the tool's z along the
// tangent and a twist about it, so there a normal stays required. Frame 0 kFixed with an
// `orientation` holds the tool as it says, and a path of pieces (pieces.hpp) whose `start`
// is kFixed without one as the robot starts (`start_W`), whatever the curve does there: a
// nozzle keeps pointing down on a curved start.
//
// Continuity: each segment starts where the previous one ended. For the tangent-following
// modes (kFrenet, kParallelTransport) that is a condition, not a construction: where the
// orientation the previous segment ends with differs from the mode's frame at the segment
// start by more than kOrientationJoinTolerance, plan_orientation reports the jump as a
// violation of `frames[i].orientationMode` (the tool cannot turn instantly).
//
// Cusps (thesis 5.6.2): the tangent inverts on the leaving side while the motion is at
// rest. The tangent-following modes keep the tool's z axis along the key frames' T
// direction, not the direction of motion: after an odd number of cusps (counted over the
// frames 0..i that segment i leaves or has passed) the tool frame is [-B N T] Ry(pi) =
// [B N -T] (a rotation of pi about the tool y axis), so the orientation is continuous
// through the cusp. The angular velocity vectors are the same with the flip (a constant
// right factor does not change omega_W).
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/error.hpp"
#include "core/geometry/key_frame.hpp"
#include "core/geometry/path.hpp"

namespace geotraj::core {

/// Largest instantaneous turn of the tool [rad] accepted where a tangent-following segment
/// joins the previous one (rounding of the frames at a C2 join is far below it).
inline constexpr double kOrientationJoinTolerance = 1e-6;

/// Largest turn [rad] of the tangent (kParallelTransport) or of the Frenet frame (kFrenet)
/// between two neighbouring points of a segment's orientation grid.
inline constexpr double kOrientationGridTurn = 0.02;

/// The precomputed orientation of one segment.
struct SegmentOrientation {
  OrientationMode mode = OrientationMode::kFixed;
  Eigen::Quaterniond q_start = Eigen::Quaterniond::Identity();  ///< R_WT at the segment start
  Eigen::Quaterniond q_end = Eigen::Quaterniond::Identity();    ///< R_WT at the segment end
  /// SLERP modes: q_end q_start^-1 = exp(theta a / 2), a in W (unit, or zero when theta = 0).
  Eigen::Vector3d axis_W = Eigen::Vector3d::Zero();
  double theta = 0.0;  ///< [rad], in [0, pi]
  bool eased = false;  ///< SLERP modes: progress h(sigma), the quintic ease (above)
  /// kFrenet, kParallelTransport: an odd number of cusps precedes, the tool z is -T.
  bool flipped = false;
  /// kParallelTransport (and kFrenet, as a fallback): R_WT, the point p [m] and the unit
  /// tangent T of the curve (all in W) at increasing local u in [0, 1].
  std::vector<double> grid_u;
  std::vector<Eigen::Quaterniond> grid_q;
  std::vector<Eigen::Vector3d> grid_p;
  std::vector<Eigen::Vector3d> grid_T;
};

/// The tool's roll about its own z axis along the path, phi(s) [rad] a function of the arc
/// length s [m] from the path's start (RobotSpec.toolAxisFree: a tool symmetric about its
/// axis; chosen by the planner): the natural cubic spline through phi_m at s_m = m L / M,
/// m = 0 .. M (phi'' = 0 at both ends), constant beyond [0, L]. A function of s, so the
/// timings see it: at s_dot, s_ddot the roll's rate is phi_s s_dot and its acceleration
/// phi_ss s_dot^2 + phi_s s_ddot.
class RollProfile {
 public:
  /// At least 2 finite values, length L > 0 [m] (preconditions, checked).
  RollProfile(std::vector<double> phi, double length);
  /// phi [rad], dphi/ds [rad/m], d2phi/ds2 [rad/m^2] at s [m]. No heap allocation.
  void at(double s, double& phi, double& phi_s, double& phi_ss) const;
  double length() const { return h_ * static_cast<double>(phi_.size() - 1); }

 private:
  std::vector<double> phi_;
  std::vector<double> m_;  // second derivatives at the knots
  double h_;
};

/// The orientation of a whole path, one entry per segment of the path it was planned for.
struct OrientationPlan {
  std::vector<SegmentOrientation> segments;
  /// The roll chosen about the tool's z axis, or null (the orientation as planned):
  /// orientation_at turns the planned R_WT to R_WT RotZ(phi(s)) (turn_about_tool_axis).
  std::shared_ptr<const RollProfile> roll = nullptr;
};

/// R turned about its own z axis by phi(t) [rad], phi_dot [rad/s], phi_ddot [rad/s^2], with
/// its angular velocity omega and acceleration alpha in W: R' = R RotZ(phi), so the axis
/// z = R e_z = R' e_z is kept; omega' = omega + phi_dot z (d/dt R RotZ(phi) = [omega] R' +
/// R [e_z] phi_dot RotZ(phi) = [omega + phi_dot z] R'), alpha' = alpha + phi_ddot z +
/// phi_dot (omega x z). No heap allocation.
void turn_about_tool_axis(Eigen::Matrix3d& R, Eigen::Vector3d& omega, Eigen::Vector3d& alpha, double phi,
                          double phi_dot, double phi_ddot);

/// The tool orientation at one point of the motion.
struct OrientationSample {
  Eigen::Quaterniond q_WT = Eigen::Quaterniond::Identity();  ///< R_WT, unit
  Eigen::Vector3d omega_W = Eigen::Vector3d::Zero();           ///< angular velocity in W [rad/s]
  Eigen::Vector3d alpha_W = Eigen::Vector3d::Zero();           ///< angular acceleration in W [rad/s^2]
};

/// Plans the tool orientation of every segment of `path` (thesis Table 6.3; see above).
/// Errors (field paths relative to the path's spec, proto JSON names):
///  - `frames[k].orientation`: missing with kCustom, given with another mode, not finite or
///    not of unit length (to within 1e-3; then it is normalised);
///  - `frames[k].normal`: a [-B N T] is needed at frame k (the path's start, or a kFrameBased
///    target) but the frame gives no normal and the curve is straight there;
///  - `frames[i].orientationMode`: kFrenet on a segment where the curvature vanishes (the u
///    is named), or a tangent-following segment that would start with a jump.
///  (`start_W`: the tool orientation before the motion, see the start above.)
Expected<OrientationPlan> plan_orientation(const Path& path,
                                           const Eigen::Quaterniond& start_W = Eigen::Quaterniond::Identity());

/// The tool orientation on `segment` at local parameter u_local in [0, 1], arc length s [m]
/// from the path start (the same point), path speed s_dot = ds/dt [m/s] and path
/// acceleration s_ddot = d2s/dt2 [m/s^2] (the tangential acceleration a_W . T of the
/// motion sample, see cartesian_state in joint_motion.hpp).
/// q_WT is R_WT (unit); omega_W [rad/s] and alpha_W [rad/s^2] in W, analytic (above; never
/// finite differences); with plan.roll, turned by it at s. No heap allocation.
/// Preconditions (checked): `plan` was planned for `path`, segment < path.segment_count().
OrientationSample orientation_at(const OrientationPlan& plan, const Path& path, std::size_t segment,
                                 double u_local, double s, double s_dot, double s_ddot);

/// The tool frame [-B N T] (6.21) as a unit quaternion; T and N unit and perpendicular (W).
Eigen::Quaterniond tool_frame(const Eigen::Vector3d& T_W, const Eigen::Vector3d& N_W);

}  // namespace geotraj::core
