// URDF models (planner/robots.hpp): the built-in arms load; forward kinematics of every URDF
// here agrees with an independent reading of the document (TinyXML and 4 x 4 products, the
// URDF specification's formulas: no urdfdom, no geotraj chain); the Panda and the UR5e agree
// with their makers' DH tables; continuous and fixed joints, base and tip links; and every
// kind of bad document is refused with the element and line it is about.
#include <chrono>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <functional>
#include <map>
#include <numbers>
#include <random>
#include <sstream>
#include <stop_token>
#include <string>
#include <tuple>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tinyxml.h>

#include "core/robot/dynamics.hpp"
#include "core/robot/ik.hpp"
#include "core/robot/kinematics.hpp"
#include "planner/robots.hpp"
#include "tests/support/build_paths.hpp"
#include "tests/support/utf8.hpp"

namespace geotraj::test {
namespace {

using ::testing::HasSubstr;
using core::JointVector;
using core::RobotModel;

std::string fixture(const std::string& name) {
  std::ifstream in(std::string(::geotraj::testing::build_paths::urdf_fixtures()) + "/" + name);
  EXPECT_TRUE(in) << name;
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string listed(const core::Violations& v) {
  std::string out;
  for (const auto& x : v) out += "  " + x.field + ": " + x.description + "\n";
  return out;
}

planner::UrdfOptions chain(std::string base, std::string tip) {
  planner::UrdfOptions options;
  options.base_link = std::move(base);
  options.tip_link = std::move(tip);
  return options;
}

RobotModel load(const std::string& text, const std::string& base = {}, const std::string& tip = {}) {
  auto m = planner::robot_from_urdf(text, chain(base, tip));
  EXPECT_TRUE(m.has_value()) << (m ? std::string() : listed(m.error()));
  return m ? *m : RobotModel{};
}

// --- an independent reading: the URDF specification's formulas, nothing of geotraj's -------

Eigen::Vector3d triple(const TiXmlElement* e, const char* attribute, const Eigen::Vector3d& fallback) {
  if (e == nullptr || e->Attribute(attribute) == nullptr) return fallback;
  std::istringstream in(e->Attribute(attribute));
  Eigen::Vector3d v;
  in >> v.x() >> v.y() >> v.z();
  return v;
}

struct UrdfJoint {
  std::string name, type, parent;
  Eigen::Matrix4d origin = Eigen::Matrix4d::Identity();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();  // URDF's default
};

// T_parent_joint = Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll) (URDF: fixed-axis roll, pitch, yaw).
Eigen::Matrix4d origin_of(const TiXmlElement* joint) {
  const TiXmlElement* o = joint->FirstChildElement("origin");
  const Eigen::Vector3d xyz = triple(o, "xyz", Eigen::Vector3d::Zero()), rpy = triple(o, "rpy", Eigen::Vector3d::Zero());
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = (Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  T.topRightCorner<3, 1>() = xyz;
  return T;
}

// The tip link's pose in the base link's frame, q in chain order (moving joints only).
Eigen::Matrix4d independent_fk(const std::string& text, const std::string& base, const std::string& tip,
                               const JointVector& q) {
  TiXmlDocument doc;
  doc.Parse(text.c_str());
  std::map<std::string, UrdfJoint> by_child;
  for (const TiXmlElement* j = doc.RootElement()->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
    UrdfJoint u;
    u.name = j->Attribute("name");
    u.type = j->Attribute("type");
    u.parent = j->FirstChildElement("parent")->Attribute("link");
    u.origin = origin_of(j);
    u.axis = triple(j->FirstChildElement("axis"), "xyz", Eigen::Vector3d::UnitX()).normalized();
    by_child[j->FirstChildElement("child")->Attribute("link")] = u;
  }
  std::vector<UrdfJoint> chain;
  for (std::string link = tip; link != base; link = by_child.at(link).parent) chain.insert(chain.begin(), by_child.at(link));
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  Eigen::Index k = 0;
  for (const UrdfJoint& j : chain) {
    Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
    if (j.type == "revolute" || j.type == "continuous") {
      M.topLeftCorner<3, 3>() = Eigen::AngleAxisd(q(k++), j.axis).toRotationMatrix();
    } else if (j.type == "prismatic") {
      M.topRightCorner<3, 1>() = q(k++) * j.axis;
    }
    T = T * j.origin * M;
  }
  EXPECT_EQ(k, q.size());
  return T;
}

JointVector random_q(const RobotModel& m, std::mt19937_64& rng) {
  JointVector q(static_cast<Eigen::Index>(m.dof()));
  for (std::size_t i = 0; i < m.dof(); ++i) {
    const bool continuous = m.joints[i].type == core::JointType::kContinuous;
    std::uniform_real_distribution<double> d(continuous ? -7.0 : m.limits[i].min_position,
                                             continuous ? 7.0 : m.limits[i].max_position);
    q(static_cast<Eigen::Index>(i)) = d(rng);
  }
  return q;
}

struct Document {
  const char* name;
  std::string text;
  const char* base;
  const char* tip;
};

std::vector<Document> documents() {
  return {{"panda", std::string(planner::builtin_urdf("panda")), "panda_link0", "panda_link8"},
          {"iiwa14", std::string(planner::builtin_urdf("iiwa14")), "iiwa_link_0", "iiwa_link_ee"},
          {"ur5e", std::string(planner::builtin_urdf("ur5e")), "base_link", "tool0"},
          {"scara_like", fixture("scara_like.urdf"), "base_link", "tool"},
          {"gen3_like", fixture("gen3_like.urdf"), "base_link", "tool_frame"}};
}

TEST(Urdf, BuiltinArmsLoad) {
  const auto& robots = planner::builtin_robots();
  ASSERT_EQ(robots.size(), 5u);
  const std::pair<const char*, std::size_t> expected[] = {{"pa10", 7}, {"ur5", 6}, {"panda", 7}, {"iiwa14", 7}, {"ur5e", 6}};
  for (std::size_t i = 0; i < robots.size(); ++i) {
    SCOPED_TRACE(expected[i].first);
    EXPECT_EQ(robots[i]->name, expected[i].first);
    EXPECT_EQ(robots[i]->dof(), expected[i].second);
    EXPECT_TRUE(core::validate_robot(*robots[i]).empty()) << listed(core::validate_robot(*robots[i]));
    EXPECT_FALSE(robots[i]->description.empty());
    EXPECT_EQ(robots[i]->dh.has_value(), i < 2);  // the thesis's PA-10 and the UR5 stay DH tables
    EXPECT_EQ(planner::builtin_urdf(robots[i]->name).empty(), i < 2);
    ASSERT_EQ(robots[i]->home.size(), robots[i]->dof());
  }
  const RobotModel& panda = *planner::find_builtin_robot("panda");
  EXPECT_EQ(panda.joints[0].name, "panda_joint1");
  EXPECT_DOUBLE_EQ(panda.limits[3].max_position, -0.0698);
  EXPECT_DOUBLE_EQ(*panda.limits[6].max_jerk, 10000.0);
  EXPECT_DOUBLE_EQ(panda.home[3], -2.35619449019);
  EXPECT_EQ(planner::find_builtin_robot("nope"), nullptr);
}

TEST(Urdf, ForwardKinematicsMatchesAnIndependentReadingOfTheDocument) {
  std::mt19937_64 rng(20261203);
  for (const Document& d : documents()) {
    SCOPED_TRACE(d.name);
    const RobotModel m = load(d.text);
    ASSERT_GT(m.dof(), 0u);
    for (int k = 0; k < 200; ++k) {
      const JointVector q = k == 0 ? JointVector(JointVector::Zero(static_cast<Eigen::Index>(m.dof()))) : random_q(m, rng);
      const Eigen::Matrix4d expected = independent_fk(d.text, d.base, d.tip, q);
      const Eigen::Matrix4d actual = core::forward_kinematics(m, q).matrix();
      ASSERT_LE((actual - expected).cwiseAbs().maxCoeff(), 1e-12) << "q = " << q.transpose() << "\n" << actual << "\n" << expected;
    }
  }
}

// The Panda's URDF against Franka's published modified-DH table (flange 0.107 m along z 7);
// the UR5e's against Universal Robots' standard DH table: two writings of one arm.
TEST(Urdf, PandaAndUr5eMatchTheirMakersDhTables) {
  const double h = std::numbers::pi / 2;
  RobotModel panda_dh = *planner::find_builtin_robot("panda");
  core::set_dh(panda_dh, {core::DhConvention::kModified,
                          {{0, 0, 0.333, 0}, {0, -h, 0, 0}, {0, h, 0.316, 0}, {0.0825, h, 0, 0},
                           {-0.0825, -h, 0.384, 0}, {0, h, 0, 0}, {0.088, h, 0, 0}}});
  panda_dh.tool = Eigen::Isometry3d(Eigen::Translation3d(0, 0, 0.107));
  RobotModel ur5e_dh = *planner::find_builtin_robot("ur5e");
  core::set_dh(ur5e_dh, {core::DhConvention::kStandard,
                         {{0, h, 0.1625, 0}, {-0.425, 0, 0, 0}, {-0.3922, 0, 0, 0}, {0, h, 0.1333, 0},
                          {0, -h, 0.0997, 0}, {0, 0, 0.0996, 0}}});
  std::mt19937_64 rng(7);
  for (const auto& [urdf, dh] : {std::pair{planner::find_builtin_robot("panda"), &panda_dh},
                                 std::pair{planner::find_builtin_robot("ur5e"), &ur5e_dh}}) {
    SCOPED_TRACE(urdf->name);
    for (int k = 0; k < 200; ++k) {
      const JointVector q = random_q(*urdf, rng);
      EXPECT_LE((core::forward_kinematics(*urdf, q).matrix() - core::forward_kinematics(*dh, q).matrix()).cwiseAbs().maxCoeff(),
                1e-12);
    }
  }
  // Franka's documented flange at q = 0: (0.088, 0, 0.926) m, z pointing down.
  const Eigen::Isometry3d X = core::forward_kinematics(*planner::find_builtin_robot("panda"), JointVector::Zero(7));
  EXPECT_LE((X.translation() - Eigen::Vector3d(0.088, 0, 0.926)).norm(), 1e-12);
  EXPECT_LE((X.linear().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
  // The iiwa straight up: the flange 0.36 + 0.42 + 0.40 + 0.126 m above the base.
  const Eigen::Isometry3d Y = core::forward_kinematics(*planner::find_builtin_robot("iiwa14"), JointVector::Zero(7));
  EXPECT_LE((Y.translation() - Eigen::Vector3d(0, 0, 1.306)).norm(), 1e-12);
}

TEST(Urdf, FixedJointsFoldAndContinuousJointsAreUnbounded) {
  const RobotModel scara = load(fixture("scara_like.urdf"));
  ASSERT_EQ(scara.dof(), 5u);  // elbow_mount and tool_joint are fixed
  const char* names[] = {"j1", "j2", "j3", "j4", "j5"};
  for (std::size_t i = 0; i < 5; ++i) EXPECT_EQ(scara.joints[i].name, names[i]);
  EXPECT_EQ(scara.joints[3].type, core::JointType::kPrismatic);
  EXPECT_EQ(scara.joints[4].type, core::JointType::kContinuous);
  EXPECT_LE((scara.joints[2].axis - Eigen::Vector3d(0, 0.6, 0.8)).norm(), 1e-15);
  EXPECT_FALSE(scara.flange.matrix().isIdentity());  // the tool joint
  EXPECT_DOUBLE_EQ(scara.limits[3].max_acceleration, 1.0);
  EXPECT_FALSE(scara.limits[2].max_jerk.has_value());

  const RobotModel gen3 = load(fixture("gen3_like.urdf"));
  ASSERT_EQ(gen3.dof(), 7u);
  for (std::size_t i : {0u, 2u, 4u, 6u}) EXPECT_EQ(gen3.joints[i].type, core::JointType::kContinuous) << i;
  for (std::size_t i : {1u, 3u, 5u}) EXPECT_EQ(gen3.joints[i].type, core::JointType::kRevolute) << i;
  EXPECT_TRUE(core::within_position_limits(gen3.joints[0].type, gen3.limits[0], 25.0));
  // The IK turns a continuous joint as far as it needs: a pose whose joints sit beyond 2 pi.
  JointVector q = core::home_configuration(gen3);
  q(0) += 2.0;
  q(6) += 9.0;
  const Eigen::Isometry3d target = core::forward_kinematics(gen3, q);
  const core::IkResult r = core::solve_ik(gen3, target, q - JointVector::Constant(7, 0.05));
  EXPECT_TRUE(r.converged);
  EXPECT_NEAR(r.q(6), q(6), 0.2);  // near the seed (7 joints: self-motion), not wrapped by 2 pi
}

// At rest at q the model's torques (standard gravity, no payload) are the derivatives of the
// potential energy V(q) [J] computed by the test (central differences, 1e-6 rad).
void expect_torques_hold_the_weights(const RobotModel& m, const JointVector& q,
                                     const std::function<double(const JointVector&)>& potential) {
  JointVector tau;
  core::inverse_dynamics(m, q, JointVector::Zero(q.size()), JointVector::Zero(q.size()), core::DynamicsOptions{}, tau);
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    JointVector up = q, down = q;
    up(i) += 1e-6;
    down(i) -= 1e-6;
    EXPECT_NEAR(tau(i), (potential(up) - potential(down)) / 2e-6, 1e-6) << "joint " << i;
  }
}

// Mass properties and efforts: every link of the SCARA-like fixture given an <inertial>
// (its own origin and rotation) is read into the joint that moves it, a fixed link's (the
// elbow block, the tool) folded into the moving link it hangs on; <limit effort> is the
// torque limit. Checked against the document read here: the gravity torques at rest against
// the derivatives of the potential energy of every link's centre of mass (each link's pose by
// the independent forward kinematics above), and the inertia seen by the prismatic and the
// last, continuous joint (the mass matrix's diagonal) against the bodies beyond them.
TEST(Urdf, InertialsAndEffortsAreRead) {
  struct Body {
    const char* link;
    int joints;  // moving joints from the base to the link
    double mass;
    Eigen::Vector3d xyz, rpy, diagonal;  // the <inertial> origin and principal moments
  };
  const std::vector<Body> bodies = {
      {"link1", 1, 4.0, {0.1, 0.0, 0.05}, {0.0, 0.0, 0.3}, {0.02, 0.03, 0.04}},
      {"link2", 2, 3.0, {0.15, 0.01, 0.0}, {0.1, -0.2, 0.0}, {0.01, 0.02, 0.025}},
      {"elbow_block", 2, 0.8, {0.0, 0.0, 0.02}, {0.0, 0.4, 0.0}, {0.002, 0.003, 0.004}},
      {"link3", 3, 2.0, {0.0, 0.02, -0.03}, {0.5, 0.0, -0.1}, {0.006, 0.007, 0.008}},
      {"link4", 4, 1.0, {0.0, 0.0, 0.04}, {0.0, 0.0, 0.0}, {0.003, 0.003, 0.001}},
      {"link5", 5, 0.5, {0.01, 0.0, 0.02}, {0.2, 0.3, 0.1}, {0.001, 0.0012, 0.0015}},
      {"tool", 5, 0.7, {0.0, 0.03, 0.05}, {-0.3, 0.0, 0.6}, {0.0015, 0.002, 0.0025}}};
  const auto document = [&](const std::vector<Body>& with) {
    std::string text = fixture("scara_like.urdf");
    for (const Body& b : with) {
      const std::string empty = std::string("<link name=\"") + b.link + "\"/>";
      const auto at = text.find(empty);
      EXPECT_NE(at, std::string::npos) << b.link;
      if (at == std::string::npos) continue;
      char inertial[512];
      std::snprintf(inertial, sizeof inertial,
                    "<link name=\"%s\"><inertial><origin xyz=\"%.17g %.17g %.17g\" rpy=\"%.17g %.17g %.17g\"/>"
                    "<mass value=\"%.17g\"/><inertia ixx=\"%.17g\" ixy=\"0\" ixz=\"0\" iyy=\"%.17g\" iyz=\"0\" "
                    "izz=\"%.17g\"/></inertial></link>",
                    b.link, b.xyz.x(), b.xyz.y(), b.xyz.z(), b.rpy.x(), b.rpy.y(), b.rpy.z(), b.mass, b.diagonal.x(),
                    b.diagonal.y(), b.diagonal.z());
      text.replace(at, empty.size(), inertial);
    }
    return text;
  };
  const std::string text = document(bodies);
  const auto rotation = [](const Eigen::Vector3d& rpy) {
    return Eigen::Matrix3d(Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                           Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                           Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()));
  };
  const RobotModel m = load(text);
  ASSERT_TRUE(core::has_dynamics(m));
  ASSERT_TRUE(core::validate_robot(m).empty()) << listed(core::validate_robot(m));
  const double efforts[] = {50, 30, 10, 200, 5};
  for (std::size_t i = 0; i < 5; ++i) EXPECT_EQ(m.limits[i].max_torque, efforts[i]) << i;
  double total = 0.0;
  for (const auto& j : m.joints) total += j.inertial->mass;
  EXPECT_NEAR(total, 12.0, 1e-12);

  std::mt19937_64 rng(35);
  for (int trial = 0; trial < 5; ++trial) {
    const JointVector q = random_q(m, rng), zero = JointVector::Zero(5);
    // Every body's centre of mass, axes and frame in the base link's frame (the model's base is
    // the identity), read from the document.
    const auto frame = [&](const Body& b, const JointVector& x) {
      return Eigen::Isometry3d(independent_fk(text, "base_link", b.link, x.head(b.joints)));
    };
    const Eigen::Vector3d g(0.0, 0.0, -core::kStandardGravity);
    const auto potential = [&](const JointVector& x) {
      double V = 0.0;
      for (const Body& b : bodies) V -= b.mass * g.dot(frame(b, x) * b.xyz);
      return V;
    };
    expect_torques_hold_the_weights(m, q, potential);
    JointVector tau;
    // The diagonal of the mass matrix at the prismatic joint 3 (the mass it carries) and the
    // continuous joint 4 (the bodies about its axis).
    core::DynamicsOptions no_gravity;
    no_gravity.gravity.setZero();
    core::inverse_dynamics(m, q, zero, JointVector::Unit(5, 3), no_gravity, tau);
    EXPECT_NEAR(tau(3), 0.5 + 0.7 + 1.0, 1e-12);
    core::inverse_dynamics(m, q, zero, JointVector::Unit(5, 4), no_gravity, tau);
    const Eigen::Isometry3d X5 = frame(bodies[5], q);
    const Eigen::Vector3d axis = X5.linear().col(2), on_axis = X5.translation();  // j5 turns about link5's z
    double expected = 0.0;
    for (const Body& b : {bodies[5], bodies[6]}) {
      const Eigen::Isometry3d X = frame(b, q);
      const Eigen::Matrix3d R = X.linear() * rotation(b.rpy);
      const Eigen::Matrix3d I = R * b.diagonal.asDiagonal() * R.transpose();
      expected += axis.dot(I * axis) + b.mass * axis.cross(X * b.xyz - on_axis).squaredNorm();
    }
    EXPECT_NEAR(tau(4), expected, 1e-12);
  }
  // Without any <inertial> the model gives no dynamics.
  EXPECT_FALSE(core::has_dynamics(load(fixture("scara_like.urdf"))));
  // Nor with an inertia no body has; its kinematics still load, and its description says why.
  std::vector<Body> rod = bodies;
  rod[0].diagonal.x() = 0.09;  // link1: 0.09 > 0.03 + 0.04
  const RobotModel kinematics_only = load(document(rod));
  EXPECT_FALSE(core::has_dynamics(kinematics_only));
  EXPECT_THAT(kinematics_only.description,
              HasSubstr("(no dynamics: link 'link1' <inertial>.inertia principal moments"));
}

// The built-in Panda (Gaz et al. 2019's identified parameters) and UR5e (UR's published
// masses, centres of mass and tensors) carry mass properties (panda.urdf, ur5e.urdf): at rest
// anywhere within their joint limits with their rated payload at the flange (3 kg, 5 kg),
// gravity needs less than their torque limits, as the makers' ratings promise; without the
// payload less again. The other built-in arms give no dynamics yet.
TEST(Urdf, TheArmsWithMassPropertiesHoldTheirRatedPayloadAnywhereWithinTheirTorques) {
  for (const auto& [name, arm_mass, rated_payload] :
       {std::tuple{"panda", 16.0, 3.0}, std::tuple{"ur5e", 17.7, 5.0}}) {
    SCOPED_TRACE(name);
    const auto& m = *planner::find_builtin_robot(name);
    ASSERT_TRUE(core::has_dynamics(m));
    double mass = 0.0;
    for (const auto& j : m.joints) mass += j.inertial->mass;
    EXPECT_NEAR(mass, arm_mass, 0.1) << "the moving links";
    std::mt19937_64 rng(34);
    core::DynamicsOptions rated, bare;
    rated.payload.mass = rated_payload;
    double worst = 0.0, worst_bare = 0.0;
    JointVector tau;
    const auto n = static_cast<Eigen::Index>(m.dof());
    for (int k = 0; k < 5000; ++k) {
      const JointVector q = random_q(m, rng), zero = JointVector::Zero(n);
      core::inverse_dynamics(m, q, zero, zero, rated, tau);
      for (Eigen::Index i = 0; i < n; ++i)
        worst = std::max(worst, std::abs(tau(i)) / *m.limits[static_cast<std::size_t>(i)].max_torque);
      core::inverse_dynamics(m, q, zero, zero, bare, tau);
      for (Eigen::Index i = 0; i < n; ++i)
        worst_bare = std::max(worst_bare, std::abs(tau(i)) / *m.limits[static_cast<std::size_t>(i)].max_torque);
    }
    std::printf("[ measured ] %s at rest, 5,000 random poses: gravity uses at most %.3f of a torque limit with %.0f kg "
                "at the flange, %.3f without\n", name, worst, rated_payload, worst_bare);
    EXPECT_LT(worst, 1.0);
    EXPECT_LT(worst_bare, worst);
    EXPECT_GT(worst, 0.3) << "the arm's weight is felt";
  }
  for (const char* name : {"pa10", "ur5"})
    EXPECT_FALSE(core::has_dynamics(*planner::find_builtin_robot(name))) << name;
}

// UR gives the UR5e's centres of mass in its standard-DH frames; ur5e.urdf's links are DH frame
// i-1 turned by q_i. The gravity torques of the model read from the URDF equal the derivatives
// of the potential energy of UR's table computed here from the DH formulas alone.
TEST(Urdf, TheUr5esCentresOfMassAreUrsInItsDhFrames) {
  const auto& m = *planner::find_builtin_robot("ur5e");
  const double a[] = {0, -0.425, -0.3922, 0, 0, 0}, d[] = {0.1625, 0, 0, 0.1333, 0.0997, 0.0996},
               alpha[] = {std::numbers::pi / 2, 0, 0, std::numbers::pi / 2, -std::numbers::pi / 2, 0};
  const double mass[] = {3.761, 8.058, 2.846, 1.37, 1.3, 0.365};
  const Eigen::Vector3d com[] = {{0, -0.02561, 0.00193}, {0.2125, 0, 0.11336}, {0.15, 0, 0.0265},
                                 {0, -0.0018, 0.01634},  {0, 0.0018, 0.01634}, {0, 0, -0.001159}};
  const Eigen::Vector3d g(0.0, 0.0, -core::kStandardGravity);
  const auto potential = [&](const JointVector& q) {
    Eigen::Isometry3d T = m.base;
    double V = 0.0;
    for (int i = 0; i < 6; ++i) {
      T = T * Eigen::AngleAxisd(q(i), Eigen::Vector3d::UnitZ()) * Eigen::Translation3d(a[i], 0.0, d[i]) *
          Eigen::AngleAxisd(alpha[i], Eigen::Vector3d::UnitX());
      V -= mass[i] * g.dot(T * com[i]);
    }
    return V;
  };
  std::mt19937_64 rng(36);
  for (int k = 0; k < 20; ++k) expect_torques_hold_the_weights(m, random_q(m, rng), potential);
}

// As ROS-Industrial ships an arm: besides tool0 at the end of the chain, a `base` frame fixed
// to base_link (REP 199) is a leaf too. The tip is the leaf reached through the most moving
// joints: tool0, with no tipLink. Two such leaves (a camera frame beside the flange, both on
// the last link) are listed, each through the same count.
TEST(Urdf, TheTipIsTheLeafThroughTheMostMovingJoints) {
  const std::string arm = R"(<?xml version="1.0"?>
<robot name="rosi_arm">
  <link name="base_link"/><link name="base"/><link name="link_1"/><link name="link_2"/><link name="link_3"/>
  <link name="flange"/><link name="tool0"/>
  <joint name="base_link-base" type="fixed"><parent link="base_link"/><child link="base"/><origin xyz="0 0 0.4"/></joint>
  <joint name="joint_a1" type="revolute"><parent link="base_link"/><child link="link_1"/><origin xyz="0 0 0.4"/>
    <axis xyz="0 0 -1"/><limit lower="-3" upper="3" effort="0" velocity="2"/></joint>
  <joint name="joint_a2" type="revolute"><parent link="link_1"/><child link="link_2"/><origin xyz="0.26 0 0.27"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="1" effort="0" velocity="2"/></joint>
  <joint name="joint_a3" type="revolute"><parent link="link_2"/><child link="link_3"/><origin xyz="0.68 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="0" velocity="2"/></joint>
  <joint name="joint_a3-flange" type="fixed"><parent link="link_3"/><child link="flange"/><origin xyz="0.6 0 0"/></joint>
  <joint name="flange-tool0" type="fixed"><parent link="flange"/><child link="tool0"/><origin rpy="0 1.5707963 0"/></joint>
</robot>
)";
  auto kinematics = [](const std::string& text) { return planner::robot_from_urdf(text); };  // as shipped
  const auto model = kinematics(arm);
  ASSERT_TRUE(model) << model.error()[0].description;
  EXPECT_EQ(model->dof(), 3u);
  const RobotModel& m = *model;
  // The flange is tool0's: 0.6 m along link_3's x, turned about y.
  EXPECT_NEAR(m.flange.translation().x(), 0.6, 1e-12);
  EXPECT_NEAR(std::abs(m.flange.linear()(0, 2)), 1.0, 1e-6);

  std::string camera = arm;
  camera.insert(camera.find("</robot>"), R"(<link name="camera_frame"/>
  <joint name="camera" type="fixed"><parent link="link_3"/><child link="camera_frame"/><origin xyz="0.3 0 0.1"/></joint>
)");
  const auto tied = kinematics(camera);
  ASSERT_FALSE(tied);
  EXPECT_EQ(tied.error()[0].field, "tipLink");
  EXPECT_THAT(tied.error()[0].description, HasSubstr("3 leaf links, 2 of them through 3 moving joints ('camera_frame', 'tool0')"));
}

TEST(Urdf, BaseAndTipChooseTheChain) {
  // A hand with two fingers below the Panda's flange: three leaves below the root.
  std::string text(planner::builtin_urdf("panda"));
  const std::string hand = R"(<link name="hand"/><link name="finger_left"/><link name="finger_right"/>
  <joint name="hand_joint" type="fixed"><parent link="panda_link8"/><child link="hand"/><origin xyz="0 0 0.1"/></joint>
  <joint name="finger_joint1" type="prismatic"><parent link="hand"/><child link="finger_left"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="0.04" effort="20" velocity="0.2"/></joint>
  <joint name="finger_joint2" type="prismatic"><parent link="hand"/><child link="finger_right"/><axis xyz="0 -1 0"/>
    <limit lower="0" upper="0.04" effort="20" velocity="0.2"/><mimic joint="finger_joint1"/></joint>
)";
  text.insert(text.find("<geotraj description"), hand);
  auto branched = planner::robot_from_urdf(text);
  ASSERT_FALSE(branched);
  EXPECT_EQ(branched.error()[0].field, "tipLink");
  EXPECT_THAT(branched.error()[0].description, HasSubstr("'finger_left', 'finger_right'"));
  const RobotModel to_hand = load(text, "", "hand");
  EXPECT_EQ(to_hand.dof(), 7u);
  const Eigen::Isometry3d X = core::forward_kinematics(to_hand, JointVector::Zero(7));
  EXPECT_NEAR(X.translation().z(), 0.926 - 0.1, 1e-12);  // the hand 0.1 m further along the flange's z (down)
  // The mimic joint is refused when it is on the chain, named.
  auto mimic = planner::robot_from_urdf(text, chain("", "finger_right"));
  ASSERT_FALSE(mimic);
  EXPECT_THAT(listed(mimic.error()), HasSubstr("finger_joint2"));
  EXPECT_THAT(listed(mimic.error()), HasSubstr("mimic"));
  // A base in the middle: the joints above it are not the robot's.
  const RobotModel forearm = load(std::string(planner::builtin_urdf("panda")), "panda_link4", "");
  EXPECT_EQ(forearm.dof(), 3u);
  EXPECT_EQ(forearm.joints[0].name, "panda_joint5");
  // Unknown links and a tip that is not below the base.
  auto unknown = planner::robot_from_urdf(std::string(planner::builtin_urdf("panda")), chain("nope", ""));
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error()[0].field, "baseLink");
  EXPECT_THAT(unknown.error()[0].description, HasSubstr("'panda_link0'"));
  auto above = planner::robot_from_urdf(std::string(planner::builtin_urdf("panda")), chain("panda_link4", "panda_link2"));
  ASSERT_FALSE(above);
  EXPECT_EQ(above.error()[0].field, "tipLink");
  EXPECT_THAT(above.error()[0].description, HasSubstr("not below"));
}

// A document without accelerations loads (the kinematics need none), saying which joints
// lack one and the three ways to give it; limits given beside the document take precedence
// over its block, and the model says where each came from.
TEST(Urdf, LoadsWithoutAccelerationsAndSaysWhereEachLimitComesFrom) {
  const std::string text = fixture("scara_like.urdf");
  const std::string bare = text.substr(0, text.find("<geotraj ")) + "</robot>\n";
  const auto loaded = planner::robot_from_urdf(bare);
  ASSERT_TRUE(loaded) << loaded.error()[0].description;
  const RobotModel& m = *loaded;
  EXPECT_TRUE(core::validate_robot(m).empty());
  ASSERT_EQ(m.limit_sources.size(), m.dof());
  for (std::size_t i = 0; i < m.dof(); ++i) {
    EXPECT_FALSE(m.acceleration_known(i));
    EXPECT_EQ(m.limits[i].max_acceleration, planner::kUnknownAcceleration);
    EXPECT_THAT(m.limit_sources[i].velocity, HasSubstr("URDF <limit velocity>, line "));
    EXPECT_THAT(m.limit_sources[i].velocity, HasSubstr("'" + m.joints[i].name + "'"));
  }
  const std::string why = planner::missing_accelerations(m);
  EXPECT_THAT(why, HasSubstr("joints 0 (j1), 1 (j2), 2 (j3), 3 (j4), 4 (j5) have no acceleration limit"));
  EXPECT_THAT(why, HasSubstr("robot.jointLimits"));
  EXPECT_THAT(why, HasSubstr("joint_limits.yaml (robot.jointLimitsYaml, or geotrajd --joint-limits FILE)"));
  EXPECT_THAT(why, HasSubstr("<geotraj><joint name=\"j1\" max_acceleration="));
  // The block's accelerations are known, and said to be the block's.
  const RobotModel blocked = *planner::robot_from_urdf(text);
  EXPECT_TRUE(planner::missing_accelerations(blocked).empty());
  EXPECT_THAT(blocked.limit_sources[0].acceleration, HasSubstr("URDF <geotraj> block, line "));

  planner::UrdfOptions given;
  for (const char* joint : {"j1", "j2", "j3", "j4", "j5"}) given.limits.push_back({joint, std::nullopt, 2.5, 30.0});
  given.limits[1].max_velocity = 0.5;
  given.limits[1].source = "robot.jointLimits[1]";
  const RobotModel g = *planner::robot_from_urdf(bare, given);
  EXPECT_TRUE(planner::missing_accelerations(g).empty());
  EXPECT_EQ(g.limits[4].max_acceleration, 2.5);
  EXPECT_EQ(*g.limits[4].max_jerk, 30.0);
  EXPECT_EQ(g.limits[1].max_velocity, 0.5);
  EXPECT_EQ(g.limit_sources[1].velocity, "robot.jointLimits[1]");
  EXPECT_EQ(g.limit_sources[1].acceleration, "robot.jointLimits[1]");
  EXPECT_EQ(g.limit_sources[4].acceleration, "robot.jointLimits");  // no source given: the request's
  EXPECT_THAT(g.limit_sources[0].velocity, HasSubstr("URDF <limit velocity>"));
  const RobotModel over = *planner::robot_from_urdf(text, given);  // over the block's 6
  EXPECT_EQ(over.limits[0].max_acceleration, 2.5);
  EXPECT_EQ(over.limit_sources[0].acceleration, "robot.jointLimits");
}

// --- bad documents -----------------------------------------------------------------------

struct BadDocument {
  const char* name;
  std::function<std::string(std::string)> spoil;  // from the scara fixture
  const char* field;
  std::vector<std::string> says;
};

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

void PrintTo(const BadDocument& d, std::ostream* os) { *os << d.name; }

class UrdfRefused : public ::testing::TestWithParam<BadDocument> {};

TEST_P(UrdfRefused, NamesTheElementAndLine) {
  const std::string text = GetParam().spoil(fixture("scara_like.urdf"));
  auto m = planner::robot_from_urdf(text);
  ASSERT_FALSE(m) << GetParam().name;
  const std::string all = listed(m.error());
  EXPECT_EQ(m.error()[0].field, GetParam().field) << all;
  for (const auto& s : GetParam().says) EXPECT_THAT(all, HasSubstr(s));
}

INSTANTIATE_TEST_SUITE_P(
    Urdf, UrdfRefused,
    ::testing::Values(
        BadDocument{"NotXml", [](std::string) { return std::string("robot name=\"x\""); }, "urdf", {"not well-formed"}},
        BadDocument{"Unclosed", [](std::string doc) { return replaced(doc, "</robot>", ""); }, "urdf", {"not well-formed", "line"}},
        BadDocument{"Empty", [](std::string) { return std::string(); }, "urdf", {"not well-formed"}},
        BadDocument{"NotARobot",
                    [](std::string) { return std::string("<?xml version=\"1.0\"?>\n<world name=\"w\"/>"); }, "urdf",
                    {"line 2", "<robot>"}},
        BadDocument{"ChildLinkMissing", [](std::string doc) { return replaced(doc, "<child link=\"link3\"/>", ""); }, "urdf",
                    {"j3"}},
        BadDocument{"UnknownParent",
                    [](std::string doc) { return replaced(doc, "<parent link=\"link1\"/>", "<parent link=\"nowhere\"/>"); },
                    "urdf", {"nowhere"}},
        BadDocument{"BadNumber",
                    [](std::string doc) { return replaced(doc, "xyz=\"0.35 0 0.02\"", "xyz=\"0.35 zero 0.02\""); }, "urdf",
                    {}},
        BadDocument{"NoLimit",
                    [](std::string doc) {
                      return replaced(doc, "<limit lower=\"-2.6\" upper=\"2.6\" effort=\"30\" velocity=\"3.5\"/>", "");
                    },
                    "urdf", {"j2"}},
        BadDocument{"ZeroVelocity",
                    [](std::string doc) { return replaced(doc, "effort=\"30\" velocity=\"3.5\"", "effort=\"30\" velocity=\"0\""); },
                    "urdf", {"line", "joint 'j2'", "velocity"}},
        BadDocument{"LowerAboveUpper",
                    [](std::string doc) { return replaced(doc, "lower=\"-1.2\" upper=\"1.2\"", "lower=\"1.2\" upper=\"-1.2\""); },
                    "urdf", {"joint 'j3'", "lower <= upper"}},
        BadDocument{"ZeroAxis", [](std::string doc) { return replaced(doc, "<axis xyz=\"0 0.6 0.8\"/>", "<axis xyz=\"0 0 0\"/>"); },
                    "urdf", {"j3"}},
        BadDocument{"FloatingJoint",
                    [](std::string doc) { return replaced(doc, "<joint name=\"j2\" type=\"revolute\">", "<joint name=\"j2\" type=\"floating\">"); },
                    "urdf", {"joint 'j2'", "floating"}},
        BadDocument{"SideBlockUnknownJoint",
                    [](std::string doc) {
                      return replaced(doc, "<joint name=\"j3\" max_acceleration=\"8\"", "<joint name=\"j33\" max_acceleration=\"8\"");
                    },
                    "urdf", {"'j33'", "no moving joint"}},
        BadDocument{"SideBlockFixedJoint",
                    [](std::string doc) {
                      return replaced(doc, "<joint name=\"j3\" max_acceleration=\"8\"", "<joint name=\"elbow_mount\" max_acceleration=\"8\"");
                    },
                    "urdf", {"'elbow_mount'", "no moving joint"}},
        BadDocument{"SideBlockBadNumber",
                    [](std::string doc) { return replaced(doc, "max_acceleration=\"7\"", "max_acceleration=\"seven\""); }, "urdf",
                    {"joint 'j2'", "not a finite number"}},
        BadDocument{"NegativeJerk",
                    [](std::string doc) { return replaced(doc, "max_jerk=\"60\"", "max_jerk=\"-60\""); }, "urdf",
                    {"joint 'j1'", "max_jerk"}},
        BadDocument{"HomeOutside", [](std::string doc) { return replaced(doc, "home=\"0.05\"", "home=\"0.5\""); }, "urdf",
                    {"joint 'j4'", "outside"}},
        BadDocument{"Loop",
                    [](std::string doc) { return replaced(doc, "<parent link=\"base_link\"/>", "<parent link=\"tool\"/>"); }, "urdf",
                    {}}),
    [](const ::testing::TestParamInfo<BadDocument>& p) { return std::string(p.param.name); });

// What would hang, leak, overflow the stack or read past the end inside TinyXML and urdfdom
// is refused before them (found by fuzz_urdf; tests/fuzz/regressions/fuzz_urdf).
TEST(Urdf, HostileDocumentsAreRefusedBeforeTheParsers) {
  const std::string joint = R"(<joint name="%s" type="revolute"><parent link="%s"/><child link="%s"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>)";
  const auto j = [&](const char* name, const char* parent, const char* child) {
    std::string out = joint;
    for (const char* x : {name, parent, child}) out.replace(out.find("%s"), 2, x);
    return out;
  };
  // A loop of links beside a root: urdfdom accepts it, and the walk to the root never ends.
  const std::string loop = "<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/><link name=\"c\"/><link name=\"d\"/>" +
                           j("ab", "a", "b") + j("cd", "c", "d") + j("dc", "d", "c") + "</robot>";
  auto m = planner::robot_from_urdf(loop, chain("", "c"));
  ASSERT_FALSE(m);
  EXPECT_THAT(listed(m.error()), HasSubstr("loop"));
  // Two parents for one link.
  const std::string twice = "<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/><link name=\"c\"/>" +
                            j("ab", "a", "b") + j("cb", "c", "b") + "</robot>";
  m = planner::robot_from_urdf(twice);
  ASSERT_FALSE(m);
  EXPECT_THAT(listed(m.error()), HasSubstr("already the child of line 1, joint 'ab'"));
  // A long chain is refused by its count before any work per joint.
  std::string longest = "<robot name=\"r\"><link name=\"l0\"/>";
  for (int k = 1; k <= 5000; ++k) {
    const std::string a = "l" + std::to_string(k - 1), b = "l" + std::to_string(k);
    longest += "<link name=\"" + b + "\"/>" + j(("j" + std::to_string(k)).c_str(), a.c_str(), b.c_str());
  }
  m = planner::robot_from_urdf(longest + "</robot>");
  ASSERT_FALSE(m);
  EXPECT_THAT(m.error()[0].description, HasSubstr("has 5000 moving joints; at most 12"));
  // Nesting: 65 levels are refused at once (TinyXML recurses per level, in time depth^2).
  std::string deep = "<robot name=\"r\">";
  for (int k = 0; k < 100000; ++k) deep += "<a>";
  m = planner::robot_from_urdf(deep);
  ASSERT_FALSE(m);
  EXPECT_THAT(m.error()[0].description, HasSubstr("nest deeper than 64"));
  // Comments, CDATA and quoted '>' do not count as levels.
  std::string fine(planner::builtin_urdf("ur5e"));
  fine.insert(fine.find("<link"), "<!-- <a><a><a> --><![CDATA[<b><b>]]>");
  EXPECT_TRUE(planner::robot_from_urdf(fine)) << "a comment is not nesting";
  // Not UTF-8: a multi-byte character cut off at the end, a stray continuation byte.
  m = planner::robot_from_urdf(std::string("<robot name=\"r\">\n<link name=\"a\"/></robot>\xC3"));
  ASSERT_FALSE(m);
  EXPECT_THAT(m.error()[0].description, HasSubstr("not UTF-8: line 2"));
  m = planner::robot_from_urdf(std::string("<robot name=\"\x80\"/>"));
  ASSERT_FALSE(m);
  EXPECT_THAT(m.error()[0].description, HasSubstr("not UTF-8"));
  EXPECT_TRUE(planner::robot_from_urdf(std::string(planner::builtin_urdf("panda")) + "<!-- \xC3\xA9 -->"))
      << "well-formed UTF-8 is fine";
}

// --- bounds before the parsers ------------------------------------------------------------

core::Violations refused(const std::string& text) {
  auto m = planner::robot_from_urdf(text);
  EXPECT_FALSE(m) << "accepted:\n" << text.substr(0, 300);
  if (m) return {};
  for (const auto& v : m.error()) EXPECT_TRUE(well_formed_utf8(v.description)) << "a message is not UTF-8: " << v.field;
  return m.error();
}

std::string repeated(const std::string& s, int times) {
  std::string out;
  out.reserve(s.size() * static_cast<std::size_t>(times));
  for (int k = 0; k < times; ++k) out += s;
  return out;
}

// Stray closing tags before <robot> drove the depth count negative, and the nesting they made
// room for reached TinyXML's recursive parser (50,000 of each: SIGSEGV). A closing tag that
// closes nothing, or not the element open, is refused where it is.
TEST(Urdf, StrayClosingTagsAreRefusedAndCannotMakeRoomForNesting) {
  const std::string attack = "<?xml version=\"1.0\"?>\n\n" + repeated("</a>", 50000) + "<robot name=\"r\">" +
                             repeated("<a>", 50000) + repeated("</a>", 50000) + "</robot>";
  auto v = refused(attack);
  ASSERT_FALSE(v.empty());
  EXPECT_EQ(v[0].field, "urdf");
  EXPECT_THAT(v[0].description, HasSubstr("line 3: the closing tag </a> closes no element"));
  // Inside the document: a closing tag of another element than the one open.
  v = refused("<robot name=\"r\">\n<link name=\"a\">\n</joint>\n</robot>");
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("line 3: the closing tag </joint> does not close <link> (line 2)"));
  // After the root: nothing is open any more.
  v = refused(std::string(planner::builtin_urdf("ur5e")) + "</robot>" + repeated("<a>", 100));
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("closes no element"));
}

// TinyXML reads a malformed character reference up to the next ';', markup included, and
// some of its lenient readings end a tag later than a plain scan would: all refused, so that
// the nesting counted is the nesting parsed.
TEST(Urdf, MarkupThatHidesTagsFromTheCountIsRefused) {
  const std::string level = "<a x=\"&#x\"></a>x41;\">";  // TinyXML: the value swallows </a>
  auto v = refused("<robot name=\"r\">" + repeated(level, 200) + "</robot>");
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("line 1: the character reference \"&#x\" is malformed"));
  v = refused("<robot name=\"r\">\n<link name=a/></robot>");
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("line 2: in <link>: an attribute is name=\"value\""));
  v = refused("<?xml version=\"1.0>\"?><robot name=\"r\"/>");
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("an XML declaration is"));
  v = refused("<robot name=\"r\">\n\n< link/></robot>");
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("line 3: '<' starts no tag"));
  v = refused(std::string("<robot name=\"r\">\n\x01</robot>"));
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("line 2: the control character U+0001"));
}

// TinyXML compares each attribute with the element's earlier ones: 40,000 on one element held
// a worker 26 s. More than 64 on one element are refused; 64 are fine.
TEST(Urdf, ManyAttributesOnOneElementAreRefused) {
  const std::string ur5e(planner::builtin_urdf("ur5e"));
  const auto with_attributes = [&](int count) {
    std::string extra;
    for (int k = 1; k < count; ++k) extra += " x" + std::to_string(k) + "=\"" + std::to_string(k) + "\"";
    std::string text = ur5e;
    text.insert(text.find("<link name=\"base_link\"") + 22, extra);  // after its name: `count` in all
    return text;
  };
  EXPECT_TRUE(planner::robot_from_urdf(with_attributes(64))) << "64 attributes on an element are fine";
  std::size_t line = 1;
  for (std::size_t i = 0; i < ur5e.find("<link name=\"base_link\""); ++i) line += ur5e[i] == '\n';
  auto v = refused(with_attributes(65));
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("line " + std::to_string(line) + ": <link> has more than 64 attributes"));
  v = refused(with_attributes(40000));
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("has more than 64 attributes"));
}

// urdfdom splits a vector's value into a string per space (32 bytes each): 4 MiB of spaces in
// one xyz cost 180 MB. A value has at most 16 KiB.
TEST(Urdf, LongAttributeValuesAreRefused) {
  const std::string ur5e(planner::builtin_urdf("ur5e"));
  const auto padded = [&](std::size_t spaces) { return replaced(ur5e, "xyz=\"", "xyz=\"" + std::string(spaces, ' ')); };
  EXPECT_TRUE(planner::robot_from_urdf(padded(16000))) << "16,000 bytes in a value are fine";
  auto v = refused(padded(4u << 20));
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr(": the value of xyz has "));
  EXPECT_THAT(v[0].description, HasSubstr("bytes; at most 16384"));
}

// Elements, attributes, comments and other markup: at most 100,000 in all (a robot has a few
// thousand; each is an object of both parsers).
TEST(Urdf, ManyElementsAreRefused) {
  std::string text(planner::builtin_urdf("panda"));
  const std::size_t at = text.find("<link");
  text.insert(at, repeated("<empty/>", 10000) + repeated("<!-- c -->", 10000));
  EXPECT_TRUE(planner::robot_from_urdf(text)) << "20,000 more elements and comments are fine";
  text.insert(at, repeated("<empty/>", 50000) + repeated("<!-- c -->", 30000));
  auto v = refused(text);
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("more than 100000 elements, attributes, comments and other markup"));
  EXPECT_THAT(v[0].description, HasSubstr("line "));
}

// TinyXML decodes a character reference to whatever it names (a surrogate, past U+10FFFF, NUL)
// and urdfdom reads one beyond ASCII as a single byte: either puts bytes that are not UTF-8
// into names and messages. Refused, naming the reference and its line.
TEST(Urdf, CharacterReferencesThatAreNotAsciiTextAreRefusedByName) {
  const std::string scara = fixture("scara_like.urdf");
  const std::string entry = "<joint name=\"j3\" max_acceleration=\"8\"";
  std::size_t line = 1;
  for (std::size_t i = 0; i < scara.find(entry); ++i) line += scara[i] == '\n';
  struct Case {
    const char* reference;
    const char* says;
  };
  for (const Case& c : {Case{"&#xD800;", "surrogate"}, Case{"&#x110000;", "past U+10FFFF"},
                        Case{"&#0;", "control character U+0000"}, Case{"&#55296;", "surrogate"},
                        Case{"&#xE9;", "beyond ASCII (U+00E9)"}, Case{"&#x;", "malformed"},
                        Case{"&#X41;", "malformed"}, Case{"&#x1F600;", "beyond ASCII"},
                        Case{"&#x100000041;", "past U+10FFFF"}}) {
    SCOPED_TRACE(c.reference);
    auto v = refused(replaced(scara, entry, "<joint name=\"j9" + std::string(c.reference) + "\" max_acceleration=\"8\""));
    ASSERT_FALSE(v.empty());
    EXPECT_EQ(v[0].field, "urdf");
    EXPECT_THAT(v[0].description, HasSubstr("line " + std::to_string(line) + ": the character reference"));
    EXPECT_THAT(v[0].description, HasSubstr(c.says));
  }
  auto v = refused(replaced(scara, entry, "<joint name=\"j9&#x110000;\" max_acceleration=\"8\""));
  ASSERT_FALSE(v.empty());
  EXPECT_THAT(v[0].description, HasSubstr("\"&#x110000;\""));
  // ASCII references, and characters beyond ASCII written as themselves, are fine.
  std::string fine = replaced(scara, "<geotraj description=\"", "<geotraj description=\"&#x41;&#65;&#10;&#9;&amp; \xC3\xA9 ");
  auto m = planner::robot_from_urdf(fine);
  ASSERT_TRUE(m) << listed(m.error());
  EXPECT_THAT(m->description, HasSubstr("AA\n\t& \xC3\xA9"));
}

// Real robots, as their makers and xacro write them, still load.
TEST(Urdf, RealDocumentsPassTheBounds) {
  for (const Document& d : documents()) {
    SCOPED_TRACE(d.name);
    EXPECT_TRUE(planner::robot_from_urdf(d.text, chain(d.base, d.tip)));
    // With what XML allows around the markup: a declaration with an encoding, a DOCTYPE, a
    // byte-order mark, a space before '>' of a closing tag, CDATA.
    std::string text = d.text;
    if (text.starts_with("<?xml")) text.erase(0, text.find("?>") + 2);
    text = "\xEF\xBB\xBF<?xml version='1.0' encoding=\"UTF-8\" standalone=\"yes\"?>\n<!DOCTYPE robot>\n" + text;
    text.replace(text.rfind("</robot>"), 8, "<![CDATA[ </a></b> ]]></robot >");
    auto m = planner::robot_from_urdf(text, chain(d.base, d.tip));
    EXPECT_TRUE(m) << (m ? std::string() : listed(m.error()));
  }
}

// The parse gives up between its stages once the call's deadline has passed or the call
// was cancelled: a valid document is then refused with a violation of `urdf` that says so,
// and is read whole with time left.
TEST(Urdf, TheParseStopsAtTheDeadlineOrOnCancellation) {
  const std::string text(planner::builtin_urdf("ur5e"));
  ASSERT_FALSE(text.empty());
  planner::UrdfOptions late;
  late.stop_at.deadline = std::chrono::steady_clock::now() - std::chrono::milliseconds(1);
  auto m = planner::robot_from_urdf(text, late);
  ASSERT_FALSE(m);
  ASSERT_EQ(m.error().size(), 1u);
  EXPECT_EQ(m.error()[0].field, "urdf");
  EXPECT_THAT(m.error()[0].description, HasSubstr("deadline passed or it was cancelled"));

  std::stop_source cancel;
  cancel.request_stop();
  planner::UrdfOptions cancelled;
  cancelled.stop_at.stop = cancel.get_token();
  EXPECT_FALSE(planner::robot_from_urdf(text, cancelled));

  planner::UrdfOptions in_time;
  in_time.stop_at.deadline = std::chrono::steady_clock::now() + std::chrono::hours(1);
  EXPECT_TRUE(planner::robot_from_urdf(text, in_time));
}

// Messages point at the line: the element's own line in the document.
TEST(Urdf, ErrorsGiveTheLineOfTheElement) {
  const std::string text = fixture("scara_like.urdf");
  const std::string spoiled = replaced(text, "effort=\"30\" velocity=\"3.5\"", "effort=\"30\" velocity=\"-1\"");
  std::size_t line = 1;
  for (std::size_t i = 0; i < spoiled.find("<joint name=\"j2\""); ++i) line += spoiled[i] == '\n';
  auto m = planner::robot_from_urdf(spoiled);
  ASSERT_FALSE(m);
  EXPECT_THAT(m.error()[0].description, HasSubstr("line " + std::to_string(line) + ", joint 'j2'"));
}

// --- the iiwa 14's mass properties (iiwa14.urdf: the IFL-CAMP iiwa_stack description's) -------

// One joint of a chain written out here: its origin in the parent link (URDF: Trans(xyz)
// Rz(yaw) Ry(pitch) Rx(roll)) and its axis in the child link.
struct ChainJoint {
  Eigen::Vector3d xyz, rpy, axis;
};

// Every link's frame in W (link i is the body joint i moves), from the base's pose and the rows.
std::vector<Eigen::Isometry3d> link_frames(const Eigen::Isometry3d& base, const std::vector<ChainJoint>& rows,
                                           const JointVector& q) {
  std::vector<Eigen::Isometry3d> frames;
  Eigen::Isometry3d X = base;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const ChainJoint& r = rows[i];
    X = X * Eigen::Translation3d(r.xyz) * Eigen::AngleAxisd(r.rpy.z(), Eigen::Vector3d::UnitZ()) *
        Eigen::AngleAxisd(r.rpy.y(), Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(r.rpy.x(), Eigen::Vector3d::UnitX()) *
        Eigen::AngleAxisd(q(static_cast<Eigen::Index>(i)), r.axis);
    frames.push_back(X);
  }
  return frames;
}

// The iiwa 14 read from iiwa14.urdf carries iiwa_stack's mass properties (masses 4, 4, 3, 2.7,
// 1.7, 1.8, 0.3 kg; 17.5 kg) and KUKA's torques. Its gravity torques are the derivatives of the
// potential energy of its links' centres of mass computed two ways, each link's pose written
// out here: (1) from iiwa14.urdf's joint origins (translations along z, A2 and A6 about +y, A4
// about -y, link 7 flipped by pi about x) with the centres of mass as iiwa14.urdf gives them;
// (2) from iiwa_stack's own chain (iiwa_description/urdf/iiwa14.xacro: its joint origins with
// their rpy, every joint about its child's z) with its centres of mass exactly as that file
// gives them, which checks the move into iiwa14.urdf's link frames. Its mass matrix equals the
// one of iiwa_stack's chain and diagonal inertias (sum of m J_v^T J_v + J_w^T R I R^T J_w),
// which checks the inertias' move.
TEST(Urdf, TheIiwa14sMassPropertiesAreIiwaStacksInItsLinkFrames) {
  const auto& m = *planner::find_builtin_robot("iiwa14");
  ASSERT_TRUE(core::has_dynamics(m));
  ASSERT_EQ(m.dof(), 7u);
  const double mass[] = {4.0, 4.0, 3.0, 2.7, 1.7, 1.8, 0.3};
  double total = 0.0;
  for (std::size_t i = 0; i < 7; ++i) {
    EXPECT_DOUBLE_EQ(m.joints[i].inertial->mass, mass[i]) << "link " << i + 1;
    total += m.joints[i].inertial->mass;
  }
  EXPECT_NEAR(total, 17.5, 1e-12);
  const double efforts[] = {320, 320, 176, 176, 110, 40, 40};  // KUKA's, unchanged
  for (std::size_t i = 0; i < 7; ++i) EXPECT_EQ(m.limits[i].max_torque, efforts[i]) << "A" << i + 1;

  const double pi = std::numbers::pi, h = pi / 2;
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY(), z = Eigen::Vector3d::UnitZ(), o = Eigen::Vector3d::Zero();
  // (1) iiwa14.urdf's joints and centres of mass.
  const std::vector<ChainJoint> ours = {{{0, 0, 0.1575}, o, z}, {{0, 0, 0.2025}, o, y},  {{0, 0, 0.2045}, o, z},
                                        {{0, 0, 0.2155}, o, -y}, {{0, 0, 0.1845}, o, z}, {{0, 0, 0.2155}, o, y},
                                        {{0, 0, 0.081}, {pi, 0, 0}, -z}};
  const Eigen::Vector3d our_com[] = {{0, -0.03, 0.12},  {-0.0003, 0.042, 0.059}, {0, 0.03, 0.13}, {0, -0.034, 0.067},
                                     {-0.0001, -0.021, 0.076}, {0, 0.0004, 0.0006}, {0, 0, -0.02}};
  // (2) iiwa_stack's joints (iiwa14.xacro: joint_1 .. joint_7), centres of mass and inertias.
  const std::vector<ChainJoint> stack = {{{0, 0, 0.1575}, o, z},       {{0, 0, 0.2025}, {h, 0, pi}, z},
                                         {{0, 0.2045, 0}, {h, 0, pi}, z}, {{0, 0, 0.2155}, {h, 0, 0}, z},
                                         {{0, 0.1845, 0}, {-h, pi, 0}, z}, {{0, 0, 0.2155}, {h, 0, 0}, z},
                                         {{0, 0.081, 0}, {-h, pi, 0}, z}};
  const Eigen::Vector3d stack_com[] = {{0, -0.03, 0.12},       {0.0003, 0.059, 0.042}, {0, 0.03, 0.13},
                                       {0, 0.067, 0.034},      {0.0001, 0.021, 0.076}, {0, 0.0006, 0.0004},
                                       {0, 0, 0.02}};
  const Eigen::Vector3d stack_inertia[] = {{0.1, 0.09, 0.02},     {0.05, 0.018, 0.044}, {0.08, 0.075, 0.01},
                                           {0.03, 0.01, 0.029},   {0.02, 0.018, 0.005}, {0.005, 0.0036, 0.0047},
                                           {0.001, 0.001, 0.001}};
  const Eigen::Vector3d g(0.0, 0.0, -core::kStandardGravity);
  const auto potential = [&](const std::vector<ChainJoint>& rows, const Eigen::Vector3d* com) {
    return [&rows, com, &m, &mass, &g](const JointVector& q) {
      const std::vector<Eigen::Isometry3d> X = link_frames(m.base, rows, q);
      double V = 0.0;
      for (std::size_t i = 0; i < 7; ++i) V -= mass[i] * g.dot(X[i] * com[i]);
      return V;
    };
  };
  std::mt19937_64 rng(37);
  core::DynamicsOptions no_gravity;
  no_gravity.gravity.setZero();
  const JointVector zero = JointVector::Zero(7);
  for (int k = 0; k < 20; ++k) {
    const JointVector q = k == 0 ? zero : random_q(m, rng);
    SCOPED_TRACE(::testing::Message() << "q = " << q.transpose());
    expect_torques_hold_the_weights(m, q, potential(ours, our_com));
    expect_torques_hold_the_weights(m, q, potential(stack, stack_com));
    // The mass matrix of iiwa_stack's chain against the model's, column by column.
    const std::vector<Eigen::Isometry3d> X = link_frames(m.base, stack, q);
    Eigen::Matrix<double, 7, 7> M = Eigen::Matrix<double, 7, 7>::Zero();
    for (std::size_t i = 0; i < 7; ++i) {
      Eigen::Matrix<double, 3, 7> Jv = Eigen::Matrix<double, 3, 7>::Zero(), Jw = Jv;
      const Eigen::Vector3d c = X[i] * stack_com[i];
      for (std::size_t j = 0; j <= i; ++j) {
        const Eigen::Vector3d axis = X[j].linear().col(2);  // every iiwa_stack joint turns about its child's z
        Jw.col(static_cast<Eigen::Index>(j)) = axis;
        Jv.col(static_cast<Eigen::Index>(j)) = axis.cross(c - X[j].translation());
      }
      const Eigen::Matrix3d I = X[i].linear() * stack_inertia[i].asDiagonal() * X[i].linear().transpose();
      M += mass[i] * Jv.transpose() * Jv + Jw.transpose() * I * Jw;
    }
    JointVector tau;
    for (Eigen::Index j = 0; j < 7; ++j) {
      core::inverse_dynamics(m, q, zero, JointVector::Unit(7, j), no_gravity, tau);
      EXPECT_LE((tau - M.col(j)).cwiseAbs().maxCoeff(), 1e-12) << "column " << j << ": " << tau.transpose()
                                                                << "\n  iiwa_stack's: " << M.col(j).transpose();
    }
  }
}

// KUKA rates the LBR iiwa 14 R820 for 14 kg. With iiwa_stack's mass properties and KUKA's
// torques, at rest anywhere within its joint limits with 14 kg at the flange (a point mass at
// iiwa_link_ee's origin), gravity needs less than every torque limit; without the payload
// less again. The outstretched arm (A2 at 90 deg, the rest 0) gives the payload its longest
// lever about A2 (1.306 - 0.36 m); there A2's torque is the sum of every weight times its height
// above A2 in the upright arm (iiwa14.urdf's centres of mass), and no random pose loads A2 more
// than that but for the centres of mass' small sideways offsets (0.1 % allowed).
TEST(Urdf, TheIiwa14HoldsItsRatedPayloadAnywhereWithinItsTorques) {
  const auto& m = *planner::find_builtin_robot("iiwa14");
  ASSERT_TRUE(core::has_dynamics(m));
  ASSERT_TRUE(m.tool.matrix().isIdentity());
  const double rated_payload = 14.0;
  core::DynamicsOptions rated, bare;
  rated.payload.mass = rated_payload;
  const Eigen::Index n = 7;
  const JointVector zero = JointVector::Zero(n);
  JointVector tau;
  std::mt19937_64 rng(34);
  double worst = 0.0, worst_bare = 0.0;
  JointVector per_joint = JointVector::Zero(n);
  const auto usage = [&](Eigen::Index i) { return std::abs(tau(i)) / *m.limits[static_cast<std::size_t>(i)].max_torque; };
  for (int k = 0; k < 5000; ++k) {
    const JointVector q = random_q(m, rng);
    core::inverse_dynamics(m, q, zero, zero, rated, tau);
    for (Eigen::Index i = 0; i < n; ++i) {
      per_joint(i) = std::max(per_joint(i), usage(i));
      worst = std::max(worst, usage(i));
    }
    core::inverse_dynamics(m, q, zero, zero, bare, tau);
    for (Eigen::Index i = 0; i < n; ++i) worst_bare = std::max(worst_bare, usage(i));
  }
  // The outstretched arm: every centre of mass beyond A2 at its height above A2 in the upright
  // arm, now a horizontal lever; the payload at 1.306 - 0.36 m. Links 2-7: A3 is 0.2045 m above
  // A2, A4 0.42, A5 0.42 + 0.1845, A6 0.82, A7 0.82 + 0.081 (link 7 flipped: its z = -0.02 is
  // 0.02 m further up).
  JointVector out = zero;
  out(1) = std::numbers::pi / 2;
  core::inverse_dynamics(m, out, zero, zero, rated, tau);
  const double above_a2[] = {0.059, 0.2045 + 0.13, 0.42 + 0.067, 0.42 + 0.1845 + 0.076, 0.82 + 0.0006,
                             0.82 + 0.081 + 0.02};
  double lever_sum = rated_payload * (1.306 - 0.36);
  for (std::size_t i = 1; i < 7; ++i) lever_sum += m.joints[i].inertial->mass * above_a2[i - 1];
  const double a2_outstretched = lever_sum * core::kStandardGravity;
  EXPECT_NEAR(std::abs(tau(1)), a2_outstretched, 1e-9);
  const double a2_worst = a2_outstretched / *m.limits[1].max_torque;
  std::printf("[ measured ] iiwa14 at rest, 5,000 random poses: gravity uses at most %.3f of a torque limit with %.0f kg "
              "at the flange (A1..A7: %.3f %.3f %.3f %.3f %.3f %.3f %.3f), %.3f without; outstretched, A2 %.1f N m = "
              "%.3f of 320 N m\n",
              worst, rated_payload, per_joint(0), per_joint(1), per_joint(2), per_joint(3), per_joint(4), per_joint(5),
              per_joint(6), worst_bare, a2_outstretched, a2_worst);
  EXPECT_LT(worst, 1.0);
  EXPECT_LT(a2_worst, 1.0);
  EXPECT_LE(per_joint(1), a2_worst * 1.001) << "no random pose loads A2 more than the outstretched arm";
  EXPECT_LT(worst_bare, worst);
  EXPECT_GT(worst, 0.3) << "the arm's weight and the payload are felt";
}

}  // namespace
}  // namespace geotraj::test
