// TrajectoryService through a generated stub on a loopback port: the thesis's worked
// numbers (golden), the closed loop of PlanTrajectory, the profiles of AnalyzePath.
#include <algorithm>
#include <cmath>
#include <ostream>
#include <string>

#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

struct Expected3 {
  double x, y, z;
};

// |actual - expected| per component within rel * max(|expected|, floor): the thesis rounds
// its inputs (0.707 for 1/sqrt(2)) and prints 3 to 5 significant digits.
void expect_near(const v1::Vec3& actual, Expected3 e, double rel, double floor, const std::string& what) {
  const double scale = std::max({std::abs(e.x), std::abs(e.y), std::abs(e.z), floor});
  EXPECT_NEAR(actual.x(), e.x, rel * scale) << what << ".x";
  EXPECT_NEAR(actual.y(), e.y, rel * scale) << what << ".y";
  EXPECT_NEAR(actual.z(), e.z, rel * scale) << what << ".z";
}

v1::ConvertRequest convert_request_of(const v1::PlanRequest& plan) {
  v1::ConvertRequest request;
  *request.mutable_path() = plan.path();
  return request;
}

// --- ConvertConstraints: thesis Tables 5.10/5.11 ------------------------------------------

// Table 5.11, frame 2, from Table 5.10 with the erratum of thesis-notes.md (dp/du = T2, not
// the printed (0, 0.707, -0.707)). Per parameter, tangent scale 1. The thesis rounds T2 and
// N2 to 4 digits, so the derivatives agree to about 1e-3 relative.
TEST_F(ServerTest, Table_5_11_Frame2_ParametricConstraints) {
  v1::ConvertResponse response;
  const auto status = convert(example<v1::ConvertRequest>("convert_table_5_10.json"), response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(response.frames_size(), 3);
  for (const auto* side : {&response.frames(1).approach(), &response.frames(1).leave()}) {
    ASSERT_EQ(side->derivatives_size(), 4) << "curvature, its derivative, torsion and its derivative fix order 4";
    constexpr double rel = 2e-3;
    expect_near(side->derivatives(0), {0.707, 0.3536, 0.6124}, rel, 1.0, "d1");
    expect_near(side->derivatives(1), {0.0, -2.598, 1.5}, rel, 1.0, "d2");
    expect_near(side->derivatives(2), {-10.606, 13.962, 4.183}, rel, 1.0, "d3");
    expect_near(side->derivatives(3), {123.745, -61.861, -107.142}, rel, 1.0, "d4");
  }
  // Frames 1 and 3 give only a tangent (the printed zeros of kappa' and tau' with kappa = 0
  // are "not given": thesis footnote 5), so only d1 is fixed.
  EXPECT_EQ(response.frames(0).leave().derivatives_size(), 1);
  expect_near(response.frames(0).leave().derivatives(0), {1, 0, 0}, 1e-12, 1.0, "frame 1 d1");
  EXPECT_EQ(response.frames(2).approach().derivatives_size(), 1);
  expect_near(response.frames(2).approach().derivatives(0), {0, -1, 0}, 1e-12, 1.0, "frame 3 d1");
  expect_near(response.frames(2).position(), {2, -2, -0.5}, 1e-12, 1.0, "frame 3 position");
}

// --- ConvertConstraints: thesis Tables 7.19 and 7.20 (the demonstration) --------------------

struct DemoRow {
  char path;
  Expected3 frame2_d2, frame2_d3;  // Table 7.19 (path A's d2z with the erratum: -0.3125)
  Expected3 frame3_d2, frame3_d3;  // Table 7.20, approach side
};

// Test names show the path, not the bytes of the row.
void PrintTo(const DemoRow& row, std::ostream* os) { *os << "path " << row.path; }

class DemoConversion : public ServerTest, public ::testing::WithParamInterface<DemoRow> {};

TEST_P(DemoConversion, Tables_7_19_7_20) {
  const DemoRow row = GetParam();
  v1::ConvertResponse response;
  const auto status = convert(convert_request_of(demo_request(row.path)), response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(response.frames_size(), 4);
  constexpr double rel = 1e-4;  // the tables print 4 to 5 significant digits

  const auto& f2 = response.frames(1).approach();
  ASSERT_EQ(f2.derivatives_size(), 3) << "curvature and torsion fix order 3";
  expect_near(f2.derivatives(0), {0, -0.25, 0}, rel, 1.0, "frame 2 d1");
  expect_near(f2.derivatives(1), row.frame2_d2, rel, 1.0, "frame 2 d2");
  expect_near(f2.derivatives(2), row.frame2_d3, rel, 1.0, "frame 2 d3");

  const auto& f3 = response.frames(2).approach();
  ASSERT_EQ(f3.derivatives_size(), 3);
  expect_near(f3.derivatives(0), {0.25, 0, 0}, rel, 1.0, "frame 3 d1");
  expect_near(f3.derivatives(1), row.frame3_d2, rel, 1.0, "frame 3 d2");
  expect_near(f3.derivatives(2), row.frame3_d3, rel, 1.0, "frame 3 d3");

  // Frame 3 is a cusp: the leaving side runs back along -T.
  const auto& f3_leave = response.frames(2).leave();
  ASSERT_GE(f3_leave.derivatives_size(), 1);
  expect_near(f3_leave.derivatives(0), {-0.25, 0, 0}, 1e-12, 1.0, "frame 3 leave d1");
  expect_near(f3_leave.tangent(), {-1, 0, 0}, 1e-12, 1.0, "frame 3 leave tangent");

  // Frames 1 and 4 give only a tangent.
  EXPECT_EQ(response.frames(0).leave().derivatives_size(), 1);
  EXPECT_EQ(response.frames(3).approach().derivatives_size(), 1);
}

INSTANTIATE_TEST_SUITE_P(PathsABC, DemoConversion,
                         ::testing::Values(
                             DemoRow{'a', {0, 0, -0.3125}, {-3.9063, 0, 0}, {0, 0.0625, 0}, {0, 0, 0}},
                             DemoRow{'b', {0, 0, -0.625}, {-7.8125, 0, 0}, {0, 0.625, 0}, {0, 0, 15.625}},
                             DemoRow{'c', {0, 0, -1.25}, {-15.625, 0, 0}, {0, 0.625, 0}, {0, 0, -15.625}}),
                         [](const auto& p) { return std::string("Path") + static_cast<char>(p.param.path - 32); });

// --- PlanTrajectory ---------------------------------------------------------------------------

class DemoPlan : public ServerTest, public ::testing::WithParamInterface<char> {};

TEST_P(DemoPlan, ClosedLoopAndAdditiveArcLengths) {
  const v1::PlanRequest request = demo_request(GetParam());
  ASSERT_TRUE(request.has_motion()) << "the example carries a motion, which PlanTrajectory accepts";
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_TRUE(status.ok()) << status.error_message();

  EXPECT_LT(response.closed_loop().max_error(), 1e-9) << "worst at " << response.closed_loop().worst_field();

  ASSERT_EQ(response.segments_size(), 3);
  double sum = 0.0;
  for (int i = 0; i < response.segments_size(); ++i) {
    const auto& s = response.segments(i);
    EXPECT_EQ(s.index(), static_cast<unsigned>(i));
    EXPECT_EQ(s.from_frame(), static_cast<unsigned>(i));
    EXPECT_EQ(s.to_frame(), static_cast<unsigned>(i + 1));
    EXPECT_GT(s.arc_length(), 0.0);
    EXPECT_EQ(s.blend(), v1::BLEND_METHOD_POLYNOMIAL);
    EXPECT_EQ(s.degree(), s.start_order() + s.end_order() + 1);
    sum += s.arc_length();
  }
  EXPECT_NEAR(response.arc_length(), sum, 1e-12 * sum);
  // Every segment is longer than the chord between its frames.
  EXPECT_GT(response.segments(0).arc_length(), std::hypot(0.4 - 0.106, 0.15, 0.5 - 0.975));

  ASSERT_EQ(response.frames_size(), 4);
  EXPECT_FALSE(response.frames(0).has_approach()) << "an open path has no segment arriving at its first frame";
  EXPECT_TRUE(response.frames(0).has_leave());
  EXPECT_TRUE(response.frames(3).has_approach());
  EXPECT_FALSE(response.frames(3).has_leave());
  const auto& f2 = response.frames(1).approach();
  EXPECT_NEAR(f2.speed(), 0.25, 1e-12);
  ASSERT_TRUE(f2.has_curvature() && f2.has_torsion() && f2.has_normal() && f2.has_binormal());
  EXPECT_NEAR(f2.curvature(), request.path().frames(1).curvature(), 1e-9);
  EXPECT_NEAR(f2.torsion(), request.path().frames(1).torsion(), 1e-9 * 50);
  EXPECT_TRUE(f2.has_curvature_derivative() && f2.has_torsion_derivative());
  EXPECT_NEAR(response.frames(2).leave().tangent().x(), -1.0, 1e-12) << "frame 3 is a cusp";

  // The example's motion: 10 s at 100 Hz, two rest-to-rest portions (the cusp), the same
  // peak speed L / (T (1 - 0.15)) on both (Eqs. 6.11-6.13).
  ASSERT_TRUE(response.has_motion());
  EXPECT_DOUBLE_EQ(response.motion().duration_s(), 10.0);
  EXPECT_EQ(response.motion().sample_count(), 1001u);
  EXPECT_NEAR(response.motion().peak_speed(), response.arc_length() / (10.0 * 0.85), 1e-12);
  EXPECT_FALSE(response.has_robot());
  EXPECT_FALSE(response.has_optimization());
}

INSTANTIATE_TEST_SUITE_P(PathsABC, DemoPlan, ::testing::Values('a', 'b', 'c'),
                         [](const auto& p) { return std::string("Path") + static_cast<char>(p.param - 32); });

// A closed path of three frames on a circle, trapezoid-blended: three segments, the last
// one returning to frame 0, the trapezoid orders reported per axis.
TEST_F(ServerTest, PlanClosedTrapezoidPath) {
  const auto request = from_json<v1::PlanRequest>(R"({"path": {
      "closed": true, "blend": "BLEND_METHOD_TRAPEZOIDAL",
      "frames": [
        {"position": {"x": 1, "y": 0, "z": 0}, "tangent": {"x": 0, "y": 1, "z": 0}},
        {"position": {"x": -0.5, "y": 0.866, "z": 0}, "tangent": {"x": -0.866, "y": -0.5, "z": 0}},
        {"position": {"x": -0.5, "y": -0.866, "z": 0}, "tangent": {"x": 0.866, "y": -0.5, "z": 0}}]}})");
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(response.segments_size(), 3);
  EXPECT_EQ(response.segments(2).from_frame(), 2u);
  EXPECT_EQ(response.segments(2).to_frame(), 0u);
  for (const auto& s : response.segments()) {
    EXPECT_EQ(s.blend(), v1::BLEND_METHOD_TRAPEZOIDAL);
    ASSERT_EQ(s.trapezoid_orders_size(), 3);
    for (auto n : s.trapezoid_orders()) EXPECT_EQ(n, 5u) << "the smoothest reading fixes orders 1-4 at every frame: 4 + 1";
  }
  for (const auto& f : response.frames()) {
    EXPECT_TRUE(f.has_approach() && f.has_leave()) << "every frame of a closed path has both sides";
  }
  EXPECT_LT(response.closed_loop().max_error(), 1e-9) << response.closed_loop().worst_field();
}

// --- The geometry between frames and the plan's warnings ---------------------------------------

// The README's minimal request; `middle_scale` > 0 sets the middle frame's tangent scale.
v1::PlanRequest readme_request(double middle_scale) {
  auto request = from_json<v1::PlanRequest>(R"({"path": {"frames": [
      {"position": {"x": 0, "y": 0, "z": 0}, "tangent": {"x": 1}, "tangentScale": 0.5},
      {"position": {"x": 0.3, "y": 0.2, "z": 0.1}, "tangent": {"y": 1}, "normal": {"x": -1},
       "curvature": 5, "torsion": 2},
      {"position": {"x": 0.1, "y": 0.5, "z": 0.1}, "tangent": {"x": -1}, "tangentScale": 0.5}]}})");
  if (middle_scale > 0.0) request.mutable_path()->mutable_frames(1)->set_tangent_scale(middle_scale);
  return request;
}

// With the old 1 m default at its middle frame (and lowest-degree segments, the old reading)
// the README's request doubles back with a 15 um radius: the plan says so, at the point; as
// the README gives it, it is gentle and quiet. The extremes are where they say (a dense
// AnalyzePath agrees) and each names u and s.
TEST_F(ServerTest, PlanReportsGeometryBetweenFramesAndWarnings) {
  auto kinked = readme_request(1.0);
  kinked.mutable_path()->set_unspecified(v1::UNSPECIFIED_CONSTRAINTS_LOWEST_DEGREE);
  v1::PlanResponse response;
  auto status = plan(kinked, response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(response.segments_size(), 2);
  const auto& seg = response.segments(1);
  EXPECT_GT(seg.peak_curvature().value(), 1e4);
  EXPECT_LT(seg.min_speed().value(), 0.1 * seg.arc_length());
  EXPECT_GT(seg.min_speed().u(), 1.0);
  EXPECT_LT(seg.min_speed().u(), 2.0);
  EXPECT_GT(seg.min_speed().s(), response.segments(0).arc_length());
  // Segment 0 curls too (its tangent turns about 4.5 rad more than its ends need).
  const auto near_cusp = std::find_if(response.warnings().begin(), response.warnings().end(),
                                      [](const auto& x) { return x.code() == v1::PLAN_WARNING_CODE_NEAR_CUSP; });
  ASSERT_NE(near_cusp, response.warnings().end());
  const auto& w = *near_cusp;
  EXPECT_EQ(w.segment(), 1u);
  EXPECT_DOUBLE_EQ(w.value(), seg.min_speed().value());
  EXPECT_DOUBLE_EQ(w.u(), seg.min_speed().u());
  EXPECT_NE(w.message().find("tangent scales"), std::string::npos) << w.message();

  // The profile around the reported minimum never goes below it.
  kinked.set_analysis_points(20001);
  v1::PathProfile profile;
  status = analyze(kinked, profile);
  ASSERT_TRUE(status.ok()) << status.error_message();
  double peak = 0.0;
  for (const auto& p : profile.points()) {
    if (p.segment() == 1 && p.has_curvature()) peak = std::max(peak, p.curvature());
  }
  EXPECT_GE(seg.peak_curvature().value(), peak * (1 - 1e-9));

  response.Clear();
  status = plan(readme_request(0.0), response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.warnings_size(), 0) << response.warnings(0).message();
  for (const auto& g : response.segments()) {
    EXPECT_GT(g.peak_curvature().value(), 0.0);
    EXPECT_LT(g.peak_curvature().value(), 20.0);
    EXPECT_GT(g.turning(), 0.0);
  }

  // maxCurvature below the README's bends: a TIGHT_BEND per segment; bad values named.
  auto tight = readme_request(0.0);
  tight.mutable_path()->set_max_curvature(1.0);
  response.Clear();
  ASSERT_TRUE(plan(tight, response).ok());
  ASSERT_EQ(response.warnings_size(), 2);
  for (const auto& t : response.warnings()) EXPECT_EQ(t.code(), v1::PLAN_WARNING_CODE_TIGHT_BEND);
  tight.mutable_path()->set_max_curvature(-1.0);
  status = plan(tight, response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const auto violations = bad_request_violations(status);
  ASSERT_EQ(violations.size(), 1u);
  EXPECT_EQ(violations[0].field, "path.maxCurvature");
}

// MotionSummary: the peaks are those of the streamed samples: the whole acceleration
// (tangential and centripetal, larger than the profile's tangential part on a curve) and the
// tool's angular speed, checked against finite differences of the streamed orientations.
TEST_F(ServerTest, MotionSummaryPeaksAreThoseOfTheSamples) {
  auto request = demo_example('a');
  for (auto& f : *request.mutable_path()->mutable_frames()) f.set_orientation_mode(v1::ORIENTATION_MODE_FRAME_BASED);
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  grpc::Status stream_status;
  const auto samples = stream_all(request, stream_status);
  ASSERT_TRUE(stream_status.ok()) << stream_status.error_message();
  ASSERT_EQ(samples.size(), response.motion().sample_count());
  double peak_a = 0.0, peak_v = 0.0, peak_w_fd = 0.0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const auto& a = samples[k].acceleration();
    peak_a = std::max(peak_a, std::sqrt(a.x() * a.x() + a.y() * a.y() + a.z() * a.z()));
    peak_v = std::max(peak_v, samples[k].speed());
    if (k == 0) continue;
    const auto& q0 = samples[k - 1].orientation();
    const auto& q1 = samples[k].orientation();
    const double dot = std::abs(q0.w() * q1.w() + q0.x() * q1.x() + q0.y() * q1.y() + q0.z() * q1.z());
    peak_w_fd = std::max(peak_w_fd, 2.0 * std::acos(std::min(1.0, dot)) / (samples[k].t() - samples[k - 1].t()));
  }
  const auto& m = response.motion();
  EXPECT_DOUBLE_EQ(m.peak_acceleration(), peak_a);
  EXPECT_DOUBLE_EQ(m.peak_speed(), peak_v);
  EXPECT_GT(m.peak_acceleration(), 1.5 * m.peak_tangential_acceleration()) << "the centripetal part counts";
  EXPECT_GT(m.peak_angular_speed(), 0.0);
  EXPECT_NEAR(m.peak_angular_speed(), peak_w_fd, 0.02 * peak_w_fd);
}

// FIXED orientation on a straight start (frame 0 without a normal): the tool keeps the
// orientation the robot holds at its initial joints; without a robot, the world axes.
TEST_F(ServerTest, FixedOrientationOnAStraightStart) {
  auto request = from_json<v1::PlanRequest>(R"({"path": {"frames": [
      {"position": {"x": 0.5, "y": 0.0, "z": 0.5}, "tangent": {"y": 1}},
      {"position": {"x": 0.5, "y": 0.2, "z": 0.5}, "tangent": {"y": 1}}]},
      "motion": {"durationS": 2}})");
  grpc::Status status;
  auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_FALSE(samples.empty());
  for (const auto& s : samples) EXPECT_NEAR(std::abs(s.orientation().w()), 1.0, 1e-12);
}

// --- AnalyzePath -------------------------------------------------------------------------------

TEST_F(ServerTest, AnalyzeDemoPathCountsAndFields) {
  auto request = demo_request('a');
  request.set_analysis_points(61);
  v1::PathProfile profile;
  const auto status = analyze(request, profile);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(profile.points_size(), 61);
  EXPECT_EQ(profile.points(0).u(), 0.0);
  EXPECT_EQ(profile.points(60).u(), 3.0) << "u spans all three segments, both ends included";
  EXPECT_EQ(profile.points(60).segment(), 2u);
  EXPECT_DOUBLE_EQ(profile.points(60).s(), profile.arc_length());
  for (int i = 0; i < profile.points_size(); ++i) {
    const auto& p = profile.points(i);
    if (i > 0) {
      EXPECT_GT(p.u(), profile.points(i - 1).u());
      EXPECT_GE(p.s(), profile.points(i - 1).s());
    }
    EXPECT_TRUE(p.has_position());
    // The demonstration path bends everywhere it is sampled here.
    EXPECT_TRUE(p.has_tangent() && p.has_curvature()) << "point " << i;
    EXPECT_TRUE(p.has_normal() && p.has_binormal() && p.has_torsion()) << "point " << i;
    EXPECT_TRUE(p.has_curvature_derivative() && p.has_torsion_derivative()) << "point " << i;
  }
  // At frame 2 (u = 1, the start of segment 1) the path has the requested curvature.
  EXPECT_EQ(profile.points(20).u(), 1.0);
  EXPECT_EQ(profile.points(20).segment(), 1u);
  EXPECT_NEAR(profile.points(20).curvature(), 5.0, 1e-9);
  EXPECT_NEAR(profile.points(20).torsion(), -50.0, 1e-7);

  v1::PlanResponse plan_response;
  ASSERT_TRUE(plan(request, plan_response).ok());
  EXPECT_NEAR(profile.arc_length(), plan_response.arc_length(), 1e-12);
}

TEST_F(ServerTest, AnalyzeStraightLineHasNoNormalNorTorsion) {
  const auto request = from_json<v1::PlanRequest>(R"({"analysisPoints": 5, "path": {"frames": [
      {"position": {"x": 0, "y": 0, "z": 0}, "tangent": {"x": 0, "y": 0, "z": 1}},
      {"position": {"x": 0, "y": 0, "z": 2}, "tangent": {"x": 0, "y": 0, "z": 1}, "tangentScale": 2}]}})");
  v1::PathProfile profile;
  const auto status = analyze(request, profile);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(profile.points_size(), 5);
  EXPECT_NEAR(profile.arc_length(), 2.0, 1e-12);
  for (const auto& p : profile.points()) {
    ASSERT_TRUE(p.has_tangent() && p.has_curvature());
    EXPECT_NEAR(p.tangent().z(), 1.0, 1e-12);
    EXPECT_EQ(p.curvature(), 0.0);
    EXPECT_FALSE(p.has_normal()) << "u = " << p.u();
    EXPECT_FALSE(p.has_binormal()) << "u = " << p.u();
    EXPECT_FALSE(p.has_torsion()) << "u = " << p.u();
    EXPECT_FALSE(p.has_curvature_derivative()) << "u = " << p.u();
    EXPECT_FALSE(p.has_torsion_derivative()) << "u = " << p.u();
  }
}

TEST_F(ServerTest, AnalyzeDefaultsTo101Points) {
  auto request = demo_request('b');
  request.clear_analysis_points();
  v1::PathProfile profile;
  const auto status = analyze(request, profile);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(profile.points_size(), 101);
}

}  // namespace
}  // namespace geotraj::testing
