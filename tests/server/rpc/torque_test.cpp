// Timing within joint torques through the real service, checked the way a user would check
// it: the streamed torques recomputed outside by an independent Newton-Euler implementation
// (Orocos KDL's ChainIdSolver_RNE on the model ListRobots returns, the payload on the tool's
// segment) at every sample, against the effort limits; the limit reached where the timing
// says it binds; payloads from none to the arm's rating; the errors of bad payloads and
// torque limits, and of a pose whose gravity load passes a limit.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>

#include "server/wire/convert.hpp"
#include "tests/core/robot/kdl_chain.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

// The Panda's rated payload (Franka Emika: 3 kg), its centre of mass 5 cm out along the tool.
constexpr double kPayloadKg = 3.0;
constexpr double kPayloadZ = 0.05;

void set_payload(v1::PlanRequest& request, double mass) {
  request.mutable_robot()->mutable_payload()->set_mass(mass);
  request.mutable_robot()->mutable_payload()->mutable_center_of_mass()->set_z(kPayloadZ);
}

void limit_torque(v1::PlanRequest& request, const std::string& joint, double max_torque) {
  auto* l = request.mutable_robot()->add_joint_limits();
  l->set_joint(joint);
  l->set_max_torque(max_torque);
}

// The request's torque limits: the model's, with the request's jointLimits over them.
std::vector<double> torque_limits(const v1::RobotModel& model, const v1::PlanRequest& request) {
  std::vector<double> limits;
  for (int j = 0; j < model.limits_size(); ++j) limits.push_back(model.limits(j).max_torque());
  for (const auto& l : request.robot().joint_limits()) {
    for (int j = 0; j < model.joints_size(); ++j)
      if (model.joints(j).name() == l.joint() && l.has_max_torque()) limits[static_cast<std::size_t>(j)] = l.max_torque();
  }
  return limits;
}

// KDL's inverse dynamics of the model ListRobots gives, with `payload_kg` at kPayloadZ on the
// tool: an implementation of the Newton-Euler recursion independent of the server's.
class KdlTorques {
 public:
  KdlTorques(const v1::RobotModel& proto, double payload_kg) {
    auto model = server::robot_model_from_proto(proto, "");
    EXPECT_TRUE(model.has_value());
    if (!model) return;
    core::Inertial payload;
    payload.mass = payload_kg;
    payload.center_of_mass = Eigen::Vector3d(0.0, 0.0, kPayloadZ);
    chain_ = test::general_to_kdl_chain(*model, payload);
    n_ = chain_.getNrOfJoints();
  }
  std::vector<double> at(const v1::Sample& s) const {
    KDL::ChainIdSolver_RNE solver(chain_, KDL::Vector(0.0, 0.0, -9.80665));
    KDL::JntArray q(n_), qd(n_), qdd(n_), tau(n_);
    for (unsigned i = 0; i < n_; ++i) {
      q(i) = s.joints(static_cast<int>(i));
      qd(i) = s.joint_velocities(static_cast<int>(i));
      qdd(i) = s.joint_accelerations(static_cast<int>(i));
    }
    KDL::Wrenches external(chain_.getNrOfSegments(), KDL::Wrench::Zero());
    EXPECT_GE(solver.CartToJnt(q, qd, qdd, external, tau), 0);
    return std::vector<double>(tau.data.data(), tau.data.data() + n_);
  }
  unsigned joints() const { return n_; }

 private:
  KDL::Chain chain_;
  unsigned n_ = 0;
};

// What a user checks of a stream with torques: every sample carries one torque per joint,
// each what KDL computes from the sample's joints (1e-6 N m), each within its limit; the
// largest usage (|tau| / limit) over the stream.
double check_stream(const std::vector<v1::Sample>& samples, const KdlTorques& kdl, const std::vector<double>& limits) {
  double worst = 0.0;
  for (std::size_t k = 0; k < samples.size(); ++k) {
    const auto& s = samples[k];
    EXPECT_EQ(s.joint_torques_size(), static_cast<int>(kdl.joints())) << "sample " << k;
    if (s.joint_torques_size() != static_cast<int>(kdl.joints())) return worst;
    const std::vector<double> tau = kdl.at(s);
    for (int j = 0; j < s.joint_torques_size(); ++j) {
      const double streamed = s.joint_torques(j);
      EXPECT_NEAR(streamed, tau[static_cast<std::size_t>(j)], 1e-6 * std::max(1.0, std::abs(streamed)))
          << "sample " << k << " joint " << j;
      const double limit = limits[static_cast<std::size_t>(j)];
      EXPECT_LE(std::abs(streamed), limit * (1.0 + 1e-9)) << "sample " << k << " t " << s.t() << " joint " << j;
      worst = std::max(worst, std::abs(streamed) / limit);
    }
  }
  return worst;
}

class TorqueTest : public ServerTest {};

// The Panda along the thesis's path C (with its approach move) carrying its rated payload,
// its shoulder and elbow limited below what the fastest motion within the other limits asks:
// slower, every streamed torque within its limit and equal to KDL's, the limit reached.
TEST_F(TorqueTest, ThePandaWithItsRatedPayloadKeepsEveryTorqueItStreams) {
  const auto panda = robot_model("panda");
  auto request = example<v1::PlanRequest>("plan_panda_path_c.json");
  set_payload(request, kPayloadKg);
  const auto free = plan_ok(request);
  ASSERT_TRUE(free.has_robot());
  ASSERT_EQ(free.robot().joints_size(), 7);
  // Without an override the Panda's own limits (its URDF's efforts) hold: reported per joint.
  for (const auto& j : free.robot().joints()) {
    ASSERT_TRUE(j.has_peak_torque() && j.has_torque_usage()) << "joint " << j.joint();
    EXPECT_LE(j.torque_usage(), 1.0 + 1e-9);
  }
  const double shoulder = free.robot().joints(1).peak_torque(), elbow = free.robot().joints(3).peak_torque();
  std::printf("[ measured ] panda path C with %g kg: %.4f s, shoulder %.2f N m, elbow %.2f N m at peak\n", kPayloadKg,
              free.motion().duration_s(), shoulder, elbow);

  auto limited = request;
  limit_torque(limited, "panda_joint2", 0.94 * shoulder);
  limit_torque(limited, "panda_joint4", 0.94 * elbow);
  const auto slow = plan_ok(limited);
  ASSERT_TRUE(slow.has_robot());
  EXPECT_TRUE(slow.robot().feasible());
  EXPECT_GT(slow.motion().duration_s(), free.motion().duration_s());
  std::printf("[ measured ] limited to 94 %%: %.4f s (%+.2f %%)\n", slow.motion().duration_s(),
              100.0 * (slow.motion().duration_s() / free.motion().duration_s() - 1.0));
  bool torque_binds = false;
  for (const auto& b : slow.robot().binding()) torque_binds = torque_binds || b.kind() == v1::BINDING_KIND_JOINT_TORQUE;
  EXPECT_TRUE(torque_binds) << "the report names the torque where it binds";

  grpc::Status status;
  const auto samples = stream_all(limited, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(samples.size(), slow.motion().sample_count());
  const std::vector<double> limits = torque_limits(panda, limited);
  const double worst = check_stream(samples, KdlTorques(panda, kPayloadKg), limits);
  std::printf("[ measured ] streamed: largest torque usage %.6f over %zu samples\n", worst, samples.size());
  EXPECT_GT(worst, 0.99) << "as fast as the torques allow: a limit reached";
  // The report's peaks are the stream's.
  for (int j = 0; j < 7; ++j) {
    double peak = 0.0;
    for (const auto& s : samples) peak = std::max(peak, std::abs(s.joint_torques(j)));
    EXPECT_NEAR(slow.robot().joints(j).peak_torque(), peak, 1e-9 * std::max(1.0, peak)) << "joint " << j;
    EXPECT_NEAR(slow.robot().joints(j).torque_usage(), peak / limits[static_cast<std::size_t>(j)], 1e-9);
  }
}

// A joint path (the Panda's pick and place) within torque limits, timed time-optimally and
// jerk-limited as any joint path: slower than without them, within them at every sample.
TEST_F(TorqueTest, AJointPathKeepsItsTorques) {
  const auto panda = robot_model("panda");
  auto request = example<v1::PlanRequest>("plan_joint_path_panda.json");
  set_payload(request, kPayloadKg);
  const auto free = plan_ok(request);
  const double shoulder = free.robot().joints(1).peak_torque();
  limit_torque(request, "panda_joint2", 0.85 * shoulder);
  const auto slow = plan_ok(request);
  EXPECT_GT(slow.motion().duration_s(), free.motion().duration_s() * 1.01);
  std::printf("[ measured ] panda joint path with %g kg: %.4f s, shoulder at 85 %% of its %.2f N m peak: %.4f s\n",
              kPayloadKg, free.motion().duration_s(), shoulder, slow.motion().duration_s());
  grpc::Status status;
  const auto samples = stream_all(request, status);
  ASSERT_TRUE(status.ok()) << status.error_message();
  const double worst = check_stream(samples, KdlTorques(panda, kPayloadKg), torque_limits(panda, request));
  EXPECT_GT(worst, 0.99);
}

// From no payload to the rating, under the same torque limits: the heavier the load, the
// longer the motion, and every torque within its limit (KDL's, with that load).
TEST_F(TorqueTest, PayloadsFromNoneToTheRatingSlowTheMotionDown) {
  const auto panda = robot_model("panda");
  auto base = example<v1::PlanRequest>("plan_joint_path_panda.json");
  set_payload(base, 0.0);
  const double shoulder = plan_ok(base).robot().joints(1).peak_torque();
  double previous = 0.0;
  for (const double mass : {0.0, 1.0, 2.0, kPayloadKg}) {
    auto request = base;
    set_payload(request, mass);
    limit_torque(request, "panda_joint2", 1.2 * shoulder);
    const auto plan = plan_ok(request);
    const double duration = plan.motion().duration_s();
    std::printf("[ measured ] payload %g kg: %.4f s, shoulder usage %.4f\n", mass, duration,
                plan.robot().joints(1).torque_usage());
    EXPECT_GE(duration, previous * (1.0 - 1e-9)) << mass << " kg";
    previous = duration;
    grpc::Status status;
    const auto samples = stream_all(request, status);
    ASSERT_TRUE(status.ok()) << status.error_message();
    check_stream(samples, KdlTorques(panda, mass), torque_limits(panda, request));
  }
}

// A pose whose gravity load alone passes a limit cannot be held, let alone moved through:
// refused with the joint and the load, never timed around.
TEST_F(TorqueTest, GravityBeyondALimitIsAFailedPrecondition) {
  auto request = example<v1::PlanRequest>("plan_joint_path_panda.json");
  set_payload(request, kPayloadKg);
  limit_torque(request, "panda_joint2", 1.0);
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  EXPECT_THAT(status.error_message(), HasSubstr("joint 1"));
  EXPECT_THAT(status.error_message(), HasSubstr("gravity"));
}

// A motion of a given duration is not retimed: beyond a torque limit it is refused like any
// other limit, or reported with reportOnly (the violation's kind and joint).
TEST_F(TorqueTest, AGivenDurationBeyondATorqueIsRefusedOrReported) {
  auto request = example<v1::PlanRequest>("plan_joint_path_panda.json");
  set_payload(request, kPayloadKg);
  const double shoulder = plan_ok(request).robot().joints(1).peak_torque();
  request.mutable_motion()->set_duration_s(1.0);  // faster than the limits allow
  limit_torque(request, "panda_joint2", shoulder);
  v1::PlanResponse response;
  const auto status = plan(request, response);
  ASSERT_EQ(status.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << status.error_message();
  request.mutable_robot()->set_report_only(true);
  const auto reported = plan_ok(request);
  bool torque = false;
  for (const auto& v : reported.robot().violations())
    torque = torque || (v.kind() == v1::LIMIT_KIND_TORQUE && v.joint() == 1 && v.value() > v.limit());
  EXPECT_TRUE(torque) << reported.robot().DebugString();
}

// Bad input named by field: a payload on an arm without mass properties, a negative or
// infinite mass, a torque limit a model without dynamics cannot use, a torque limit <= 0.
TEST_F(TorqueTest, BadPayloadsAndTorqueLimitsAreNamed) {
  const auto refused = [&](v1::PlanRequest request, const std::string& field, const std::string& words) {
    v1::PlanResponse response;
    const auto status = plan(request, response);
    ASSERT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << field << ": " << status.error_message();
    const auto violations = bad_request_violations(status);
    EXPECT_THAT(violation_of(violations, field), HasSubstr(words)) << describe(violations);
  };
  auto pa10 = example<v1::PlanRequest>("plan_pa10_path_c.json");
  auto heavy = pa10;
  set_payload(heavy, 1.0);
  refused(heavy, "robot.payload", "mass properties");
  auto torque = pa10;
  limit_torque(torque, "S1", 10.0);
  refused(torque, "robot.jointLimits[0].maxTorque", "mass properties");

  auto panda = example<v1::PlanRequest>("plan_joint_path_panda.json");
  auto negative = panda;
  set_payload(negative, -1.0);
  refused(negative, "robot.payload.mass", "must be in [0");
  auto infinite = panda;
  set_payload(infinite, std::numeric_limits<double>::infinity());
  refused(infinite, "robot.payload.mass", "must be in [0");
  auto far = panda;
  far.mutable_robot()->mutable_payload()->mutable_center_of_mass()->set_x(std::nan(""));
  refused(far, "robot.payload.centerOfMass", "finite");
  auto zero = panda;
  limit_torque(zero, "panda_joint2", 0.0);
  refused(zero, "robot.jointLimits[0].maxTorque", "");
}

}  // namespace
}  // namespace geotraj::testing
