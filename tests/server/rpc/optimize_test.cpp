// The optimisers through the real service, checked the way a user would check them: the
// report's claims against the plan, the analysis and the stream of the same request,
// recomputed here independently of the server's own measures.
//  - Tangent scales (thesis demo path A): the objective falls, the constraints stay met,
//    the arc length and the bending energy recomputed from PlanTrajectory and AnalyzePath.
//  - Trapezoid breakpoints (thesis Appendix B's path): the peak torsion falls, recomputed
//    from a dense AnalyzePath; bad blend; a time budget too small to do anything.
//  - Time-optimal timing: the PA-10 on demo path C at durationS 0 (every streamed joint
//    velocity and acceleration within ListRobots' limits, one of them reached), and a
//    Cartesian-only time-optimal motion (speed, tangential and centripetal acceleration
//    within the limits); a path that the robot cannot follow.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <gmock/gmock.h>

#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::AnyOf;
using ::testing::Eq;
using ::testing::HasSubstr;

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

class OptimizeTest : public ServerTest {
 protected:
  v1::PathProfile analyze_ok(const v1::PlanRequest& request) {
    v1::PathProfile profile;
    const auto status = analyze(request, profile);
    EXPECT_TRUE(status.ok()) << status.error_message();
    return profile;
  }
};

// Trapezoid rule of kappa^2 over s on an AnalyzePath profile [1/m]. Points without a
// curvature (|dp/du| = 0) count as 0: they are isolated.
double bending_energy(const v1::PathProfile& profile) {
  double e = 0.0;
  for (int i = 1; i < profile.points_size(); ++i) {
    const auto& a = profile.points(i - 1);
    const auto& b = profile.points(i);
    const double ka = a.has_curvature() ? a.curvature() : 0.0;
    const double kb = b.has_curvature() ? b.curvature() : 0.0;
    e += 0.5 * (ka * ka + kb * kb) * (b.s() - a.s());
  }
  return e;
}

// Largest |torsion| over an AnalyzePath profile [1/m] (points with a torsion only).
double peak_torsion(const v1::PathProfile& profile) {
  double peak = 0.0;
  for (const auto& p : profile.points()) {
    if (p.has_torsion()) peak = std::max(peak, std::abs(p.torsion()));
  }
  return peak;
}

// =========================================================================================
// Tangent scales on the thesis demo path A

struct ScaleCase {
  v1::TangentScaleObjective objective;
  const char* name;
  bool default_reading = false;  // the shipped example (the smoothest reading), else lowest degree
};
void PrintTo(const ScaleCase& c, std::ostream* os) { *os << c.name; }

class TangentScales : public OptimizeTest, public ::testing::WithParamInterface<ScaleCase> {};

TEST_P(TangentScales, DemoPathA) {
  const ScaleCase c = GetParam();
  // With its 10 s motion, so that it also streams.
  const v1::PlanRequest plain = c.default_reading ? demo_example('a') : demo_request('a');
  v1::PlanRequest request = plain;
  request.mutable_optimize()->mutable_tangent_scales()->set_objective(c.objective);

  const auto before = plan_ok(plain);
  EXPECT_FALSE(before.has_optimization()) << "no optimize, no report";
  const auto t0 = std::chrono::steady_clock::now();
  const auto after = plan_ok(request);
  const double plan_s = seconds_since(t0);

  ASSERT_TRUE(after.has_optimization());
  ASSERT_TRUE(after.optimization().has_tangent_scales());
  EXPECT_FALSE(after.optimization().has_breakpoints());
  EXPECT_FALSE(after.optimization().has_timing());
  const auto& r = after.optimization().tangent_scales();
  std::printf("[ measured ] %s: objective %.6g -> %.6g, %u iterations, status %s, %.3f s (server), %.3f s (RPC)\n",
              c.name, r.objective_before(), r.objective_after(), r.iterations(),
              v1::OptimizerStatus_Name(r.status()).c_str(), r.seconds(), plan_s);
  EXPECT_THAT(r.status(), AnyOf(Eq(v1::OPTIMIZER_STATUS_CONVERGED), Eq(v1::OPTIMIZER_STATUS_ITERATION_LIMIT)))
      << r.message();
  EXPECT_LT(r.objective_after(), r.objective_before());
  EXPECT_GT(r.objective_after(), 0.0);
  EXPECT_GT(r.seconds(), 0.0);

  // 4 frames, and frame 2 (the cusp) has a leaving side of its own.
  ASSERT_EQ(r.tangent_scales_size(), 5);
  for (double scale : r.tangent_scales()) EXPECT_GT(scale, 0.0);
  // The achieved |dp/du| at the frames is the reported scales: frame 0 leave, frame 1 both
  // sides, frame 2 approach then leave, frame 3 approach.
  ASSERT_EQ(after.frames_size(), 4);
  const double rel = 1e-9;
  EXPECT_NEAR(after.frames(0).leave().speed(), r.tangent_scales(0), rel * r.tangent_scales(0));
  EXPECT_NEAR(after.frames(1).approach().speed(), r.tangent_scales(1), rel * r.tangent_scales(1));
  EXPECT_NEAR(after.frames(1).leave().speed(), r.tangent_scales(1), rel * r.tangent_scales(1));
  EXPECT_NEAR(after.frames(2).approach().speed(), r.tangent_scales(2), rel * r.tangent_scales(2));
  EXPECT_NEAR(after.frames(2).leave().speed(), r.tangent_scales(3), rel * r.tangent_scales(3));
  EXPECT_NEAR(after.frames(3).approach().speed(), r.tangent_scales(4), rel * r.tangent_scales(4));

  // The geometry asked for still holds (as service_test checks for the plain plan).
  EXPECT_LT(after.closed_loop().max_error(), 1e-9) << "worst at " << after.closed_loop().worst_field();
  EXPECT_NEAR(after.frames(1).approach().curvature(), plain.path().frames(1).curvature(), 1e-9);
  EXPECT_NEAR(after.frames(1).approach().torsion(), plain.path().frames(1).torsion(), 50 * 1e-9);
  EXPECT_NEAR(after.frames(2).leave().tangent().x(), -1.0, 1e-12) << "frame 2 is still a cusp";

  // The same request analysed and streamed: the optimised path.
  v1::PlanRequest dense = request;
  dense.set_analysis_points(20001);
  const auto profile = analyze_ok(dense);
  ASSERT_EQ(profile.points_size(), 20001);
  EXPECT_NEAR(profile.arc_length(), after.arc_length(), 1e-9 * after.arc_length());
  EXPECT_GT(std::abs(profile.arc_length() - before.arc_length()), 1e-6) << "AnalyzePath used the request's scales";
  EXPECT_NEAR(profile.points(profile.points_size() - 1).s(), after.arc_length(), 1e-9 * after.arc_length());

  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  ASSERT_EQ(samples.size(), after.motion().sample_count());
  EXPECT_NEAR(samples.back().s(), after.arc_length(), 1e-9 * after.arc_length()) << "the stream ran the optimised path";

  if (c.objective == v1::TANGENT_SCALE_OBJECTIVE_ARC_LENGTH) {
    EXPECT_NEAR(after.arc_length(), r.objective_after(), 1e-6 * r.objective_after());
    EXPECT_NEAR(before.arc_length(), r.objective_before(), 1e-6 * r.objective_before());
    EXPECT_LT(after.arc_length(), before.arc_length());
    std::printf("[ measured ] arc length %.6f m -> %.6f m\n", before.arc_length(), after.arc_length());
  } else if (c.objective == v1::TANGENT_SCALE_OBJECTIVE_PEAK_CURVATURE) {
    // Independent: the largest curvature over the 20001-point profile, and the geometry
    // report's peak (refined between samples).
    double peak = 0.0, reported = 0.0;
    for (const auto& p : profile.points()) peak = std::max(peak, p.has_curvature() ? p.curvature() : 0.0);
    for (const auto& seg : after.segments()) reported = std::max(reported, seg.peak_curvature().value());
    std::printf("[ measured ] peak curvature %.6g -> %.6g 1/m (profile), %.6g (geometry report)\n",
                r.objective_before(), peak, reported);
    EXPECT_NEAR(peak, r.objective_after(), 0.01 * r.objective_after());
    EXPECT_NEAR(reported, r.objective_after(), 0.01 * r.objective_after());
    EXPECT_LT(after.arc_length(), 2.25 * before.arc_length()) << "kPeakLengthGrowth from its bending-energy start";
  } else {
    // Independent: kappa^2 integrated over s by the trapezoid rule on 20001 points uniform in
    // u. The optimiser measures it with its own Gauss-Legendre rule; they agree to about
    // 1e-5 here, and 1 % leaves room for the trapezoid rule near the curvature peaks.
    const double energy = bending_energy(profile);
    v1::PlanRequest plain_dense = plain;
    plain_dense.set_analysis_points(20001);
    const double energy_before = bending_energy(analyze_ok(plain_dense));
    std::printf("[ measured ] bending energy (trapezoid, 20001 points) %.6g -> %.6g 1/m\n", energy_before, energy);
    // The objective adds the length weight times the arc length (by default E0 / L0).
    const double w = r.length_weight();
    EXPECT_GT(w, 0.0) << "the default length weight";
    EXPECT_NEAR(w, energy_before / before.arc_length(), 0.01 * w);
    EXPECT_NEAR(energy + w * after.arc_length(), r.objective_after(), 0.01 * r.objective_after());
    EXPECT_NEAR(energy_before + w * before.arc_length(), r.objective_before(), 0.01 * r.objective_before());
    EXPECT_LT(energy + w * after.arc_length(), energy_before + w * before.arc_length());
    EXPECT_LT(after.arc_length(), 1.3 * before.arc_length()) << "the length stays in check";
  }
}

INSTANTIATE_TEST_SUITE_P(Objectives, TangentScales,
                         ::testing::Values(ScaleCase{v1::TANGENT_SCALE_OBJECTIVE_BENDING_ENERGY, "BendingEnergy"},
                                           ScaleCase{v1::TANGENT_SCALE_OBJECTIVE_ARC_LENGTH, "ArcLength"},
                                           ScaleCase{v1::TANGENT_SCALE_OBJECTIVE_BENDING_ENERGY,
                                                     "BendingEnergySmoothest", true},
                                           ScaleCase{v1::TANGENT_SCALE_OBJECTIVE_PEAK_CURVATURE,
                                                     "PeakCurvatureSmoothest", true}),
                         [](const auto& p) { return std::string(p.param.name); });

// =========================================================================================
// Trapezoid breakpoints on Appendix B's path

TEST_F(OptimizeTest, BreakpointsLowerThePeakTorsionOfAppendixB) {
  auto request = example<v1::PlanRequest>("appendix_b_optimized.json");
  const auto uniform = example<v1::PlanRequest>("appendix_b_uniform.json");
  ASSERT_GE(request.analysis_points(), 20001u) << "the example asks for a dense analysis";
  // The Plan and the AnalyzePath below each run the optimiser; both must stop at its
  // iteration limit (deterministic), not at the example's time budget, which a slow build
  // (the sanitizers take ~10 s a run) can reach in one call and not the other.
  request.mutable_optimize()->set_time_budget_s(30.0);  // the server's default limit

  const auto t0 = std::chrono::steady_clock::now();
  const auto response = plan_ok(request);
  const double plan_s = seconds_since(t0);
  ASSERT_TRUE(response.has_optimization());
  ASSERT_TRUE(response.optimization().has_breakpoints());
  EXPECT_FALSE(response.optimization().has_tangent_scales());
  const auto& r = response.optimization().breakpoints();
  std::printf("[ measured ] breakpoints: peak torsion %.6g -> %.6g 1/m, %u iterations, status %s, %.3f s (server), "
              "%.3f s (RPC)\n",
              r.objective_before(), r.objective_after(), r.iterations(), v1::OptimizerStatus_Name(r.status()).c_str(),
              r.seconds(), plan_s);
  EXPECT_NE(r.status(), v1::OPTIMIZER_STATUS_FAILED) << r.message();
  EXPECT_LT(r.objective_after(), r.objective_before());
  EXPECT_LT(response.closed_loop().max_error(), 1e-6) << "worst at " << response.closed_loop().worst_field();

  // Two segments, each with x, y and z lists of 2n + 2 ordered values from 0 to 1, n the
  // axis's trapezoid order as the plan reports it.
  ASSERT_EQ(response.segments_size(), 2);
  ASSERT_EQ(r.breakpoints_size(), 2);
  for (int i = 0; i < 2; ++i) {
    SCOPED_TRACE("segment " + std::to_string(i));
    const auto& b = r.breakpoints(i);
    EXPECT_EQ(b.segment(), static_cast<unsigned>(i));
    const auto& seg = response.segments(i);
    EXPECT_EQ(seg.blend(), v1::BLEND_METHOD_TRAPEZOIDAL);
    ASSERT_EQ(seg.trapezoid_orders_size(), 3);
    const google::protobuf::RepeatedField<double>* axes[] = {&b.x(), &b.y(), &b.z()};
    for (int a = 0; a < 3; ++a) {
      SCOPED_TRACE("axis " + std::to_string(a));
      const auto& u = *axes[a];
      ASSERT_EQ(u.size(), static_cast<int>(2 * seg.trapezoid_orders(a) + 2));
      EXPECT_EQ(u[0], 0.0);
      EXPECT_EQ(u[u.size() - 1], 1.0);
      EXPECT_LT(u[0], u[1]);
      for (int k = 1; k < u.size(); ++k) EXPECT_LE(u[k - 1], u[k]) << "k = " << k;
    }
  }

  // Independently: the largest |torsion| of a dense AnalyzePath of the same request. The
  // optimiser refines its peaks by golden section, so the sampled peak of 40001 points can
  // only be lower; at 20000 points per segment it is within 1 % (the peaks are smooth).
  // 40001 points are about 7 MB, above gRPC's default 4 MB receive limit: a channel that
  // takes them.
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(64 << 20);
  const auto big = v1::TrajectoryService::NewStub(
      grpc::CreateCustomChannel(address_, grpc::InsecureChannelCredentials(), args));
  v1::PathProfile profile, profile_uniform;
  auto status = big->AnalyzePath(context().get(), request, &profile);
  ASSERT_TRUE(status.ok()) << status.error_message();
  status = big->AnalyzePath(context().get(), uniform, &profile_uniform);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(profile.points_size(), static_cast<int>(request.analysis_points()));
  const double peak = peak_torsion(profile);
  const double peak_uniform = peak_torsion(profile_uniform);
  std::printf("[ measured ] peak |torsion| of AnalyzePath (%d points): uniform %.6g, optimised %.6g 1/m\n",
              profile.points_size(), peak_uniform, peak);
  EXPECT_NEAR(peak_uniform, r.objective_before(), 0.01 * r.objective_before());
  EXPECT_LT(peak, peak_uniform);
  // The analysis used the same optimised path: the optimiser is deterministic.
  EXPECT_NE(r.status(), v1::OPTIMIZER_STATUS_TIME_LIMIT) << r.message();
  EXPECT_NEAR(peak, r.objective_after(), 0.01 * r.objective_after());
  EXPECT_NEAR(profile.arc_length(), response.arc_length(), 1e-9 * response.arc_length());
}

TEST_F(OptimizeTest, BreakpointsOfAPolynomialBlendNameTheBlend) {
  auto request = demo_request('a');
  request.mutable_optimize()->mutable_breakpoints()->set_objective(v1::BREAKPOINT_OBJECTIVE_PEAK_TORSION);
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  const auto violations = bad_request_violations(status);
  EXPECT_NE(violation_of(violations, "path.blend"), "") << describe(violations);

  v1::PathProfile profile;
  const auto analyzed = analyze(request, profile);
  EXPECT_EQ(analyzed.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(violation_of(bad_request_violations(analyzed), "path.blend"), "");
}

TEST_F(OptimizeTest, ATinyTimeBudgetStopsAtOnce) {
  auto request = example<v1::PlanRequest>("appendix_b_optimized.json");
  request.mutable_optimize()->set_time_budget_s(1e-6);
  const auto t0 = std::chrono::steady_clock::now();
  const auto response = plan_ok(request);
  const double plan_s = seconds_since(t0);
  ASSERT_TRUE(response.optimization().has_breakpoints());
  const auto& r = response.optimization().breakpoints();
  std::printf("[ measured ] breakpoints with timeBudgetS 1e-6: status %s, %.6f s (server), %.3f s (RPC)\n",
              v1::OptimizerStatus_Name(r.status()).c_str(), r.seconds(), plan_s);
  EXPECT_EQ(r.status(), v1::OPTIMIZER_STATUS_TIME_LIMIT) << r.message();
  // The budget is spent before the first evaluation (building the path alone takes longer
  // than 1 us): the optimiser evaluates nothing and returns the request's own breakpoints.
  EXPECT_EQ(r.iterations(), 0u);
  EXPECT_EQ(r.objective_after(), r.objective_before());
}

// =========================================================================================
// Time-optimal timing

// Demo path C on the PA-10 as fast as its joints allow.
v1::PlanRequest pa10_path_c_fastest() {
  auto request = demo_request('c');
  request.mutable_motion()->set_duration_s(0.0);
  request.mutable_robot()->set_name("pa10");
  return request;
}

// The timing report's binding stretches: contiguous in s from 0 to the arc length and in t
// from 0 to the duration, each at its limit. On the grid interval where the solver switches
// from one limit to another, the acceleration is set by where the next limit starts rather
// than by a limit, so a short stretch there may sit below 1; the stretches at their limit
// (usage >= 0.99) must cover nearly all of the path.
void expect_timing_binding(const google::protobuf::RepeatedPtrField<v1::BindingStretch>& binding, double arc_length,
                           double duration) {
  ASSERT_GT(binding.size(), 0);
  EXPECT_NEAR(binding[0].s_start(), 0.0, 1e-12);
  EXPECT_NEAR(binding[0].t_start(), 0.0, 1e-12);
  EXPECT_NEAR(binding[binding.size() - 1].s_end(), arc_length, 1e-9 * arc_length);
  EXPECT_NEAR(binding[binding.size() - 1].t_end(), duration, 1e-9 * duration);
  double lowest_usage = 1.0, s_at_limit = 0.0, t_at_limit = 0.0;
  for (int i = 0; i < binding.size(); ++i) {
    SCOPED_TRACE("stretch " + std::to_string(i));
    const auto& b = binding[i];
    EXPECT_NE(b.kind(), v1::BINDING_KIND_UNSPECIFIED);
    EXPECT_LT(b.s_start(), b.s_end());
    EXPECT_LT(b.t_start(), b.t_end());
    if (i > 0) {
      EXPECT_NEAR(b.s_start(), binding[i - 1].s_end(), 1e-12) << "contiguous in s";
      EXPECT_NEAR(b.t_start(), binding[i - 1].t_end(), 1e-12) << "contiguous in t";
    }
    EXPECT_GT(b.limit(), 0.0);
    EXPECT_NEAR(b.usage(), b.value() / b.limit(), 1e-9);
    EXPECT_LE(b.usage(), 1.0 + 1e-9);
    EXPECT_GT(b.usage(), 0.5);
    if (b.usage() >= 0.99) {
      s_at_limit += b.s_end() - b.s_start();
      t_at_limit += b.t_end() - b.t_start();
    }
    lowest_usage = std::min(lowest_usage, b.usage());
    if (std::getenv("GEOTRAJ_TEST_VERBOSE")) {
      std::printf("  %-47s j%u s %.5f-%.5f t %.4f-%.4f usage %.6f value %.6g limit %.6g\n",
                  v1::BindingKind_Name(b.kind()).c_str(), b.joint(), b.s_start(), b.s_end(), b.t_start(), b.t_end(),
                  b.usage(), b.value(), b.limit());
    }
  }
  std::printf("[ measured ] %d binding stretches, lowest usage %.6f; at the limit on %.2f %% of s, %.2f %% of t\n",
              binding.size(), lowest_usage, 100 * s_at_limit / arc_length, 100 * t_at_limit / duration);
  EXPECT_GT(s_at_limit, 0.95 * arc_length);
  EXPECT_GT(t_at_limit, 0.95 * duration);
}

TEST_F(OptimizeTest, TimeOptimalPa10OnDemoPathC) {
  const auto request = pa10_path_c_fastest();
  const auto t0 = std::chrono::steady_clock::now();
  const auto response = plan_ok(request);
  const double plan_s = seconds_since(t0);
  ASSERT_TRUE(response.has_motion());
  ASSERT_TRUE(response.has_robot());
  const double duration = response.motion().duration_s();
  std::printf("[ measured ] PA-10 on demo path C at durationS 0: %.4f s (%lu samples), RPC %.3f s\n", duration,
              static_cast<unsigned long>(response.motion().sample_count()), plan_s);
  EXPECT_GT(duration, 0.0);
  EXPECT_LT(duration, 8.0) << "well below the thesis's 10 s";
  // The contract: a report per optimiser only for a request with `optimize`.
  EXPECT_FALSE(response.has_optimization());

  const auto& robot = response.robot();
  EXPECT_TRUE(robot.feasible());
  EXPECT_EQ(robot.violations_size(), 0);
  double top_usage = 0.0;
  for (const auto& j : robot.joints()) {
    EXPECT_LE(j.velocity_usage(), 1.0 + 1e-9) << "joint " << j.joint();
    EXPECT_LE(j.acceleration_usage(), 1.0 + 1e-9) << "joint " << j.joint();
    top_usage = std::max({top_usage, j.velocity_usage(), j.acceleration_usage()});
  }
  EXPECT_GT(top_usage, 0.98) << "as fast as the joints allow: some joint at its limit";
  std::printf("[ measured ] largest joint usage %.6f\n", top_usage);
  // The robot report's stretches (the most used joint limit, sample by sample): in time
  // order, contiguous, up to the end. (Their s span: RobotBindingHasArcLengths.)
  ASSERT_GT(robot.binding_size(), 0);
  EXPECT_NEAR(robot.binding(0).t_start(), 0.0, 0.0101);
  EXPECT_NEAR(robot.binding(robot.binding_size() - 1).t_end(), duration, 1e-9);
  for (int i = 0; i < robot.binding_size(); ++i) {
    const auto& b = robot.binding(i);
    EXPECT_THAT(b.kind(), AnyOf(Eq(v1::BINDING_KIND_JOINT_VELOCITY), Eq(v1::BINDING_KIND_JOINT_ACCELERATION)));
    EXPECT_LT(b.joint(), 7u);
    EXPECT_LE(b.usage(), 1.0 + 1e-9);
    if (i > 0) {
      EXPECT_EQ(b.t_start(), robot.binding(i - 1).t_end()) << "stretch " << i;
    }
  }

  // The PA-10 gives no jerk limits: without optimize.timing the motion is timed
  // jerk-limited under the default bound (no acceleration step), and says so.
  EXPECT_TRUE(robot.has_default_jerk());
  EXPECT_EQ(robot.default_jerk().joints_size(), 7);

  // Asked for explicitly: the time-optimal sweep (bang-bang in the path acceleration), with
  // the timing report, faster by the ramps the default jerk adds.
  auto asked = request;
  asked.mutable_optimize()->mutable_timing()->set_time_optimal(true);
  const auto reported = plan_ok(asked);
  ASSERT_TRUE(reported.has_optimization());
  ASSERT_TRUE(reported.optimization().has_timing());
  EXPECT_FALSE(reported.robot().has_default_jerk());
  const auto& timing = reported.optimization().timing();
  EXPECT_LT(reported.motion().duration_s(), duration);
  EXPECT_GT(reported.motion().duration_s(), 0.9 * duration);
  const double sweep = reported.motion().duration_s();
  EXPECT_EQ(timing.objective_after(), reported.motion().duration_s());
  // objectiveBefore: 0, documented: no move time was asked and no Cartesian limit given.
  EXPECT_EQ(timing.objective_before(), 0.0);
  EXPECT_EQ(timing.status(), v1::OPTIMIZER_STATUS_CONVERGED) << timing.message();
  std::printf("[ measured ] timing report: %.4f s -> %.4f s, %.3f s (server)\n", timing.objective_before(),
              timing.objective_after(), timing.seconds());
  expect_timing_binding(timing.binding(), reported.arc_length(), sweep);
  for (const auto& b : timing.binding()) {
    EXPECT_THAT(b.kind(), AnyOf(Eq(v1::BINDING_KIND_JOINT_VELOCITY), Eq(v1::BINDING_KIND_JOINT_ACCELERATION)))
        << "no Cartesian limit was given";
    EXPECT_LT(b.joint(), 7u);
  }
  // The default jerk bound holds on the stream of the default timing, by differences of the
  // streamed joint accelerations (100 Hz), and the motion starts and ends without a step.

  // The stream: every joint velocity and acceleration within ListRobots' limits.
  const auto pa10 = robot_model("pa10");
  ASSERT_EQ(pa10.limits_size(), 7);
  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  ASSERT_EQ(samples.size(), response.motion().sample_count());
  double worst = 0.0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const auto& s = samples[k];
    ASSERT_EQ(s.joint_velocities_size(), 7);
    ASSERT_EQ(s.joint_accelerations_size(), 7);
    for (int j = 0; j < 7; ++j) {
      const double vmax = pa10.limits(j).max_velocity();
      const double amax = pa10.limits(j).max_acceleration();
      EXPECT_LE(std::abs(s.joint_velocities(j)), vmax * (1 + 1e-9)) << "sample " << k << " joint " << j;
      EXPECT_LE(std::abs(s.joint_accelerations(j)), amax * (1 + 1e-9)) << "sample " << k << " joint " << j;
      worst = std::max({worst, std::abs(s.joint_velocities(j)) / vmax, std::abs(s.joint_accelerations(j)) / amax});
    }
  }
  for (std::size_t k = 1; k < samples.size(); ++k) {
    for (int j = 0; j < 7; ++j) {
      const double jerk = std::abs(samples[k].joint_accelerations(j) - samples[k - 1].joint_accelerations(j)) /
                          (samples[k].t() - samples[k - 1].t());
      EXPECT_LE(jerk, robot.default_jerk().max_jerk(j) * (1 + 1e-6)) << "sample " << k << " joint " << j;
    }
  }
  for (int j = 0; j < 7; ++j) EXPECT_EQ(samples.front().joint_accelerations(j), 0.0) << "joint " << j;
  std::printf("[ measured ] streamed: largest joint usage %.9f over %zu samples\n", worst, samples.size());
  EXPECT_GT(worst, 0.98);
  EXPECT_NEAR(samples.front().speed(), 0.0, 1e-12);
  EXPECT_NEAR(samples.back().speed(), 0.0, 1e-9);
  EXPECT_NEAR(samples.back().t(), duration, 1e-9);

  // The cusp (frame 2, u = 2) is a stop: the speed falls to 0 there. The samples are at the
  // cycle rate, so the one nearest the cusp is within a cycle of the stop: its speed is at
  // most the largest speed change in one cycle, and the speed has a minimum there.
  const double s_cusp = response.segments(0).arc_length() + response.segments(1).arc_length();
  std::size_t nearest = 0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    if (std::abs(samples[k].s() - s_cusp) < std::abs(samples[nearest].s() - s_cusp)) nearest = k;
  }
  const double dt = samples[1].t() - samples[0].t();
  std::printf("[ measured ] at the cusp: sample %zu, t %.4f s, s - s_cusp %.3g m, speed %.3g m/s\n", nearest,
              samples[nearest].t(), samples[nearest].s() - s_cusp, samples[nearest].speed());
  EXPECT_NEAR(samples[nearest].s(), s_cusp, 1e-6);
  EXPECT_LT(samples[nearest].speed(), response.motion().peak_tangential_acceleration() * dt);
  ASSERT_GT(nearest, 0u);
  ASSERT_LT(nearest + 1, samples.size());
  EXPECT_LE(samples[nearest].speed(), samples[nearest - 1].speed());
  EXPECT_LE(samples[nearest].speed(), samples[nearest + 1].speed());
}

// RobotReport.binding carries the arc-length span of each stretch along the path.
TEST_F(OptimizeTest, RobotBindingHasArcLengths) {
  const auto response = plan_ok(pa10_path_c_fastest());
  const auto& binding = response.robot().binding();
  ASSERT_GT(binding.size(), 0);
  EXPECT_GT(binding[binding.size() - 1].s_end(), 0.99 * response.arc_length());
  for (int i = 0; i < binding.size(); ++i) {
    EXPECT_LE(binding[i].s_start(), binding[i].s_end()) << "stretch " << i;
    if (i > 0) {
      EXPECT_EQ(binding[i].s_start(), binding[i - 1].s_end()) << "stretch " << i;
    }
  }
}

// Cartesian limits only: the time-optimal motion stays within maxSpeed and maxAcceleration
// (tangential and centripetal separately) and beats the conservative portion-wide cap.
TEST_F(OptimizeTest, TimeOptimalWithCartesianLimitsOnly) {
  constexpr double kMaxSpeed = 0.5;         // [m/s]
  constexpr double kMaxAcceleration = 2.0;  // [m/s^2]
  auto conservative = demo_request('a');
  conservative.mutable_motion()->set_duration_s(0.0);
  conservative.mutable_motion()->set_max_speed(kMaxSpeed);
  conservative.mutable_motion()->set_max_acceleration(kMaxAcceleration);
  auto request = conservative;
  request.mutable_optimize()->mutable_timing()->set_time_optimal(true);

  const auto fast = plan_ok(request);
  const auto slow = plan_ok(conservative);
  EXPECT_FALSE(slow.has_optimization());
  ASSERT_TRUE(fast.optimization().has_timing());
  const auto& timing = fast.optimization().timing();
  const double duration = fast.motion().duration_s();
  std::printf("[ measured ] path A, maxSpeed %.2g m/s, maxAcceleration %.2g m/s^2: durationS 0 alone %.4f s, "
              "timeOptimal %.4f s (server %.3f s)\n",
              kMaxSpeed, kMaxAcceleration, slow.motion().duration_s(), duration, timing.seconds());
  // durationS 0 with the trapezoid is the time-optimal motion already (no report without
  // `optimize`); the report's "before" is the conservative portion-wide speed cap.
  EXPECT_EQ(duration, slow.motion().duration_s());
  EXPECT_EQ(timing.objective_after(), duration);
  EXPECT_GT(timing.objective_before(), 1.5 * duration);
  expect_timing_binding(timing.binding(), fast.arc_length(), duration);
  for (const auto& b : timing.binding()) {
    EXPECT_THAT(b.kind(), AnyOf(Eq(v1::BINDING_KIND_CARTESIAN_SPEED),
                                Eq(v1::BINDING_KIND_CARTESIAN_TANGENTIAL_ACCELERATION),
                                Eq(v1::BINDING_KIND_CARTESIAN_CENTRIPETAL_ACCELERATION)));
  }

  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  ASSERT_EQ(samples.size(), fast.motion().sample_count());
  double top_speed = 0.0, top_tangential = 0.0, top_centripetal = 0.0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const auto& s = samples[k];
    const double vx = s.velocity().x(), vy = s.velocity().y(), vz = s.velocity().z();
    const double ax = s.acceleration().x(), ay = s.acceleration().y(), az = s.acceleration().z();
    const double v = std::sqrt(vx * vx + vy * vy + vz * vz);
    EXPECT_NEAR(s.speed(), v, 1e-9 * std::max(1.0, v)) << "sample " << k;
    EXPECT_LE(s.speed(), kMaxSpeed * (1 + 1e-9)) << "sample " << k;
    top_speed = std::max(top_speed, s.speed());
    if (v < 1e-9) continue;
    const double tangential = std::abs(ax * vx + ay * vy + az * vz) / v;
    const double cx = ay * vz - az * vy, cy = az * vx - ax * vz, cz = ax * vy - ay * vx;
    const double centripetal = std::sqrt(cx * cx + cy * cy + cz * cz) / v;
    EXPECT_LE(tangential, kMaxAcceleration * (1 + 1e-6)) << "sample " << k << " t " << s.t();
    EXPECT_LE(centripetal, kMaxAcceleration * (1 + 1e-6)) << "sample " << k << " t " << s.t();
    top_tangential = std::max(top_tangential, tangential);
    top_centripetal = std::max(top_centripetal, centripetal);
  }
  std::printf("[ measured ] streamed %zu samples: peak speed %.9f, tangential %.9f, centripetal %.9f\n",
              samples.size(), top_speed, top_tangential, top_centripetal);
  EXPECT_GT(std::max({top_speed / kMaxSpeed, top_tangential / kMaxAcceleration, top_centripetal / kMaxAcceleration}),
            0.99)
      << "some Cartesian limit is reached";
}

// Without a robot, timeOptimal needs maxAcceleration: a named field, not a crash.
TEST_F(OptimizeTest, TimeOptimalWithoutARobotNeedsMaxAcceleration) {
  auto request = demo_request('a');
  request.mutable_motion()->set_duration_s(0.0);
  request.mutable_motion()->set_max_speed(0.5);
  request.mutable_optimize()->mutable_timing()->set_time_optimal(true);
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
  EXPECT_NE(violation_of(bad_request_violations(status), "motion.maxAcceleration"), "");
}

// jerkLimited on the PA-10 (joint jerk unlimited in the model: the Cartesian ones absent too,
// so the NLP's jerk rows are loose) answers within the deadline with a feasible plan.
TEST_F(OptimizeTest, JerkLimitedAnswersWithinTheDeadline) {
  auto request = pa10_path_c_fastest();
  request.mutable_optimize()->mutable_timing()->set_time_optimal(true);
  request.mutable_optimize()->mutable_timing()->set_jerk_limited(true);
  // The server's largest budget (30 s): under the sanitizers on a loaded machine the default
  // 10 s can end the NLP before it converges, and the answer is then its best so far.
  request.mutable_optimize()->set_time_budget_s(30.0);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
  v1::PlanResponse response;
  const auto t0 = std::chrono::steady_clock::now();
  const auto status = stub_->PlanTrajectory(&ctx, request, &response);
  const double plan_s = seconds_since(t0);
  std::printf("[ measured ] jerkLimited: %s (%s) in %.3f s\n", status.ok() ? "OK" : "error",
              status.error_message().c_str(), plan_s);
  // The jerk-limited plan is checked sample by sample like the exact one, so the service
  // accepts it. With no jerk limit given it is the time-optimal motion again, on its coarser
  // grid (200 intervals against 1,000, 3 % slower: core/planning/time_optimal.hpp) and with
  // ramps at the rests (zero acceleration at both ends): no faster than the exact minimum,
  // and at most 6 % slower.
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_TRUE(response.optimization().has_timing());
  const auto exact_response = plan_ok(pa10_path_c_fastest());
  const double exact = exact_response.motion().duration_s();
  const auto& timing = response.optimization().timing();
  EXPECT_GE(response.motion().duration_s(), exact - exact_response.optimization().timing().duration_grid_error_s());
  EXPECT_LE(response.motion().duration_s(), 1.06 * exact);
  EXPECT_TRUE(response.robot().feasible());
  // The report says how the limits were checked between the samples.
  EXPECT_EQ(timing.check_rate_hz(), 2000.0);
  EXPECT_LE(timing.worst_limit_usage(), 1.0 + 1e-9);
  EXPECT_GT(timing.worst_limit_usage(), 0.99);
  EXPECT_GT(timing.duration_grid_error_s(), 0.0);
  std::printf("[ measured ] jerk-limited %.4f s against %.4f s without jerk limits\n",
              response.motion().duration_s(), exact);
}

// A PA-10 copied from ListRobots whose base joint may turn at 1e-9 rad/s: the time-optimal
// motion along demo path C would last about 2e9 s. The service answers at once with a clean
// error naming the motion (AJointTooSlowIsAFailedPrecondition checks the code).
v1::PlanRequest pa10_with_a_frozen_base(const v1::RobotModel& pa10) {
  auto request = pa10_path_c_fastest();
  auto model = pa10;
  model.mutable_limits(0)->set_max_velocity(1e-9);
  *request.mutable_robot()->mutable_model() = model;
  return request;
}

TEST_F(OptimizeTest, AJointTooSlowForThePathIsACleanError) {
  const auto request = pa10_with_a_frozen_base(robot_model("pa10"));
  v1::PlanResponse response;
  const auto t0 = std::chrono::steady_clock::now();
  const auto status = plan(request, response);
  const double plan_s = seconds_since(t0);
  std::printf("[ measured ] joint 0 at 1e-9 rad/s: code %d, \"%s\" (%.3f s)\n", static_cast<int>(status.error_code()),
              status.error_message().c_str(), plan_s);
  EXPECT_THAT(status.error_code(),
              AnyOf(Eq(grpc::StatusCode::FAILED_PRECONDITION), Eq(grpc::StatusCode::INVALID_ARGUMENT)));
  EXPECT_THAT(status.error_message(), HasSubstr("motion"));

  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  EXPECT_TRUE(samples.empty());
  EXPECT_EQ(stream_status.error_code(), status.error_code());
}

// The request is valid (durationS 0 asks for the fastest motion) and the joint limits allow
// only a motion too slow to stream: FAILED_PRECONDITION naming `motion.durationS`, the field
// whose 0 asked for the minimum time.
TEST_F(OptimizeTest, AJointTooSlowIsAFailedPrecondition) {
  const auto request = pa10_with_a_frozen_base(robot_model("pa10"));
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  const auto violations = precondition_violations(status);
  ASSERT_FALSE(violations.empty());
  EXPECT_EQ(violations[0].subject(), "motion.durationS");
  EXPECT_THAT(violations[0].description(), HasSubstr("samples"));
}

// A path out of the arm's reach: no grid point has an IK solution, a FAILED_PRECONDITION
// that names `motion` and where.
TEST_F(OptimizeTest, APathOutOfReachIsAFailedPrecondition) {
  auto request = pa10_path_c_fastest();
  for (auto& f : *request.mutable_path()->mutable_frames()) f.mutable_position()->set_x(f.position().x() + 3.0);
  v1::PlanResponse response;
  const auto status = plan(request, response);
  std::printf("[ measured ] out of reach: %d %s\n", static_cast<int>(status.error_code()),
              status.error_message().c_str());
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  const auto violations = precondition_violations(status);
  ASSERT_FALSE(violations.empty());
  EXPECT_THAT(status.error_message(), HasSubstr("s = "));
}

}  // namespace
}  // namespace geotraj::testing
