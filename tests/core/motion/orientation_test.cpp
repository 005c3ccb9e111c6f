// Tool orientation along a blended path (thesis 6.3.3, Table 6.3, 7.3.2): every mode on a
// helix, a circle, a straight line and the thesis demo path C (Table 7.8, with its cusp);
// unit quaternions, continuity along the path and across frames and cusps, Frenet frames
// against local_geometry, parallel transport (z on the tangent, no twist, no flip through a
// straight stretch), SLERP targets at segment ends, angular velocity against central
// differences, angular acceleration against central differences of the angular velocity
// along a timed motion, the errors that name their field, and no heap allocation per sample.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "core/geometry/arc_length.hpp"
#include "core/geometry/differential_geometry.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "test_support.hpp"
#include "thesis_paths.hpp"

namespace geotraj::test {
namespace {

using core::OrientationMode;
using core::OrientationPlan;
using core::OrientationSample;
using core::Path;
using Eigen::Quaterniond;

constexpr double kPi = 3.14159265358979323846;

const char* name(OrientationMode m) {
  switch (m) {
    case OrientationMode::kFixed: return "Fixed";
    case OrientationMode::kFrameBased: return "FrameBased";
    case OrientationMode::kCustom: return "Custom";
    case OrientationMode::kFrenet: return "Frenet";
    case OrientationMode::kParallelTransport: return "ParallelTransport";
  }
  return "?";
}

/// The custom target of frame k: some rotation well away from the others.
Quaterniond custom_target(std::size_t k) {
  return Quaterniond(Eigen::AngleAxisd(0.4 + 0.5 * static_cast<double>(k), Vector3d(1, 2, 3).normalized()));
}

/// Every frame's mode set to `mode` (and a custom orientation where the mode needs one).
core::PathSpec with_mode(core::PathSpec spec, OrientationMode mode) {
  for (std::size_t k = 0; k < spec.frames.size(); ++k) {
    spec.frames[k].orientation_mode = mode;
    spec.frames[k].orientation.reset();
    if (mode == OrientationMode::kCustom) spec.frames[k].orientation = custom_target(k);
  }
  return spec;
}

// Helix (r cos t, r sin t, c t): kappa = r/(r^2+c^2), tau = c/(r^2+c^2), frames every 1.2 rad.
core::PathSpec helix_spec() {
  const double r = 0.2, c = 0.05, rc = r * r + c * c, dt = 1.2;
  std::vector<core::KeyFrame> frames;
  for (int k = 0; k < 4; ++k) {
    const double t = dt * k;
    frames.push_back(Frame({r * std::cos(t), r * std::sin(t), c * t},
                           Vector3d(-r * std::sin(t), r * std::cos(t), c) / std::sqrt(rc))
                         .normal({-std::cos(t), -std::sin(t), 0})
                         .curvature(r / rc)
                         .torsion(c / rc)
                         .curvature_derivative(0)
                         .torsion_derivative(0)
                         .scale(std::sqrt(rc) * dt));
  }
  return make_spec(frames);
}

// Circle of radius 0.3 m in the xy plane, frames every 60 degrees (kappa = 1/R, tau = 0).
core::PathSpec circle_spec() {
  const double R = 0.3, dt = kPi / 3;
  std::vector<core::KeyFrame> frames;
  for (int k = 0; k < 4; ++k) {
    const double t = dt * k;
    frames.push_back(Frame({R * std::cos(t), R * std::sin(t), 0}, {-std::sin(t), std::cos(t), 0})
                         .normal({-std::cos(t), -std::sin(t), 0})
                         .curvature(1 / R)
                         .torsion(0)
                         .scale(R * dt));
  }
  return make_spec(frames);
}

// A straight line along x, with normals (no curvature) so that [-B N T] is defined.
core::PathSpec line_spec(bool normals = true) {
  std::vector<core::KeyFrame> frames;
  for (int k = 0; k < 3; ++k) {
    Frame f({0.5 * k, 0, 0}, {1, 0, 0});
    f.scale(0.5);
    if (normals) f.normal({0, 1, 0});
    frames.push_back(f);
  }
  return make_spec(frames);
}

// Curved, then exactly straight (segment 1: colinear frames, kappa = 0 at both ends), then
// curved out of the plane.
core::PathSpec straight_stretch_spec() {
  return make_spec({Frame({0, 0, 0}, {1, 0, 0}).normal({0, 1, 0}).curvature(2).torsion(0),
                    Frame({1, 0, 0}, {1, 0, 0}).curvature(0), Frame({2, 0, 0}, {1, 0, 0}).curvature(0),
                    Frame({2.6, 0.1, 0.4}, Vector3d(0.6, 0, 0.8)).normal(Vector3d(-0.8, 0, 0.6)).curvature(1.5)});
}

/// One sample of the orientation with where it was taken.
struct Sampled {
  std::size_t segment;
  double u, s;
  OrientationSample o;
};

/// `per_segment` + 1 samples per segment, uniform in u, at s_dot [m/s].
std::vector<Sampled> sample_path(const Path& path, const OrientationPlan& plan, int per_segment, double s_dot) {
  std::vector<Sampled> out;
  for (std::size_t i = 0; i < path.segment_count(); ++i) {
    double s = path.cumulative_lengths[i], prev = 0.0;
    for (int k = 0; k <= per_segment; ++k) {
      const double u = static_cast<double>(k) / per_segment;
      s += core::segment_arc_length(path.segments[i], prev, u);
      prev = u;
      out.push_back({i, u, s, core::orientation_at(plan, path, i, u, s, s_dot, 0.0)});
    }
  }
  return out;
}

/// Rotation vector of q (angle in [0, pi]) [rad].
Vector3d rotation_vector(Quaterniond q) {
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const double sh = q.vec().norm();
  return sh > 0 ? Vector3d(q.vec() / sh * 2.0 * std::atan2(sh, q.w())) : Vector3d::Zero();
}

core::LocalGeometry geometry(const Path& path, std::size_t i, double u) {
  core::Jet jet;
  core::evaluate(path.segments[i], u, 4, jet);
  return core::local_geometry(jet, path.p_uu_noise[i]);
}

/// Checks that hold for every mode: unit quaternions; continuity (the turn between
/// neighbouring samples bounded by the angular speed times the time step, with s_dot = 1);
/// the end of each segment equals the start of the next. Returns the samples.
std::vector<Sampled> check_common(const Path& path, const OrientationPlan& plan, const std::string& what) {
  const auto samples = sample_path(path, plan, 1500, 1.0);
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const auto& a = samples[k];
    EXPECT_NEAR(a.o.q_WT.norm(), 1.0, 1e-13) << what << " segment " << a.segment << " u " << a.u;
    if (k == 0) continue;
    const auto& b = samples[k - 1];
    const double turn = a.o.q_WT.angularDistance(b.o.q_WT);
    if (a.segment != b.segment) {
      EXPECT_LT(turn, 1e-9) << what << ": jump of " << turn << " rad at frame " << a.segment;
      continue;
    }
    // With s_dot = 1 m/s, |omega| [rad/s] is the turn per metre of arc.
    const double rate = std::max(a.o.omega_W.norm(), b.o.omega_W.norm());
    EXPECT_LE(turn, 1.5 * rate * (a.s - b.s) + 1e-9)
        << what << ": segment " << a.segment << " u " << a.u << " turn " << turn << " rate " << rate;
  }
  return samples;
}

/// omega_W against central differences of q in time: t = s / s_dot, step h = 1e-5 in u.
/// Tolerance 1e-6 rad/s + 1e-5 relative: the difference error is O(h^2) times the second
/// derivative of omega (and the arc-length quadrature is accurate to 1e-12 relative).
void check_angular_velocity(const Path& path, const OrientationPlan& plan, const std::string& what) {
  const double s_dot = 0.7, h = 1e-5;
  for (std::size_t i = 0; i < path.segment_count(); ++i) {
    for (const double u : {0.13, 0.5, 0.77}) {
      const double s0 = path.cumulative_lengths[i] + core::segment_arc_length(path.segments[i], 0.0, u);
      const double sm = s0 - core::segment_arc_length(path.segments[i], u - h, u);
      const double sp = s0 + core::segment_arc_length(path.segments[i], u, u + h);
      const auto o = core::orientation_at(plan, path, i, u, s0, s_dot, 0.0);
      const auto om = core::orientation_at(plan, path, i, u - h, sm, s_dot, 0.0);
      const auto op = core::orientation_at(plan, path, i, u + h, sp, s_dot, 0.0);
      const Vector3d fd = rotation_vector(op.q_WT * om.q_WT.conjugate()) / ((sp - sm) / s_dot);
      EXPECT_LE((fd - o.omega_W).norm(), 1e-6 + 1e-5 * o.omega_W.norm())
          << what << " segment " << i << " u " << u << "\n analytic " << o.omega_W.transpose() << "\n differences "
          << fd.transpose();
    }
  }
}

/// The mode-specific checks.
void check_mode(const Path& path, const OrientationPlan& plan, OrientationMode mode, const std::string& what) {
  const auto samples = check_common(path, plan, what);
  check_angular_velocity(path, plan, what);
  const auto& frames = path.spec.frames;
  for (std::size_t idx = 0; idx < samples.size(); ++idx) {
    const auto& smp = samples[idx];
    const auto& so = plan.segments[smp.segment];
    const Eigen::Matrix3d R = smp.o.q_WT.toRotationMatrix();
    const double sign = so.flipped ? -1.0 : 1.0;
    switch (mode) {
      case OrientationMode::kFixed:
        EXPECT_LT(smp.o.q_WT.angularDistance(core::tool_frame(frames[0].T_W, *frames[0].N_W)), 1e-12) << what;
        EXPECT_EQ(smp.o.omega_W, Vector3d::Zero());
        break;
      case OrientationMode::kFrenet: {
        const auto g = geometry(path, smp.segment, smp.u);
        ASSERT_TRUE(g.has_normal) << what;
        EXPECT_TRUE(VecNear(R.col(2), sign * g.T, 1e-12)) << what << " u " << smp.u;  // (6.21)
        EXPECT_TRUE(VecNear(R.col(1), g.N, 1e-12)) << what << " u " << smp.u;
        EXPECT_TRUE(VecNear(R.col(0), -sign * g.B, 1e-12)) << what << " u " << smp.u;
        break;
      }
      case OrientationMode::kParallelTransport: {
        const auto g = geometry(path, smp.segment, smp.u);
        EXPECT_TRUE(VecNear(R.col(2), sign * g.T, 1e-12)) << what << " u " << smp.u;
        if (idx > 0 && samples[idx - 1].segment == smp.segment) {
          // Twist: the component of the turn between neighbours along the tangent. Zero for a
          // rotation-minimising frame, up to the check's own discretisation (the commutator of
          // the rotations over one step, and T at the midpoint): ~1e-6 of the turn at worst on
          // these paths, so the bound is 1e-5 of the turn.
          const auto& prev = samples[idx - 1];
          const Vector3d turn = rotation_vector(smp.o.q_WT * prev.o.q_WT.conjugate());
          const Vector3d T_mid = geometry(path, smp.segment, 0.5 * (smp.u + prev.u)).T;
          EXPECT_LE(std::abs(turn.dot(T_mid)), 1e-5 * turn.norm() + 1e-12)
              << what << " segment " << smp.segment << " u " << smp.u;
        }
        break;
      }
      case OrientationMode::kFrameBased:
      case OrientationMode::kCustom:
        break;
    }
  }
  // SLERP modes reach their target exactly at the segment end.
  if (mode == OrientationMode::kFrameBased || mode == OrientationMode::kCustom) {
    for (std::size_t i = 0; i < path.segment_count(); ++i) {
      const std::size_t next = (i + 1) % frames.size();
      const Quaterniond target = mode == OrientationMode::kCustom
                                     ? custom_target(i)
                                     : core::tool_frame(frames[next].T_W, *frames[next].N_W);
      const auto end = core::orientation_at(plan, path, i, 1.0, path.cumulative_lengths[i + 1], 1.0, 0.0);
      EXPECT_LT(end.q_WT.angularDistance(target), 1e-12) << what << " segment " << i;
      // Angular velocity about the fixed SLERP axis: theta / L_i at s_dot = 1.
      EXPECT_NEAR(end.omega_W.norm(), plan.segments[i].theta / path.segment_lengths[i], 1e-12);
    }
  }
}

struct Case {
  const char* name;
  core::PathSpec (*spec)();
};

core::PathSpec demo_c() { return testing::thesis_demo_path('C'); }
// The demonstration under the default reading (the smoothest curve).
core::PathSpec demo_c_smoothest() {
  return testing::thesis_demo_path('C', core::BlendMethod::kPolynomial, core::UnspecifiedConstraints::kSmoothest);
}
core::PathSpec line_with_normals() { return line_spec(true); }

class EveryMode : public ::testing::TestWithParam<std::tuple<Case, OrientationMode>> {};

TEST_P(EveryMode, OnPath) {
  const auto& [c, mode] = GetParam();
  const std::string what = std::string(c.name) + "/" + name(mode);
  const Path path = build_or_fail(with_mode(c.spec(), mode));
  const auto plan = core::plan_orientation(path);
  if (mode == OrientationMode::kFrenet && std::string(c.name) == "line") {
    ASSERT_FALSE(plan);  // no normal anywhere on a straight line
    ASSERT_EQ(plan.error().size(), 2u);
    EXPECT_EQ(plan.error()[0].field, "frames[0].orientationMode");
    EXPECT_NE(plan.error()[0].description.find("u = 0 of segment 0"), std::string::npos) << plan.error()[0].description;
    EXPECT_NE(plan.error()[0].description.find("ORIENTATION_MODE_PARALLEL_TRANSPORT"), std::string::npos);
    EXPECT_EQ(plan.error()[1].field, "frames[1].orientationMode");
    return;
  }
  ASSERT_TRUE(plan) << what << ": " << plan.error().front().field << ": " << plan.error().front().description;
  ASSERT_EQ(plan->segments.size(), path.segment_count());
  check_mode(path, *plan, mode, what);
}

INSTANTIATE_TEST_SUITE_P(Orientation, EveryMode,
                         ::testing::Combine(::testing::Values(Case{"helix", helix_spec}, Case{"circle", circle_spec},
                                                              Case{"line", line_with_normals},
                                                              Case{"demoC", demo_c},
                                                              Case{"demoCSmoothest", demo_c_smoothest}),
                                            ::testing::Values(OrientationMode::kFixed, OrientationMode::kFrameBased,
                                                              OrientationMode::kCustom, OrientationMode::kFrenet,
                                                              OrientationMode::kParallelTransport)),
                         [](const auto& param_info) {
                           return std::string(std::get<0>(param_info.param).name) + "_" +
                                  name(std::get<1>(param_info.param));
                         });

// Under the default reading the demonstration is G4 at frame 1 (nothing breaks it there):
// the tangent-following tools turn continuously across it, the same orientation and the
// same angular velocity and acceleration per unit speed on both sides (FRENET's velocity is
// the Darboux vector tau T + kappa B; the acceleration takes kappa' and tau', which frame 1
// leaves to the reading here). Along every segment no step between
// points 1/2000 apart turns more than that rate allows.
TEST(Orientation, TangentFollowingModesAreContinuousUnderTheDefaultReading) {
  for (char which : {'A', 'B', 'C'}) {
    for (const auto mode : {OrientationMode::kFrenet, OrientationMode::kParallelTransport}) {
      const std::string what = std::string("path ") + which + "/" + name(mode);
      auto spec =
          testing::thesis_demo_path(which, core::BlendMethod::kPolynomial, core::UnspecifiedConstraints::kSmoothest);
      spec.frames[1].kappa_d.reset();  // left to the smoothest reading: continuous, not given
      spec.frames[1].tau_d.reset();
      const Path path = build_or_fail(with_mode(spec, mode));
      const auto plan = core::plan_orientation(path);
      ASSERT_TRUE(plan) << what;
      const double s1 = path.cumulative_lengths[1];
      const auto before = core::orientation_at(*plan, path, 0, 1.0, s1, 1.0, 0.0);
      const auto after = core::orientation_at(*plan, path, 1, 0.0, s1, 1.0, 0.0);
      EXPECT_LT(before.q_WT.angularDistance(after.q_WT), 1e-9) << what;
      EXPECT_LT((before.omega_W - after.omega_W).norm(), 1e-6 * std::max(1.0, before.omega_W.norm()))
          << what << ": " << before.omega_W.transpose() << " | " << after.omega_W.transpose();
      // d omega / ds (at s_dot = 1, s_ddot = 0) involves kappa' and tau': G4 keeps it too.
      EXPECT_LT((before.alpha_W - after.alpha_W).norm(), 1e-6 * std::max(1.0, before.alpha_W.norm()))
          << what << ": " << before.alpha_W.transpose() << " | " << after.alpha_W.transpose();
      if (mode == OrientationMode::kFrenet) {
        const auto g = geometry(path, 1, 0.0);
        EXPECT_TRUE(VecNear(after.omega_W, g.tau * g.T + g.kappa * g.B, 1e-6 * after.omega_W.norm())) << what;
      }
      constexpr int kSteps = 2000;
      for (std::size_t i = 0; i < path.segment_count(); ++i) {
        auto prev = core::orientation_at(*plan, path, i, 0.0, path.cumulative_lengths[i], 1.0, 0.0);
        double prev_s = path.cumulative_lengths[i];
        for (int k = 1; k <= kSteps; ++k) {
          const double u = static_cast<double>(k) / kSteps;
          const double s = prev_s + core::segment_arc_length(path.segments[i], u - 1.0 / kSteps, u);
          const auto o = core::orientation_at(*plan, path, i, u, s, 1.0, 0.0);
          const double rate = std::max(prev.omega_W.norm(), o.omega_W.norm());
          EXPECT_LE(prev.q_WT.angularDistance(o.q_WT), 1.05 * rate * (s - prev_s) + 1e-9)
              << what << " segment " << i << " u " << u;
          prev = o;
          prev_s = s;
        }
      }
    }
  }
}

// The demo path's frame 2 is a cusp: the tangent-following modes flip the tool frame by pi
// about its y axis after it, so the tool's z keeps pointing along the key frame's T.
TEST(Orientation, CuspKeepsToolZAlongKeyFrameTangent) {
  for (const auto mode : {OrientationMode::kFrenet, OrientationMode::kParallelTransport}) {
    const Path path = build_or_fail(with_mode(demo_c(), mode));
    const auto plan = core::plan_orientation(path);
    ASSERT_TRUE(plan) << name(mode);
    EXPECT_FALSE(plan->segments[0].flipped);
    EXPECT_FALSE(plan->segments[1].flipped);
    EXPECT_TRUE(plan->segments[2].flipped);
    const Vector3d T2 = path.spec.frames[2].T_W;
    const auto before = core::orientation_at(*plan, path, 1, 1.0, path.cumulative_lengths[2], 0.0, 0.0);
    const auto after = core::orientation_at(*plan, path, 2, 0.0, path.cumulative_lengths[2], 0.0, 0.0);
    EXPECT_TRUE(VecNear(before.q_WT * Vector3d::UnitZ(), T2, 1e-9)) << name(mode);
    EXPECT_TRUE(VecNear(after.q_WT * Vector3d::UnitZ(), T2, 1e-9)) << name(mode);
    // The direction of motion after the cusp is -T2.
    EXPECT_TRUE(VecNear(geometry(path, 2, 0.0).T, -T2, 1e-9));
  }
}

// Frame 0 fixed with an orientation given: the tool holds it from the first point of a
// curved start (path C bends where it starts), not the frame's [-B N T].
TEST(Orientation, AFixedStartWithAnOrientationHoldsIt) {
  core::PathSpec spec = with_mode(demo_c(), OrientationMode::kFixed);
  const Eigen::Quaterniond down(0.0, 1.0, 0.0, 0.0);  // the tool's z axis along -z of W
  spec.frames[0].orientation = down;
  const Path path = build_or_fail(spec);
  const auto plan = core::plan_orientation(path);
  ASSERT_TRUE(plan);
  for (std::size_t i = 0; i < path.segment_count(); ++i) {
    for (const double u : {0.0, 0.5, 1.0}) {
      const auto o = core::orientation_at(*plan, path, i, u, 0.0, 0.3, 0.0);
      EXPECT_LT(o.q_WT.angularDistance(down), 1e-12) << i << " " << u;
      EXPECT_EQ(o.omega_W.norm(), 0.0);
    }
  }
  // Another mode with an orientation is still refused by that field.
  spec.frames[0].orientation_mode = OrientationMode::kFrenet;
  const auto refused = core::plan_orientation(build_or_fail(spec));
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error().front().field, "frames[0].orientation");
}

// Parallel transport through an exactly straight segment between curved ones: the frame
// does not move there (no flip, omega = 0), while Frenet is refused on that segment.
TEST(Orientation, ParallelTransportThroughStraightStretch) {
  const Path path = build_or_fail(with_mode(straight_stretch_spec(), OrientationMode::kParallelTransport));
  const auto plan = core::plan_orientation(path);
  ASSERT_TRUE(plan) << plan.error().front().field << ": " << plan.error().front().description;
  check_mode(path, *plan, OrientationMode::kParallelTransport, "straight stretch");
  const auto start = core::orientation_at(*plan, path, 1, 0.0, path.cumulative_lengths[1], 1.0, 0.0);
  for (const double u : {0.1, 0.37, 0.5, 0.81, 1.0}) {
    const double s = path.cumulative_lengths[1] + core::segment_arc_length(path.segments[1], 0.0, u);
    const auto o = core::orientation_at(*plan, path, 1, u, s, 1.0, 0.0);
    EXPECT_LT(o.q_WT.angularDistance(start.q_WT), 1e-12) << u;
    EXPECT_LT(o.omega_W.norm(), 1e-12) << u;
  }
  // The Frenet frame is undefined on the straight segment: refused, naming that segment.
  const auto frenet = core::plan_orientation(build_or_fail(with_mode(straight_stretch_spec(), OrientationMode::kFrenet)));
  ASSERT_FALSE(frenet);
  bool named = false;
  for (const auto& v : frenet.error()) named |= v.field == "frames[1].orientationMode";
  EXPECT_TRUE(named);
}

// On a plane curve (tau = 0) the rotation-minimising frame is the Frenet frame (7.22 with
// k2 = 0 is 6.22 with tau = 0): a closed-form oracle for the double reflection.
TEST(Orientation, ParallelTransportIsFrenetOnPlaneCurve) {
  const Path path = build_or_fail(with_mode(circle_spec(), OrientationMode::kParallelTransport));
  const auto plan = core::plan_orientation(path);
  ASSERT_TRUE(plan);
  for (std::size_t i = 0; i < path.segment_count(); ++i) {
    for (const double u : {0.0, 0.21, 0.5, 0.93, 1.0}) {
      const auto g = geometry(path, i, u);
      const auto o = core::orientation_at(*plan, path, i, u, 0.0, 1.0, 0.0);
      EXPECT_LT(o.q_WT.angularDistance(core::tool_frame(g.T, g.N)), 1e-9) << i << " " << u;
      EXPECT_TRUE(VecNear(o.omega_W, g.kappa * g.B, 1e-12));
    }
  }
}

TEST(Orientation, FrameBasedNeedsNormalAtTarget) {
  auto spec = with_mode(line_spec(false), OrientationMode::kFrameBased);
  spec.frames[0].N_W = Vector3d(0, 1, 0);  // the start is defined; frames 1 and 2 have no normal
  const auto plan = core::plan_orientation(build_or_fail(spec));
  ASSERT_FALSE(plan);
  ASSERT_EQ(plan.error().size(), 2u);
  EXPECT_EQ(plan.error()[0].field, "frames[1].normal");
  EXPECT_EQ(plan.error()[1].field, "frames[2].normal");
  EXPECT_NE(plan.error()[0].description.find("FRAME_BASED"), std::string::npos);
}

TEST(Orientation, FrameBasedUsesMeasuredNormalWhereNoneIsGiven) {
  auto spec = with_mode(circle_spec(), OrientationMode::kFrameBased);
  spec.frames[3].N_W.reset();
  spec.frames[3].kappa.reset();
  spec.frames[3].tau.reset();
  const Path path = build_or_fail(spec);
  const auto plan = core::plan_orientation(path);
  ASSERT_TRUE(plan);
  const auto g = geometry(path, 2, 1.0);
  ASSERT_TRUE(g.has_normal);
  const auto end = core::orientation_at(*plan, path, 2, 1.0, path.length(), 1.0, 0.0);
  EXPECT_LT(end.q_WT.angularDistance(core::tool_frame(g.T, g.N)), 1e-9);
}

TEST(Orientation, StartNeedsNormal) {
  const auto plan = core::plan_orientation(
      build_or_fail(with_mode(line_spec(false), OrientationMode::kParallelTransport)));
  ASSERT_FALSE(plan);
  ASSERT_EQ(plan.error().size(), 1u);
  EXPECT_EQ(plan.error()[0].field, "frames[0].normal");
}

// A straight start without a normal under FIXED: the tool keeps the orientation it has
// before the motion (start_W; the world axes by default) all along, without a refusal.
TEST(Orientation, FixedStraightStartKeepsTheStartOrientation) {
  const auto path = build_or_fail(with_mode(line_spec(false), OrientationMode::kFixed));
  const Quaterniond start(Eigen::AngleAxisd(0.7, Vector3d(1, 2, 3).normalized()));
  for (const Quaterniond& q0 : {Quaterniond::Identity(), start}) {
    const auto plan = core::plan_orientation(path, q0);
    ASSERT_TRUE(plan) << plan.error()[0].field << ": " << plan.error()[0].description;
    for (double u : {0.0, 0.3, 1.0}) {
      const auto o = core::orientation_at(*plan, path, u < 1.0 ? 0 : 1, u < 1.0 ? u : 1.0, 0.5 * u, 0.2, 0.1);
      EXPECT_LT(o.q_WT.angularDistance(q0), 1e-12);
      EXPECT_EQ(o.omega_W.norm(), 0.0);
    }
  }
}

TEST(Orientation, CustomOrientationChecked) {
  auto spec = with_mode(circle_spec(), OrientationMode::kCustom);
  spec.frames[1].orientation.reset();
  spec.frames[0].orientation = Quaterniond(0.5, 0.5, 0.5, 0.6);  // |q| = 1.05
  spec.frames[2].orientation_mode = OrientationMode::kFixed;       // keeps its orientation: not allowed
  const auto plan = core::plan_orientation(build_or_fail(spec));
  ASSERT_FALSE(plan);
  ASSERT_EQ(plan.error().size(), 3u);
  EXPECT_EQ(plan.error()[0].field, "frames[0].orientation");
  EXPECT_EQ(plan.error()[1].field, "frames[1].orientation");
  EXPECT_EQ(plan.error()[2].field, "frames[2].orientation");
}

// Fixed on segment 0 keeps frame 0's orientation; at frame 1 the tangent has turned by
// 60 degrees, so parallel transport there would start with a jump.
TEST(Orientation, TangentFollowingJoinMustBeContinuous) {
  auto spec = with_mode(circle_spec(), OrientationMode::kParallelTransport);
  spec.frames[0].orientation_mode = OrientationMode::kFixed;
  auto plan = core::plan_orientation(build_or_fail(spec));
  ASSERT_FALSE(plan);
  ASSERT_EQ(plan.error().size(), 1u);
  EXPECT_EQ(plan.error()[0].field, "frames[1].orientationMode");
  EXPECT_NE(plan.error()[0].description.find("1.0472 rad"), std::string::npos) << plan.error()[0].description;

  // Frame-based into the tangent-following modes joins exactly (the key frame has a curvature).
  spec.frames[0].orientation_mode = OrientationMode::kFrameBased;
  for (const auto mode : {OrientationMode::kFrenet, OrientationMode::kParallelTransport}) {
    spec.frames[1].orientation_mode = spec.frames[2].orientation_mode = mode;
    const Path path = build_or_fail(spec);
    plan = core::plan_orientation(path);
    ASSERT_TRUE(plan) << plan.error().front().description;
    check_common(path, *plan, std::string("mixed ") + name(mode));
  }
}

// alpha_W against central differences of omega_W in time along a timed motion (10 s,
// trapezoidal profile, 1 kHz), every mode, on the helix and the demo path C. Bound: where
// alpha is smooth the difference errs by h^2/6 |alpha''|; where alpha's slope jumps (S-curve
// corners) by at most h/4 |jump of alpha'|, and where alpha itself jumps (trapezoid
// corners: s_ddot jumps) by at most |jump| / 2. The second difference of the analytic
// alpha, |alpha_{k+1} - 2 alpha_k + alpha_{k-1}|, is at least twice each of these, so it is
// the tolerance (plus 1e-9 rad/s^2 for rounding). A wrong analytic term (say the s_dot^2
// part) is smooth and does not hide in it. Samples next to another segment are skipped:
// omega_W jumps at a frame where the SLERP rate theta / L changes.
TEST(Orientation, AngularAccelerationMatchesDifferencesOfOmega) {
  const Case cases[] = {{"helix", helix_spec}, {"demoC", demo_c}};
  for (const auto& c : cases) {
    for (const auto mode : {OrientationMode::kFixed, OrientationMode::kFrameBased, OrientationMode::kCustom,
                            OrientationMode::kFrenet, OrientationMode::kParallelTransport}) {
      const std::string what = std::string(c.name) + "/" + name(mode);
      const Path path = build_or_fail(with_mode(c.spec(), mode));
      const auto plan = core::plan_orientation(path);
      ASSERT_TRUE(plan) << what;
      core::MotionSpec spec;
      spec.duration_s = 10.0;
      spec.cycle_rate_hz = 1000.0;
      const auto timing = core::plan_motion(path, spec);
      ASSERT_TRUE(timing) << what;
      core::MotionSampler sampler(path, *timing);
      std::vector<core::MotionSample> ms;
      std::vector<OrientationSample> os;
      core::MotionSample m;
      while (sampler.next(m)) {
        ms.push_back(m);
        os.push_back(core::orientation_at(*plan, path, m.segment, m.u - static_cast<double>(m.segment), m.s, m.speed,
                                          m.s_ddot));
      }
      const double h = 1.0 / spec.cycle_rate_hz;
      double worst_ratio = 0.0, peak_alpha = 0.0;
      int checked = 0;
      for (std::size_t k = 1; k + 1 < ms.size(); ++k) {
        if (ms[k - 1].segment != ms[k].segment || ms[k + 1].segment != ms[k].segment) continue;
        if (std::abs((ms[k + 1].t - ms[k].t) - h) > 1e-9 || std::abs((ms[k].t - ms[k - 1].t) - h) > 1e-9) continue;
        const Vector3d fd = (os[k + 1].omega_W - os[k - 1].omega_W) / (ms[k + 1].t - ms[k - 1].t);
        const double tol = (os[k + 1].alpha_W - 2.0 * os[k].alpha_W + os[k - 1].alpha_W).norm() + 1e-9;
        const double err = (fd - os[k].alpha_W).norm();
        worst_ratio = std::max(worst_ratio, err / tol);
        peak_alpha = std::max(peak_alpha, os[k].alpha_W.norm());
        ++checked;
        ASSERT_LE(err, tol) << what << " t " << ms[k].t << " segment " << ms[k].segment << "\n analytic "
                            << os[k].alpha_W.transpose() << "\n differences " << fd.transpose();
      }
      EXPECT_GT(checked, 9000) << what;
      if (mode == OrientationMode::kFixed) {
        EXPECT_EQ(peak_alpha, 0.0) << what;
      } else {
        EXPECT_GT(peak_alpha, 1e-3) << what;  // the check saw a turning tool
      }
      std::printf("alpha vs differences of omega, %s: %d samples, peak |alpha| %.3g rad/s^2, worst error / bound %.3f\n",
                  what.c_str(), checked, peak_alpha, worst_ratio);
    }
  }
}

TEST(Orientation, NoHeapAllocationPerSample) {
  for (const auto mode : {OrientationMode::kFixed, OrientationMode::kFrameBased, OrientationMode::kCustom,
                          OrientationMode::kFrenet, OrientationMode::kParallelTransport}) {
    const Path path = build_or_fail(with_mode(helix_spec(), mode));
    const auto plan = core::plan_orientation(path);
    ASSERT_TRUE(plan);
    double sink = 0;
    const long before = geotraj::testing::allocation_count();
    for (int k = 0; k <= 300; ++k) {
      const double u = 3.0 * k / 300.0;
      const auto [seg, ul] = core::locate(path, u);
      const auto o = core::orientation_at(*plan, path, seg, ul, path.length() * k / 300.0, 1.0, 0.5);
      sink += o.q_WT.w() + o.omega_W.x() + o.alpha_W.x();
    }
    EXPECT_EQ(geotraj::testing::allocation_count(), before) << name(mode);
    EXPECT_TRUE(std::isfinite(sink));
  }
}

// Eased SLERP (KeyFrame::ease_orientation): omega by differences of q and alpha by
// differences of omega as for the plain modes, omega and alpha zero at every frame, and so
// continuous through the frames where plain SLERP's omega jumps while the path moves.
TEST(Orientation, EasedSlerpJoinsWithContinuousAngularVelocityAndAcceleration) {
  for (const auto mode : {OrientationMode::kCustom, OrientationMode::kFrameBased}) {
    const std::string what = std::string("helix/eased ") + name(mode);
    core::PathSpec spec = with_mode(helix_spec(), mode);
    for (auto& f : spec.frames) f.ease_orientation = true;
    const Path path = build_or_fail(spec);
    const auto plan = core::plan_orientation(path);
    ASSERT_TRUE(plan) << what;
    check_common(path, *plan, what);
    check_angular_velocity(path, *plan, what);
    for (std::size_t i = 0; i < path.segment_count(); ++i) {
      for (const double u : {0.0, 1.0}) {
        const double s = path.cumulative_lengths[i] + (u == 1.0 ? path.segment_lengths[i] : 0.0);
        const auto o = core::orientation_at(*plan, path, i, u, s, 0.8, 0.3);
        EXPECT_LT(o.omega_W.norm(), 1e-12) << what << " segment " << i << " u " << u;
        EXPECT_LT(o.alpha_W.norm(), 1e-12) << what << " segment " << i << " u " << u;
      }
    }
    // Along a timed motion at 1 kHz: omega changes by at most |alpha| dt (+ its rate of
    // change) between samples, through the frames too; plain SLERP jumps there.
    core::MotionSpec motion;
    motion.duration_s = 10.0;
    motion.cycle_rate_hz = 1000.0;
    const auto timing = core::plan_motion(path, motion);
    ASSERT_TRUE(timing);
    const auto plain_spec = with_mode(helix_spec(), mode);
    const Path plain = build_or_fail(plain_spec);
    const auto plain_plan = core::plan_orientation(plain);
    ASSERT_TRUE(plain_plan);
    double worst_eased = 0.0, worst_plain = 0.0;
    for (const auto* which : {&path, &plain}) {
      const auto& p = which == &path ? *plan : *plain_plan;
      core::MotionSampler sampler(*which, *timing);
      core::MotionSample m;
      OrientationSample previous;
      bool first = true;
      while (sampler.next(m)) {
        const auto o = core::orientation_at(p, *which, m.segment, m.u - static_cast<double>(m.segment), m.s, m.speed,
                                            m.s_ddot);
        if (!first) {
          const double jump = (o.omega_W - previous.omega_W).norm() /
                              (std::max(o.alpha_W.norm(), previous.alpha_W.norm()) * 1e-3 + 1e-6);
          (which == &path ? worst_eased : worst_plain) = std::max(which == &path ? worst_eased : worst_plain, jump);
        }
        previous = o;
        first = false;
      }
    }
    std::printf("%s: largest change of omega between 1 kHz samples / (|alpha| dt): eased %.3g, plain %.3g\n",
                what.c_str(), worst_eased, worst_plain);
    EXPECT_LT(worst_eased, 1.5) << what;
    // (The helix's frame-based targets turn at one rate about one axis: no jump to show.)
    if (mode == OrientationMode::kCustom) {
      EXPECT_GT(worst_plain, 10.0) << what << ": plain SLERP's omega jumps at the frames";
    }
  }
}

}  // namespace
}  // namespace geotraj::test
