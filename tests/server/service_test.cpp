// TrajectoryService through a generated stub on a loopback port: the thesis's worked
// numbers (golden), the closed loop of PlanTrajectory, the profiles of AnalyzePath.
#include <cmath>
#include <ostream>
#include <string>

#include "test_server.hpp"

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
