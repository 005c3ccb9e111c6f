// Bad input gets INVALID_ARGUMENT with a google.rpc.BadRequest naming each field; features
// of later work get UNIMPLEMENTED naming what is missing.
#include <string>

#include <gmock/gmock.h>

#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

// A valid two-frame path to break one field at a time.
v1::PlanRequest two_frames() {
  return from_json<v1::PlanRequest>(R"({"path": {"frames": [
      {"position": {"x": 0, "y": 0, "z": 0}, "tangent": {"x": 1, "y": 0, "z": 0}},
      {"position": {"x": 1, "y": 0, "z": 0}, "tangent": {"x": 1, "y": 0, "z": 0}}]}})");
}

class ErrorTest : public ServerTest {
 protected:
  // PlanTrajectory's violations, after checking the status code and the details' shape.
  std::vector<Violation> plan_violations(const v1::PlanRequest& request) {
    v1::PlanResponse response;
    const auto status = plan(request, response);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << status.error_message();
    return bad_request_violations(status);
  }
};

TEST_F(ErrorTest, TorsionWithZeroCurvatureNamesTheTorsion) {
  auto request = two_frames();
  request.mutable_path()->mutable_frames(1)->set_curvature(0.0);
  request.mutable_path()->mutable_frames(1)->set_torsion(3.0);
  const auto violations = plan_violations(request);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "path.frames[1].torsion");
  EXPECT_THAT(violations[0].description, HasSubstr("curvature"));
}

TEST_F(ErrorTest, NonUnitTangentNamesTheTangent) {
  auto request = two_frames();
  request.mutable_path()->mutable_frames(0)->mutable_tangent()->set_x(2.0);
  const auto violations = plan_violations(request);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "path.frames[0].tangent");
  EXPECT_THAT(violations[0].description, HasSubstr("unit"));
}

TEST_F(ErrorTest, MissingTangentIsRequired) {
  auto request = two_frames();
  request.mutable_path()->mutable_frames(1)->clear_tangent();
  const auto violations = plan_violations(request);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "path.frames[1].tangent");
  EXPECT_THAT(violations[0].description, HasSubstr("required"));
}

TEST_F(ErrorTest, MissingPathIsRequired) {
  v1::PlanRequest request;
  const auto violations = plan_violations(request);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "path");

  v1::ConvertResponse response;
  const auto status = convert(v1::ConvertRequest{}, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(violation_of(bad_request_violations(status), "path"), "");
}

TEST_F(ErrorTest, OneFrameIsNotAPath) {
  auto request = two_frames();
  request.mutable_path()->mutable_frames()->RemoveLast();
  v1::ConvertRequest convert_request;
  *convert_request.mutable_path() = request.path();
  v1::ConvertResponse response;
  const auto status = convert(convert_request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const auto violations = bad_request_violations(status);
  EXPECT_THAT(violation_of(violations, "path.frames"), HasSubstr("at least 2")) << describe(violations);
}

TEST_F(ErrorTest, AnalysisPointsOutOfRange) {
  for (const unsigned points : {0u, 1u, 1000001u}) {
    auto request = two_frames();
    request.set_analysis_points(points);
    v1::PathProfile profile;
    const auto status = analyze(request, profile);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << points;
    const auto violations = bad_request_violations(status);
    ASSERT_EQ(violations.size(), 1u) << describe(violations);
    EXPECT_EQ(violations[0].field, "analysisPoints");
    EXPECT_THAT(violations[0].description, HasSubstr(std::to_string(points)));
  }
  // The JSON form too: an explicit 0 is given, not absent.
  auto request = from_json<v1::PlanRequest>(R"({"analysisPoints": 0})");
  EXPECT_TRUE(request.has_analysis_points());
}

TEST_F(ErrorTest, UnknownEnumValuesAreNamed) {
  auto request = two_frames();
  request.mutable_path()->set_derivative_convention(static_cast<v1::DerivativeConvention>(7));
  request.mutable_path()->set_blend(static_cast<v1::BlendMethod>(9));
  request.mutable_path()->mutable_frames(0)->set_orientation_mode(static_cast<v1::OrientationMode>(42));
  const auto violations = plan_violations(request);
  ASSERT_EQ(violations.size(), 3u) << describe(violations);
  EXPECT_THAT(violation_of(violations, "path.derivativeConvention"), HasSubstr("DERIVATIVE_CONVENTION_PER_PARAMETER"));
  EXPECT_THAT(violation_of(violations, "path.blend"), HasSubstr("9"));
  EXPECT_THAT(violation_of(violations, "path.frames[0].orientationMode"), HasSubstr("42"));
}

TEST_F(ErrorTest, CustomOrientationNeedsAUnitQuaternion) {
  auto request = two_frames();
  request.mutable_path()->mutable_frames(0)->set_orientation_mode(v1::ORIENTATION_MODE_CUSTOM);
  request.mutable_path()->mutable_frames(1)->mutable_orientation()->set_w(0.5);  // mode is not CUSTOM
  auto violations = plan_violations(request);
  EXPECT_THAT(violation_of(violations, "path.frames[0].orientation"), HasSubstr("required")) << describe(violations);
  EXPECT_THAT(violation_of(violations, "path.frames[1].orientation"), HasSubstr("CUSTOM")) << describe(violations);
}

// Every problem of the request in one answer: the wire checks and core's together, and the
// message names them for clients that do not read the details.
TEST_F(ErrorTest, AllViolationsAreCollected) {
  const auto request = example<v1::PlanRequest>("bad_request.json");
  v1::PathProfile profile;
  const auto status = analyze(request, profile);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const auto violations = bad_request_violations(status);
  EXPECT_EQ(violations.size(), 4u) << describe(violations);
  for (const char* field : {"path.frames[0].tangent", "path.frames[1].torsion", "path.frames[2].tangent",
                            "analysisPoints"}) {
    EXPECT_NE(violation_of(violations, field), "") << field << " missing from\n" << describe(violations);
    EXPECT_THAT(status.error_message(), HasSubstr(field));
  }
}

// Bad optimisation requests name their fields: a budget that is no time, breakpoints on a
// polynomial blend, an objective out of range, and optimize on a move.
TEST_F(ErrorTest, BadOptimizationRequestsNameTheirFields) {
  auto request = demo_request('a');
  request.mutable_optimize()->set_time_budget_s(-1.0);
  request.mutable_optimize()->mutable_tangent_scales()->set_objective(static_cast<v1::TangentScaleObjective>(42));
  auto violations = plan_violations(request);
  EXPECT_NE(violation_of(violations, "optimize.timeBudgetS"), "") << describe(violations);
  EXPECT_NE(violation_of(violations, "optimize.tangentScales.objective"), "") << describe(violations);

  request = demo_request('a');
  request.mutable_optimize()->mutable_breakpoints();
  violations = plan_violations(request);
  ASSERT_EQ(violations.size(), 1u) << describe(violations);
  EXPECT_EQ(violations[0].field, "path.blend");

  v1::PlanRequest move;
  move.mutable_robot()->set_name("pa10");
  move.mutable_motion()->set_duration_s(2.0);
  for (double q : {0.1, 0.2, 0.3, 1.0, 0.0, 0.5, 0.0}) move.mutable_joint_move()->add_goal(q);
  move.mutable_optimize()->mutable_timing()->set_time_optimal(true);
  violations = plan_violations(move);
  EXPECT_NE(violation_of(violations, "optimize"), "") << describe(violations);
}

// A stream refused before any sample: its final status.
grpc::Status refused_stream(v1::TrajectoryService::Stub& stub, const v1::PlanRequest& request) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  auto reader = stub.StreamSamples(&context, request);
  v1::SampleBatch batch;
  EXPECT_FALSE(reader->Read(&batch)) << "a sample arrived";
  return reader->Finish();
}

TEST_F(ErrorTest, StreamSamplesNeedsAMotion) {
  auto request = demo_request('a');
  request.clear_motion();
  const auto status = refused_stream(*stub_, request);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("motion"));
}

TEST_F(ErrorTest, StreamSamplesNamesBadMotionFields) {
  auto request = demo_request('a');
  request.mutable_motion()->set_ramp_fraction(0.7);
  request.mutable_motion()->set_cycle_rate_hz(0.0);
  const auto status = refused_stream(*stub_, request);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("motion.rampFraction"));
  EXPECT_THAT(status.error_message(), HasSubstr("motion.cycleRateHz"));
}

}  // namespace
}  // namespace geotraj::testing
