// Paths of pieces through the real service: a weld seam (line, quarter arc, line) with
// transitions on the UR5e and the Panda, streamed at 1 and 4 kHz and measured on the
// samples (straight and round outside the transitions, within the tolerance inside, never
// at rest, the tool's acceleration continuous, the nozzle held, every joint within its
// limits by finite differences); a curvature and torsion profile recovered by AnalyzePath;
// bad pieces named by field.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <gmock/gmock.h>

#include "tests/server/support/dh_reference.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;
using Eigen::Vector3d;
constexpr double kPi = std::numbers::pi;

class PiecesTest : public ServerTest {};

void set(v1::Vec3* out, const Vector3d& v) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}
Vector3d vec3(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

// A seam in the plane of (t, n) through p0: a line of length a along t, a quarter arc of
// radius r turning towards n, a line of length b along n.
struct Seam {
  Vector3d p0, t, n;
  double a = 0.1, r = 0.04, b = 0.1;

  // Distance [m] from q to the programmed seam, in the seam's own coordinates.
  double distance(const Vector3d& q) const {
    const Vector3d d = q - p0;
    const double x = d.dot(t), y = d.dot(n), z = d.dot(t.cross(n));
    double best = std::hypot(std::max({0.0, x - a, -x}), y, z);
    best = std::min(best, std::hypot(x - (a + r), std::max({0.0, y - r - b, r - y}), z));
    const double cx = x - a, cy = y - r;  // from the arc's centre
    if (cx >= 0.0 && cy <= 0.0) best = std::min(best, std::hypot(std::hypot(cx, cy) - r, z));
    return best;
  }

  v1::PlanRequest request(const std::string& robot, double rate_hz, double tolerance) const {
    auto request = from_json<v1::PlanRequest>(R"({"path": {"pieces": [
        {"lengthM": 0.1, "line": {}}, {"lengthM": 0.0628318530717958648, "arc": {"radius": 0.04}},
        {"lengthM": 0.1, "line": {}}]},
        "motion": {"durationS": 0, "profile": "MOTION_PROFILE_S_CURVE", "maxSpeed": 0.25, "maxAcceleration": 1.5,
                   "maxJerk": 20}})");
    auto& path = *request.mutable_path();
    set(path.mutable_start()->mutable_position(), p0);
    set(path.mutable_start()->mutable_tangent(), t);
    set(path.mutable_start()->mutable_normal(), n);
    path.set_transition_tolerance(tolerance);
    request.mutable_motion()->set_cycle_rate_hz(rate_hz);
    request.mutable_robot()->set_name(robot);
    return request;
  }
};

// The seam from the robot's home tool position, in a horizontal plane, along the world's x
// axis then towards the robot's base side.
Seam seam_at_home(const v1::RobotModel& model) {
  const Eigen::Isometry3d X = forward_kinematics(model, model.home());
  Seam seam;
  seam.p0 = X.translation();
  const Vector3d radial = Vector3d(seam.p0.x(), seam.p0.y(), 0.0).normalized();
  seam.t = Vector3d::UnitZ().cross(radial);  // around the base
  seam.n = -radial;                          // then inwards
  return seam;
}

// Every joint of `samples` within `model`'s limits, by finite differences of what is
// streamed (non-uniform steps: the last one may be shorter).
void expect_within_joint_limits(const v1::RobotModel& model, const std::vector<v1::Sample>& samples,
                                const std::string& what) {
  for (std::size_t k = 1; k + 1 < samples.size(); ++k) {
    for (int j = 0; j < model.limits_size(); ++j) {
      const auto& l = model.limits(j);
      const double q0 = samples[k - 1].joints(j), q1 = samples[k].joints(j), q2 = samples[k + 1].joints(j);
      ASSERT_GE(q1, l.min_position()) << what << " joint " << j;
      ASSERT_LE(q1, l.max_position()) << what << " joint " << j;
      const double h1 = samples[k].t() - samples[k - 1].t(), h2 = samples[k + 1].t() - samples[k].t();
      const double v = (q1 - q0) / h1;
      ASSERT_LE(std::abs(v), l.max_velocity() * (1 + 1e-3)) << what << " joint " << j << " t " << samples[k].t();
      const double acc = 2.0 * ((q2 - q1) / h2 - v) / (h1 + h2);
      ASSERT_LE(std::abs(acc), l.max_acceleration() * (1 + 2e-2)) << what << " joint " << j << " t " << samples[k].t();
    }
  }
}

TEST_F(PiecesTest, ASeamIsStraightAndRoundOutsideItsTransitionsOnTheUr5eAndThePanda) {
  constexpr double kTolerance = 2e-4;
  for (const std::string robot : {"ur5e", "panda"}) {
    const auto model = robot_model(robot);
    const Seam seam = seam_at_home(model);
    const Eigen::Quaterniond q_home(forward_kinematics(model, model.home()).linear());
    double jump_at[2] = {0.0, 0.0};  // the largest step of the tool's acceleration [m/s^2]
    for (const double rate : {1000.0, 4000.0}) {
      const auto request = seam.request(robot, rate, kTolerance);
      const v1::PlanResponse plan = plan_ok(request);
      ASSERT_EQ(plan.segments_size(), 5) << robot;
      std::vector<v1::SegmentKind> kind;
      for (const auto& s : plan.segments()) kind.push_back(s.kind());
      EXPECT_EQ(kind[1], v1::SEGMENT_KIND_TRANSITION);
      EXPECT_EQ(kind[2], v1::SEGMENT_KIND_PIECE);
      EXPECT_EQ(plan.segments(2).piece(), 1u);

      grpc::Status status;
      const auto samples = stream_all(request, status);
      ASSERT_TRUE(status.ok()) << robot << ": " << status.error_message();
      ASSERT_GT(samples.size(), 100u);
      double inside = 0.0, outside = 0.0, jump = 0.0;
      for (std::size_t k = 0; k < samples.size(); ++k) {
        const auto& s = samples[k];
        const double d = seam.distance(vec3(s.position()));
        (kind[s.segment()] == v1::SEGMENT_KIND_PIECE ? outside : inside) = std::max(
            kind[s.segment()] == v1::SEGMENT_KIND_PIECE ? outside : inside, d);
        if (k > 0 && k + 1 < samples.size()) {
          ASSERT_GT(s.speed(), 0.0) << robot << " rests at t " << s.t();
          jump = std::max(jump, (vec3(s.acceleration()) - vec3(samples[k - 1].acceleration())).norm());
        }
        ASSERT_LT(quat(s.orientation()).angularDistance(q_home), 1e-9) << "the nozzle is held";
      }
      EXPECT_LE(outside, 1e-9) << robot;
      EXPECT_LE(inside, kTolerance) << robot;
      jump_at[rate == 1000.0 ? 0 : 1] = jump;

      // Every joint within its limits, by finite differences of what is streamed.
      expect_within_joint_limits(model, samples, robot);
      std::printf("[ measured ] seam on the %s at %.0f Hz: %.4f s, %zu samples; deviation %.3g m in the transitions, "
                  "%.3g m outside; largest step of the tool's acceleration %.4g m/s^2\n",
                  robot.c_str(), rate, samples.back().t(), samples.size(), inside, outside, jump);
    }
    // Continuous: the acceleration's steps shrink with the cycle (jerk x dt), a jump would not.
    EXPECT_LT(jump_at[1], 0.4 * jump_at[0]) << robot;
  }
}

// Parallel transport on the seam (no robot): the tool's z axis along the path, and on the
// arc and its transitions a rotation about the seam plane's normal only (no twist).
TEST_F(PiecesTest, ParallelTransportTurnsTheToolAboutTheArcsAxis) {
  Seam seam;
  seam.p0 = Vector3d(0.4, 0.1, 0.3);
  seam.t = Vector3d::UnitX();
  seam.n = Vector3d::UnitY();
  auto request = seam.request("ur5e", 500.0, 1e-4);
  request.clear_robot();
  request.mutable_path()->mutable_start()->set_orientation_mode(v1::ORIENTATION_MODE_PARALLEL_TRANSPORT);
  request.mutable_motion()->set_duration_s(3.0);
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const Vector3d axis = seam.t.cross(seam.n);
  double turned = 0.0;
  for (std::size_t k = 1; k + 1 < samples.size(); ++k) {
    const auto& s = samples[k];
    const Vector3d z = quat(s.orientation()).toRotationMatrix().col(2);
    ASSERT_LT((z - vec3(s.velocity()).normalized()).norm(), 1e-9) << "t " << s.t();
    const Vector3d w = vec3(s.angular_velocity());
    ASSERT_LT((w - w.dot(axis) * axis).norm(), 1e-9) << "t " << s.t();
    turned += w.dot(axis) * (s.t() - samples[k - 1].t());
  }
  EXPECT_NEAR(turned, 0.5 * kPi, 2e-3) << "a quarter turn in all";
  // The tool ends as it started, turned a quarter about the axis.
  const Eigen::Quaterniond q0 = quat(samples.front().orientation()), q1 = quat(samples.back().orientation());
  EXPECT_LT(((q1 * q0.conjugate()).toRotationMatrix() - Eigen::AngleAxisd(0.5 * kPi, axis).toRotationMatrix()).norm(),
            1e-9);
}

// Helices of several radii and pitches, streamed: the samples lie on the cylinder of the
// radius asked and rise by the pitch asked per turn; AnalyzePath measures kappa and tau of
// 4.18-4.19 along them.
TEST_F(PiecesTest, StreamedHelicesHaveTheRadiusAndPitchAsked) {
  struct Helix {
    double radius, pitch;
  };
  for (const Helix h : {Helix{0.05, 0.02}, Helix{0.2, -0.05}, Helix{0.01, 0.1}}) {
    const double c = h.pitch / (2 * kPi), turns = 3.0;
    auto request = from_json<v1::PlanRequest>(R"({"path": {
        "start": {"position": {"x": 0.5, "z": 0.3}, "tangent": {"x": 1}, "normal": {"y": 1}},
        "pieces": [{"helix": {}}]}, "motion": {"durationS": 4, "cycleRateHz": 250}, "analysisPoints": 501})");
    auto& piece = *request.mutable_path()->mutable_pieces(0);
    piece.set_length_m(turns * 2 * kPi * std::hypot(h.radius, c));
    piece.mutable_helix()->set_radius(h.radius);
    piece.mutable_helix()->set_pitch(h.pitch);
    grpc::Status status;
    const auto samples = stream_all(request, status);
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_EQ(samples.size(), 1001u);
    const double kappa = h.radius / (h.radius * h.radius + c * c), tau = c / (h.radius * h.radius + c * c);
    const Vector3d p0(0.5, 0.0, 0.3), axis = Vector3d(tau, 0.0, kappa).normalized();
    const Vector3d centre = p0 + h.radius * Vector3d::UnitY();
    double angle = 0.0, previous = 0.0;
    const Vector3d e1 = (p0 - centre).normalized(), e2 = axis.cross(e1);
    for (std::size_t k = 0; k < samples.size(); ++k) {
      const Vector3d d = vec3(samples[k].position()) - centre;
      const Vector3d radial = d - d.dot(axis) * axis;
      ASSERT_NEAR(radial.norm(), h.radius, 1e-9) << h.radius << " " << h.pitch;
      const double a = std::atan2(radial.dot(e2), radial.dot(e1));
      if (k > 0) angle += std::remainder(a - previous, 2 * kPi);
      previous = a;
      // The rise along the axis is the pitch per turn of the angle turned.
      ASSERT_NEAR(d.dot(axis), h.pitch * angle / (2 * kPi), 1e-9) << h.radius << " " << h.pitch;
    }
    EXPECT_NEAR(std::abs(angle), turns * 2 * kPi, 1e-9);
    v1::PathProfile profile;
    ASSERT_TRUE(analyze(request, profile).ok());
    for (const auto& p : profile.points()) {
      ASSERT_NEAR(p.curvature(), kappa, 1e-9 * kappa);
      ASSERT_NEAR(p.torsion(), tau, 1e-9 * std::max(1.0, std::abs(tau)));
    }
  }
}

// The seam timed by optimize.timing (time-optimal; jerk-limited) on the UR5e and as one step
// of a sequence followed by a line: planned, streamed within the joint limits, never at rest
// on the seam.
TEST_F(PiecesTest, TheSeamIsTimedByTheOptimiserAndRunsInASequence) {
  const auto model = robot_model("ur5e");
  const Seam seam = seam_at_home(model);
  for (const bool jerk : {false, true}) {
    auto request = seam.request("ur5e", 1000.0, 1e-4);
    request.mutable_optimize()->mutable_timing()->set_time_optimal(true);
    request.mutable_optimize()->mutable_timing()->set_jerk_limited(jerk);
    const v1::PlanResponse plan = plan_ok(request);
    EXPECT_TRUE(plan.optimization().has_timing());
    grpc::Status status;
    const auto samples = stream_all(request, status);
    ASSERT_TRUE(status.ok()) << status.error_message();
    EXPECT_EQ(samples.size(), plan.motion().sample_count());
    expect_within_joint_limits(model, samples, jerk ? "jerk-limited" : "time-optimal");
    for (std::size_t k = 1; k + 1 < samples.size(); ++k) ASSERT_GT(samples[k].speed(), 0.0) << samples[k].t();
    std::printf("[ measured ] seam on the UR5e, %s: %.4f s\n", jerk ? "jerk-limited" : "time-optimal",
                plan.motion().duration_s());
  }
  // A sequence: the seam, then a line up by 5 cm from where it ends.
  const auto single = seam.request("ur5e", 500.0, 1e-4);
  v1::PlanRequest sequence;
  *sequence.mutable_robot() = single.robot();
  sequence.mutable_motion()->set_duration_s(2.0);
  sequence.mutable_motion()->set_cycle_rate_hz(500.0);
  *sequence.add_sequence()->mutable_path() = single.path();
  const Vector3d end = seam.p0 + (seam.a + seam.r) * seam.t + (seam.r + seam.b) * seam.n + Vector3d(0, 0, 0.05);
  auto* goal = sequence.add_sequence()->mutable_linear_move()->mutable_goal();
  set(goal->mutable_position(), end);
  const Eigen::Quaterniond q(forward_kinematics(model, model.home()).linear());
  goal->mutable_orientation()->set_w(q.w());
  goal->mutable_orientation()->set_x(q.x());
  goal->mutable_orientation()->set_y(q.y());
  goal->mutable_orientation()->set_z(q.z());
  grpc::Status status;
  const auto samples = stream_all(sequence, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_LE((vec3(samples.back().position()) - end).norm(), 1e-9);
  expect_within_joint_limits(model, samples, "sequence");
  double on_seam = 0.0;
  for (const auto& s : samples)
    if (s.step() == 0) on_seam = std::max(on_seam, std::min(seam.distance(vec3(s.position())), 1.0));
  EXPECT_LE(on_seam, 1e-4);
}

// ORIENTATION_MODE_FIXED with an orientation on a curved start: held from the first sample,
// on a path of pieces (start.orientation) and on key frames (frames[0].orientation); with
// another mode the orientation is refused by its field.
TEST_F(PiecesTest, AFixedStartHoldsTheOrientationGivenOnCurvedStarts) {
  const Eigen::Quaterniond tilted(Eigen::AngleAxisd(2.8, Vector3d(1, 1, 0).normalized()));
  auto pieces = from_json<v1::PlanRequest>(R"({"path": {
      "start": {"position": {"x": 0.5}, "tangent": {"x": 1}, "normal": {"y": 1}},
      "pieces": [{"lengthM": 0.2, "arc": {"radius": 0.1}}, {"lengthM": 0.1, "line": {}}],
      "transitionTolerance": 0.0001}, "motion": {"durationS": 2, "cycleRateHz": 250}})");
  auto frames = from_json<v1::PlanRequest>(R"({"path": {"frames": [
      {"position": {"x": 0.5}, "tangent": {"x": 1}, "normal": {"y": 1}, "curvature": 10},
      {"position": {"x": 0.6, "y": 0.05}, "tangent": {"y": 1}}]}, "motion": {"durationS": 2, "cycleRateHz": 250}})");
  for (v1::KeyFrame* first : {pieces.mutable_path()->mutable_start(), frames.mutable_path()->mutable_frames(0)}) {
    first->mutable_orientation()->set_w(tilted.w());
    first->mutable_orientation()->set_x(tilted.x());
    first->mutable_orientation()->set_y(tilted.y());
    first->mutable_orientation()->set_z(tilted.z());
  }
  for (const auto* request : {&pieces, &frames}) {
    grpc::Status status;
    const auto samples = stream_all(*request, status);
    ASSERT_TRUE(status.ok()) << status.error_message();
    for (const auto& s : samples) ASSERT_LT(quat(s.orientation()).angularDistance(tilted), 1e-9) << s.t();
  }
  frames.mutable_path()->mutable_frames(0)->set_orientation_mode(v1::ORIENTATION_MODE_FRENET);
  v1::PlanResponse response;
  const auto status = plan(frames, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(status), "path.frames[0].orientation"),
              HasSubstr("ORIENTATION_MODE_FIXED on the first frame"));
}

TEST_F(PiecesTest, AnalyzePathRecoversTheCurvatureAndTorsionAsked) {
  // kappa(s) = 5 + 20 s, tau(s) = 2 - 10 s over 0.3 m (a twisted clothoid).
  const auto request = from_json<v1::PlanRequest>(R"({"path": {
      "start": {"position": {}, "tangent": {"x": 1}, "normal": {"y": 1}},
      "pieces": [{"lengthM": 0.3, "profile": {"curvature": [5, 20], "torsion": [2, -10]}}]},
      "analysisPoints": 301})");
  v1::PathProfile profile;
  const auto status = analyze(request, profile);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(profile.points_size(), 301);
  for (const auto& p : profile.points()) {
    const double s = p.s();
    EXPECT_NEAR(p.curvature(), 5 + 20 * s, 1e-8) << s;
    EXPECT_NEAR(p.torsion(), 2 - 10 * s, 1e-7) << s;
    EXPECT_NEAR(p.curvature_derivative(), 20, 1e-5) << s;
  }
  EXPECT_NEAR(profile.points(300).s(), 0.3, 1e-12);
}

// An S-bend of two clothoids from a client: 0 -> 20 1/m over 0.5 m, then 20 -> -20 1/m
// over 0.5 m through an inflection. AnalyzePath measures the curvature linear in s (its
// magnitude: 40 s, then |20 - 80 (s - 0.5)|), no torsion, the curve in the start's plane,
// and the first clothoid's points are its Fresnel integrals x = int cos(20 t^2),
// y = int sin(20 t^2) (power series in long double, here) to 1e-12 m.
TEST_F(PiecesTest, ClothoidsAreLinearInCurvatureAndTheirPointsTheirFresnelIntegrals) {
  const auto request = from_json<v1::PlanRequest>(R"({"path": {
      "start": {"position": {}, "tangent": {"x": 1}, "normal": {"y": 1}},
      "pieces": [{"lengthM": 0.5, "clothoid": {"endCurvature": 20}},
                 {"lengthM": 0.5, "clothoid": {"endCurvature": -20}}]},
      "analysisPoints": 501})");
  v1::PathProfile profile;
  const auto status = analyze(request, profile);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(profile.points_size(), 501);
  const auto fresnel = [](double s) {  // int_0^s exp(i 20 t^2) dt by its power series
    long double c = 0.0L, sn = 0.0L, term = s;  // 20^n s^(2n+1) / n!
    for (int n = 0; n < 120; ++n) {
      const long double part = term / (2 * n + 1);
      if (n % 4 == 0) c += part;
      if (n % 4 == 1) sn += part;
      if (n % 4 == 2) c -= part;
      if (n % 4 == 3) sn -= part;
      term *= 20.0L * s * s / (n + 1);
    }
    return std::pair<double, double>{static_cast<double>(c), static_cast<double>(sn)};
  };
  for (const auto& p : profile.points()) {
    const double s = p.s();
    const double want = s <= 0.5 ? 40.0 * s : std::abs(20.0 - 80.0 * (s - 0.5));
    if (std::abs(s - 0.75) > 1e-9) {  // the inflection has no normal
      EXPECT_NEAR(p.curvature(), want, 1e-8) << s;
      EXPECT_NEAR(p.torsion(), 0.0, 1e-8) << s;
    }
    EXPECT_NEAR(p.position().z(), 0.0, 1e-15) << s;
    if (s <= 0.5) {
      const auto [x, y] = fresnel(s);
      EXPECT_NEAR(p.position().x(), x, 1e-12) << s;
      EXPECT_NEAR(p.position().y(), y, 1e-12) << s;
    }
  }
  EXPECT_NEAR(profile.points(500).s(), 1.0, 1e-12);
}

TEST_F(PiecesTest, BadPiecesAreNamedByTheirField) {
  const auto request = from_json<v1::PlanRequest>(R"({"path": {
      "start": {"position": {}, "tangent": {"x": 1}},
      "pieces": [{"lengthM": 0.1, "arc": {"radius": 0.1}}, {"lengthM": -1, "line": {}}, {"lengthM": 0.1},
                 {"to": {"position": {"x": 1}, "tangent": {"x": 2}}}]},
      "motion": {"durationS": 2}})");
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const auto violations = bad_request_violations(status);
  EXPECT_THAT(violation_of(violations, "path.pieces[2]"), HasSubstr("give its shape"));
  EXPECT_THAT(violation_of(violations, "path.pieces[1].lengthM"), HasSubstr("must be a length"));
  EXPECT_THAT(describe(violations), HasSubstr("path.pieces[3].to.tangent"));
  // Without those, the missing normal where the arc bends.
  const auto bent = from_json<v1::PlanRequest>(R"({"path": {
      "start": {"position": {}, "tangent": {"x": 1}},
      "pieces": [{"lengthM": 0.1, "arc": {"radius": 0.1}}]}, "motion": {"durationS": 2}})");
  const auto bent_status = plan(bent, response);
  ASSERT_EQ(bent_status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(violation_of(bad_request_violations(bent_status), "path.start.normal"), HasSubstr("bends"));
}

}  // namespace
}  // namespace geotraj::testing
