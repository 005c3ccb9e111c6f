// The `geotraj` CLI run as a subprocess on the example request files: tables, --json, errors
// on stderr, in process and against a server on a loopback port.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gmock/gmock.h>

#include "planner/robots.hpp"
#include "tests/client/cli_support.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;

// Runs the CLI with `args` (shell words), `stdin_text` (no single quotes) on its standard
// input when given, and captures its output.
CliRun run_cli(const std::string& args, bool merge_stderr = false, const std::string& stdin_text = "") {
  const std::string feed = stdin_text.empty() ? "" : "printf '%s' '" + stdin_text + "' | ";
  const std::string command =
      feed + "'" + build_paths::cli() + "' " + args + (merge_stderr ? " 2>&1" : " 2>/dev/null");
  return run_shell(command);
}

std::string example_path(const std::string& name) { return std::string("'") + build_paths::examples_dir() + "/" + name + "'"; }

TEST(Cli, PlanPrintsATable) {
  const CliRun run = run_cli("plan " + example_path("plan_demo_path_a.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_THAT(run.out, HasSubstr("segments: 3, total arc length"));
  EXPECT_THAT(run.out, HasSubstr("POLYNOMIAL"));
  EXPECT_THAT(run.out, HasSubstr("closed loop: max error"));
}

TEST(Cli, PlanJsonIsAPlanResponse) {
  const CliRun run = run_cli("plan --json " + example_path("plan_demo_path_b.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto response = from_json<v1::PlanResponse>(run.out);
  EXPECT_EQ(response.segments_size(), 3);
  EXPECT_EQ(response.frames_size(), 4);
  EXPECT_GT(response.arc_length(), 0.0);
  EXPECT_LT(response.closed_loop().max_error(), 1e-9);
}

// --optimize-redundancy: the PA-10's self-motion chosen over path C's 10 s, reported in the
// PlanResponse's optimization block; a criterion the flag does not know is refused by the CLI.
TEST(Cli, OptimizeRedundancyChoosesThePa10sSelfMotion) {
  const CliRun run = run_cli("plan --json --optimize-redundancy acceleration=1,range=0.01 " +
                             example_path("plan_pa10_path_c.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto response = from_json<v1::PlanResponse>(run.out);
  const auto& report = response.optimization().redundancy();
  EXPECT_NE(report.status(), v1::OPTIMIZER_STATUS_UNSPECIFIED);
  EXPECT_LE(report.objective_after(), report.objective_before());
  const CliRun bad = run_cli("plan --optimize-redundancy speed=1 " + example_path("plan_pa10_path_c.json"), true);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.out.find("unknown criterion \"speed\""), std::string::npos) << bad.out;
}

// --tool-axis-free: the UR5e's weld seam with the torch's roll chosen with the joints (the
// redundancy optimiser's report comes with the plan); without a robot, refused by the CLI.
TEST(Cli, ToolAxisFreeChoosesTheTorchsRoll) {
  const CliRun run = run_cli("plan --json --tool-axis-free " + example_path("plan_seam_ur5e.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto response = from_json<v1::PlanResponse>(run.out);
  EXPECT_TRUE(response.robot().feasible());
  const auto& report = response.optimization().redundancy();
  EXPECT_NE(report.status(), v1::OPTIMIZER_STATUS_UNSPECIFIED);
  EXPECT_NE(report.status(), v1::OPTIMIZER_STATUS_FAILED) << report.message();
  const CliRun bad = run_cli("plan --tool-axis-free " + example_path("plan_demo_path_a.json"), true);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.out.find("--tool-axis-free frees a robot's tool roll: the request has no robot"), std::string::npos)
      << bad.out;
}

// --payload and --max-torque: the Panda's pick and place with its rated 3 kg, its shoulder
// limited to 50 N m, timed within that torque (reached, to the jerk-limited timing's margin:
// 100.0 % in the table); a flag that cannot be read, or a request without a robot, refused
// by the CLI. (A flag of several values takes the words after it: the file goes first.)
TEST(Cli, PayloadAndTorqueLimitsTimeTheMotionWithinTheTorques) {
  const std::string flags = " --payload 3,0,0,0.05 --max-torque panda_joint2=50";
  const CliRun table = run_cli("plan " + example_path("plan_joint_path_panda.json") + flags);
  ASSERT_EQ(table.exit_code, 0) << table.out;
  EXPECT_THAT(table.out, HasSubstr("peak |tau|  tau usage"));
  const CliRun json = run_cli("plan --json " + example_path("plan_joint_path_panda.json") + flags);
  ASSERT_EQ(json.exit_code, 0) << json.out;
  const auto response = from_json<v1::PlanResponse>(json.out);
  ASSERT_EQ(response.robot().joints_size(), 7);
  EXPECT_LE(response.robot().joints(1).peak_torque(), 50.0 * (1.0 + 1e-9));
  EXPECT_GT(response.robot().joints(1).torque_usage(), 0.999);
  std::stringstream lines(table.out);
  bool shown = false;
  for (std::string line; std::getline(lines, line);)
    shown = shown || (line.rfind("    1 ", 0) == 0 && line.size() > 6 && line.substr(line.size() - 6) == "100.0%");
  EXPECT_TRUE(shown) << table.out;
  const CliRun bad = run_cli("plan " + example_path("plan_joint_path_panda.json") + " --max-torque panda_joint2", true);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_THAT(bad.out, HasSubstr("--max-torque takes JOINT=N_M,...: 'panda_joint2' is not one"));
  const CliRun none = run_cli("plan " + example_path("plan_demo_path_a.json") + " --payload 1", true);
  EXPECT_NE(none.exit_code, 0);
  EXPECT_THAT(none.out, HasSubstr("--payload and --max-torque are a robot's"));
}

// A file in the test's temporary directory, removed at the end of the test.
struct TempText {
  std::string path;
  TempText(const std::string& name, const std::string& text)
      : path(::testing::TempDir() + "geotraj_cli_test_" + std::to_string(::getpid()) + "_" + name) {
    std::ofstream(path) << text;
  }
  ~TempText() { std::remove(path.c_str()); }
};

// --urdf FILE: the Panda's URDF as Franka ships it (no <geotraj> block) for fk and ik at once,
// the same pose as the built-in Panda's; a plan with MoveIt's joint_limits.yaml for the
// accelerations (--joint-limits), refused without it naming what is missing; --robot with
// --urdf refused.
TEST(Cli, UrdfAsShippedForTheKinematicsAndWithMoveItsLimitsForAPlan) {
  std::string urdf(planner::builtin_urdf("panda"));
  const auto block = urdf.rfind("<geotraj");
  urdf.erase(block, urdf.find("</geotraj>") + std::string("</geotraj>").size() - block);
  const TempText file("panda.urdf", urdf);
  const std::string q = "0.1,-0.6,0.2,-2.2,0.1,1.7,0.7";
  const CliRun shipped = run_cli("fk --json --urdf '" + file.path + "' --joints " + q);
  ASSERT_EQ(shipped.exit_code, 0) << shipped.out;
  const CliRun builtin = run_cli("fk --json --robot panda --joints " + q);
  ASSERT_EQ(builtin.exit_code, 0) << builtin.out;
  const auto a = from_json<v1::ForwardKinematicsResponse>(shipped.out);
  const auto b = from_json<v1::ForwardKinematicsResponse>(builtin.out);
  EXPECT_NEAR(a.pose().position().x(), b.pose().position().x(), 1e-12);
  EXPECT_NEAR(a.pose().position().y(), b.pose().position().y(), 1e-12);
  EXPECT_NEAR(a.pose().position().z(), b.pose().position().z(), 1e-12);
  const CliRun ik = run_cli("ik --json --urdf '" + file.path + "' --position 0.4,0.1,0.5 --orientation 0,1,0,0");
  EXPECT_EQ(ik.exit_code, 0) << ik.out;

  std::string yaml = "joint_limits:\n";
  for (int j = 1; j <= 7; ++j)
    yaml += "  panda_joint" + std::to_string(j) + ":\n    has_acceleration_limits: true\n    max_acceleration: 5\n";
  const TempText limits("joint_limits.yaml", yaml);
  const std::string request = example_path("plan_joint_path_panda.json");
  const CliRun bare = run_cli("plan " + request + " --urdf '" + file.path + "'", true);
  EXPECT_NE(bare.exit_code, 0);
  EXPECT_THAT(bare.out, HasSubstr("have no acceleration limit"));
  EXPECT_THAT(bare.out, HasSubstr("robot.jointLimitsYaml"));
  const CliRun planned = run_cli("plan --json " + request + " --urdf '" + file.path + "' --joint-limits '" + limits.path + "'");
  ASSERT_EQ(planned.exit_code, 0) << planned.out;
  const auto response = from_json<v1::PlanResponse>(planned.out);
  EXPECT_TRUE(response.robot().feasible());
  for (const auto& j : response.robot().joints()) {
    EXPECT_LE(j.peak_acceleration(), 5.0 * (1 + 1e-9));
    EXPECT_EQ(j.limit_sources().acceleration(), "robot.jointLimitsYaml");  // the file the CLI sent
    EXPECT_THAT(j.limit_sources().velocity(), HasSubstr("URDF <limit velocity>, line "));
  }
  // A hand's two fingers: two leaves, listed; --tip-link names the flange.
  std::string hand = urdf;
  hand.insert(hand.find("</robot>"), R"(<link name="finger_left"/><link name="finger_right"/>
  <joint name="finger_joint1" type="prismatic"><parent link="panda_link8"/><child link="finger_left"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="0.04" effort="20" velocity="0.2"/></joint>
  <joint name="finger_joint2" type="prismatic"><parent link="panda_link8"/><child link="finger_right"/><axis xyz="0 -1 0"/>
    <limit lower="0" upper="0.04" effort="20" velocity="0.2"/></joint>
)");
  const TempText with_hand("panda_hand.urdf", hand);
  const CliRun tied = run_cli("fk --urdf '" + with_hand.path + "' --joints " + q, true);
  EXPECT_NE(tied.exit_code, 0);
  EXPECT_THAT(tied.out, HasSubstr("'finger_left', 'finger_right'"));
  const CliRun tipped = run_cli("fk --json --urdf '" + with_hand.path + "' --tip-link panda_link8 --joints " + q);
  ASSERT_EQ(tipped.exit_code, 0) << tipped.out;
  const auto c = from_json<v1::ForwardKinematicsResponse>(tipped.out);
  EXPECT_NEAR(c.pose().position().x(), a.pose().position().x(), 1e-12);
  EXPECT_NEAR(c.pose().position().z(), a.pose().position().z(), 1e-12);
  EXPECT_EQ(run_cli("fk --robot panda --tip-link panda_link8 --joints " + q, true).exit_code, 2);
  const CliRun both = run_cli("fk --robot panda --urdf '" + file.path + "' --joints " + q, true);
  EXPECT_EQ(both.exit_code, 2);
  EXPECT_THAT(both.out, HasSubstr("--robot NAME or --urdf FILE, not both"));
}

TEST(Cli, ConvertReadsStdin) {
  const CliRun run = run_cli("convert - < " + example_path("convert_table_5_10.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_THAT(run.out, HasSubstr("parametric constraints"));
  EXPECT_THAT(run.out, HasSubstr("-2.59804"));  // d2y of frame 2, Table 5.11
}

TEST(Cli, AnalyzeJsonHasTheRequestedPoints) {
  const CliRun run = run_cli("analyze --json " + example_path("analyze_demo_path_a.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto profile = from_json<v1::PathProfile>(run.out);
  EXPECT_EQ(profile.points_size(), 31);
}

TEST(Cli, BadRequestPrintsEachFieldViolation) {
  const CliRun run = run_cli("plan " + example_path("bad_request.json"), /*merge_stderr=*/true);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.out, HasSubstr("INVALID_ARGUMENT"));
  for (const char* line : {"  path.frames[0].tangent: ", "  path.frames[1].torsion: ", "  path.frames[2].tangent: ",
                           "  analysisPoints: "}) {
    EXPECT_THAT(run.out, HasSubstr(line));
  }
}

TEST(Cli, UnreadableRequestExitsWithUsageError) {
  const CliRun run = run_cli("plan -", /*merge_stderr=*/true, R"({"path": {"frames": 3}})");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.out, HasSubstr("geotraj.v1.PlanRequest"));
}

// CLI11's number checks compare, and NaN compares false with every bound: each
// floating-point flag is refused by name when it is not finite.
TEST(Cli, NonFiniteFlagValuesAreRefusedByName) {
  for (const std::string flag : {"--timeout nan", "--timeout inf", "--timeout -nan"}) {
    const CliRun run = run_cli(flag + " robots", /*merge_stderr=*/true);
    EXPECT_NE(run.exit_code, 0) << flag;
    EXPECT_THAT(run.out, HasSubstr("--timeout")) << flag;
    EXPECT_THAT(run.out, HasSubstr("not a finite number")) << flag;
  }
  for (const std::string args : {"execute --deadman nan x.json", "execute --override nan x.json",
                                 "jog --rate nan --script -", "plan --optimize-budget inf x.json"}) {
    const CliRun run = run_cli(args, /*merge_stderr=*/true);
    EXPECT_NE(run.exit_code, 0) << args;
    EXPECT_THAT(run.out, HasSubstr("not a finite number")) << args;
  }
}

// --- robots ---------------------------------------------------------------------------------

TEST(Cli, RobotsListsTheBuiltInModels) {
  const CliRun run = run_cli("robots");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_THAT(run.out, HasSubstr("pa10  (7 joints, MODIFIED DH)"));
  EXPECT_THAT(run.out, HasSubstr("ur5  (6 joints, STANDARD DH)"));
  EXPECT_THAT(run.out, HasSubstr("      0  S1             REVOLUTE"));
  EXPECT_THAT(run.out, HasSubstr("      5  wrist_3        REVOLUTE"));

  const CliRun json = run_cli("--json robots");
  ASSERT_EQ(json.exit_code, 0) << json.out;
  const auto robots = from_json<v1::ListRobotsResponse>(json.out);
  ASSERT_EQ(robots.robots_size(), 5);
  EXPECT_EQ(robots.robots(0).links_size() + robots.robots(1).links_size(), 13);
  EXPECT_EQ(robots.robots(2).joints_size(), 7);  // the Panda, from its URDF
  EXPECT_THAT(run.out, HasSubstr("panda  (7 joints, general chain)"));
  EXPECT_THAT(run.out, HasSubstr("      3  panda_joint4      REVOLUTE      0.0825    0.0000    0.0000  1.571  0.000  0.000"));
  // Joint names whole, the column as wide as the longest (the UR5e's).
  EXPECT_THAT(run.out, HasSubstr("      1  shoulder_lift_joint REVOLUTE"));
  // The in-process server logs only when asked: the output is the answer alone.
  const CliRun merged = run_cli("robots", /*merge_stderr=*/true);
  EXPECT_EQ(merged.out.find("INFO"), std::string::npos) << merged.out.substr(0, 300);

  // The URDF of a built-in arm, to start one's own from; a DH model has none.
  const CliRun urdf = run_cli("robots --urdf ur5e");
  ASSERT_EQ(urdf.exit_code, 0) << urdf.out;
  EXPECT_THAT(urdf.out, HasSubstr("<robot name=\"ur5e\">"));
  const CliRun none = run_cli("robots --urdf pa10", /*merge_stderr=*/true);
  EXPECT_EQ(none.exit_code, 2);
  EXPECT_THAT(none.out, HasSubstr("DH tables"));
}

// The fields of one CSV line.
std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream in(line);
  for (std::string field; std::getline(in, field, ',');) fields.push_back(field);
  return fields;
}

TEST(Cli, StreamOfARobotRequestHasJointColumns) {
  // A 3 s joint move of the PA-10 at 100 Hz (within its limits): 301 samples.
  const CliRun run = run_cli("stream -", /*merge_stderr=*/false,
                             R"({"jointMove": {"goal": [0.6, 0.9, -0.3, 1.5, 0.4, 0.6, -0.8]},
                                 "robot": {"name": "pa10"}, "motion": {"durationS": 3}})");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  std::stringstream out(run.out);
  std::string header;
  ASSERT_TRUE(std::getline(out, header));
  std::string expected = "t,u,s,segment,x,y,z,qw,qx,qy,qz,vx,vy,vz,ax,ay,az,speed,wx,wy,wz";
  for (const char* name : {"q", "qd", "qdd"}) {
    for (int j = 0; j < 7; ++j) expected += "," + std::string(name) + std::to_string(j);  // joint 0 at the base
  }
  EXPECT_EQ(header, expected);
  std::vector<std::string> last;
  int rows = 0;
  for (std::string line; std::getline(out, line); ++rows) {
    last = csv_fields(line);
    ASSERT_EQ(last.size(), 42u) << line;
  }
  EXPECT_EQ(rows, 301);
  ASSERT_EQ(last.size(), 42u);
  const double goal[7] = {0.6, 0.9, -0.3, 1.5, 0.4, 0.6, -0.8};
  for (int j = 0; j < 7; ++j) {
    EXPECT_EQ(std::stod(last[21 + j]), goal[j]) << "q" << j;  // %.17g: exact
    EXPECT_EQ(std::stod(last[28 + j]), 0.0) << "qd" << j;
  }
}

// A path with its approach move streams in two steps: the CSV has the `step` column, 0 for the
// approach and 1 for the path, as for a sequence.
TEST(Cli, AnApproachPlanHasTheStepColumn) {
  const CliRun run = run_cli("stream " + example_path("plan_panda_path_c.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out.substr(0, 300);
  std::stringstream out(run.out);
  std::string header;
  ASSERT_TRUE(std::getline(out, header));
  const auto columns = csv_fields(header);
  const auto at = std::find(columns.begin(), columns.end(), "step");
  ASSERT_NE(at, columns.end()) << header;
  const auto k = static_cast<std::size_t>(at - columns.begin());
  std::set<std::string> steps;
  for (std::string line; std::getline(out, line);) steps.insert(csv_fields(line).at(k));
  EXPECT_EQ(steps, (std::set<std::string>{"0", "1"}));
}

// The joint values of the last CSV row of a stream (columns q0..q6 after the 21 tool columns).
std::vector<double> last_joints(const std::string& csv) {
  std::stringstream out(csv);
  std::vector<std::string> last;
  for (std::string line; std::getline(out, line);) last = csv_fields(line);
  std::vector<double> q;
  for (std::size_t j = 21; j < 28 && j < last.size(); ++j) q.push_back(std::stod(last[j]));
  return q;
}

TEST(Cli, WaypointsFromMoveItAreAJointPathInTheRobotsJointOrder) {
  // A RobotTrajectory's joint_trajectory with the Panda's first two joints swapped.
  const std::string trajectory = R"({"joint_trajectory": {"joint_names": ["panda_joint2", "panda_joint1",
      "panda_joint3", "panda_joint4", "panda_joint5", "panda_joint6", "panda_joint7"],
      "points": [{"positions": [-0.785, 0.0, 0.0, -2.356, 0.0, 1.571, 0.785], "time_from_start": {"sec": 0}},
                 {"positions": [-0.45, 0.35, 0.1, -2.2, 0.05, 1.8, 1.1]},
                 {"positions": [-0.1, 0.42, 0.12, -2.35, 0.02, 2.25, 1.2]}]}})";
  const CliRun run = run_cli("stream --waypoints - --robot panda --blend-tolerance 0.05 --rate 100", false, trajectory);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_EQ(last_joints(run.out), (std::vector<double>{0.42, -0.1, 0.12, -2.35, 0.02, 2.25, 1.2}));
  // The same waypoints as text (a header of names, a comment, commas or spaces).
  const std::string text = "panda_joint2 panda_joint1 panda_joint3 panda_joint4 panda_joint5 panda_joint6 panda_joint7\n"
                           "# from the planner\n-0.785 0 0 -2.356 0 1.571 0.785\n-0.45, 0.35, 0.1, -2.2, 0.05, 1.8, 1.1\n"
                           "-0.1 0.42 0.12 -2.35 0.02 2.25 1.2\n";
  const CliRun plain = run_cli("stream --waypoints - --robot panda --blend-tolerance 0.05 --rate 100", false, text);
  ASSERT_EQ(plain.exit_code, 0) << plain.out;
  EXPECT_EQ(plain.out, run.out);
  // A request file gives the rest (here its robot and motion; its path is replaced).
  const CliRun planned = run_cli("plan --json --waypoints - --blend-tolerance 0 " + example_path("plan_joint_path_panda.json"),
                                 false, trajectory);
  ASSERT_EQ(planned.exit_code, 0) << planned.out;
  EXPECT_GT(from_json<v1::PlanResponse>(planned.out).motion().duration_s(), 0.0);
}

TEST(Cli, WaypointsThatCannotBeReadAreNamed) {
  CliRun run = run_cli("plan --waypoints - --robot panda", true, "a b\n1 2\n");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.out, HasSubstr("the waypoints name no joint 'panda_joint1' of the robot"));
  run = run_cli("plan --waypoints - --robot panda", true, "1 2 3\n4 5\n");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.out, HasSubstr("waypoint 1 has 2 values, the first 3"));
  run = run_cli("plan --waypoints - --robot panda", true, R"({"points": [{"velocities": [1]}]})");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.out, HasSubstr("points[0].positions is not an array of numbers"));
  // Read, and refused by the service by field: 3 values for 7 joints.
  run = run_cli("plan --waypoints - --robot panda", true, "[[0, 0, 0], [1, 1, 1]]");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.out, HasSubstr("jointPath.waypoints[0].positions"));
}

TEST(Cli, PlanWithAReportOnlyRobotPrintsTheJointTable) {
  // Path C in the thesis's 10 s is too fast for the PA-10; the example asks for the report.
  const CliRun run = run_cli("plan " + example_path("plan_pa10_path_c.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_THAT(run.out, HasSubstr("robot pa10: 1001 samples, LIMITS BROKEN"));
  EXPECT_THAT(run.out, HasSubstr("joint     min q       max q"));
  EXPECT_THAT(run.out, HasSubstr("tightest acceleration: ACCELERATION"));
  EXPECT_THAT(run.out, HasSubstr("VIOLATION ACCELERATION"));
}

TEST(Cli, RobotThatCannotFollowFailsWithFailedPrecondition) {
  std::string request = example_text("plan_pa10_path_c.json");
  const std::string report_only = "\"reportOnly\": true";
  const auto at = request.find(report_only);
  ASSERT_NE(at, std::string::npos);
  request.replace(at, report_only.size(), "\"reportOnly\": false");
  const CliRun run = run_cli("plan -", /*merge_stderr=*/true, request);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.out, HasSubstr("FAILED_PRECONDITION"));
  EXPECT_THAT(run.out, HasSubstr("robot 'pa10' cannot follow the plan: joint"));
}

// Every robot example file beside examples.sh plans with the CLI.
TEST(Cli, RobotExamplesPlan) {
  for (const auto& [file, robot] : {std::pair<std::string, std::string>{"plan_pa10_path_c.json", "pa10"},
                                    {"joint_move_pa10.json", "pa10"},
                                    {"linear_move_ur5.json", "ur5"},
                                    {"sequence_ur5.json", "ur5"},
                                    {"sequence_blended_ur5.json", "ur5"},
                                    {"plan_panda_path_c.json", "panda"}}) {
    const CliRun run = run_cli("plan " + example_path(file), /*merge_stderr=*/true);
    EXPECT_EQ(run.exit_code, 0) << file << "\n" << run.out;
    EXPECT_THAT(run.out, HasSubstr("robot " + robot + ": ")) << file;
  }
}

// The --optimize-* flags fill the request's `optimize` block: the time-optimal PA-10 plan
// prints which limit binds where and is within every limit; a tangent-scale objective by
// name; an unknown objective name is a usage error (exit 2) that names it.
TEST(Cli, OptimizeFlagsFillTheRequest) {
  std::string request = example_text("plan_pa10_path_c.json");
  const std::string duration = "\"durationS\": 10";
  const auto at = request.find(duration);
  ASSERT_NE(at, std::string::npos) << request;
  request.replace(at, duration.size(), "\"durationS\": 0");
  CliRun run = run_cli("plan --time-optimal -", /*merge_stderr=*/true, request);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_THAT(run.out, HasSubstr("timing          CONVERGED"));
  EXPECT_THAT(run.out, HasSubstr("the most used limit, stretch by stretch (binding: at 100 %):"));
  EXPECT_THAT(run.out, HasSubstr("  binding\n")) << "a time-optimal timing has a limit at 100 % somewhere";
  // About 5.4 s at 100 Hz against the fixed 10 s.
  EXPECT_THAT(run.out, ::testing::ContainsRegex("robot pa10: 5[0-9][0-9] samples, within every limit"));
  EXPECT_THAT(run.out, HasSubstr("limits checked at 2000 Hz"));
  // Half the joint speeds: about twice the time.
  run = run_cli("plan --json --time-optimal --velocity-scale 0.5 --acceleration-scale 0.25 -", false, request);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_GT(from_json<v1::PlanResponse>(run.out).motion().duration_s(), 9.0);
  run = run_cli("plan --velocity-scale 2 -", true, request);
  EXPECT_EQ(run.exit_code, 1) << run.out;  // the server's INVALID_ARGUMENT
  EXPECT_THAT(run.out, HasSubstr("robot.velocityScale"));
  run = run_cli("plan --velocity-scale 0.5 " + example_path("plan_demo_path_a.json"), true);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.out, HasSubstr("the request has no robot"));

  run = run_cli("plan --unspecified lowest-degree --optimize-tangent-scales arc-length " +
                example_path("plan_demo_path_a.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_THAT(run.out, HasSubstr("tangent scales  CONVERGED"));

  // Under the default reading, with the length weight given or by default (E0 / L0, printed).
  run = run_cli("plan --json --optimize-tangent-scales bending-energy --length-weight 0 " +
                example_path("plan_demo_path_a.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto unweighted = from_json<v1::PlanResponse>(run.out);
  EXPECT_EQ(unweighted.optimization().tangent_scales().length_weight(), 0.0);
  run = run_cli("plan --json --optimize-tangent-scales bending-energy " + example_path("plan_demo_path_a.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto weighted = from_json<v1::PlanResponse>(run.out);
  EXPECT_GT(weighted.optimization().tangent_scales().length_weight(), 0.0);
  EXPECT_LT(weighted.arc_length(), unweighted.arc_length()) << "the weight keeps the length in check";
  run = run_cli("plan --optimize-tangent-scales bending-energy " + example_path("plan_demo_path_a.json"));
  EXPECT_THAT(run.out, HasSubstr("; length weight"));
  run = run_cli("plan --length-weight 2 " + example_path("plan_demo_path_a.json"), true);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.out, HasSubstr("--length-weight needs --optimize-tangent-scales"));

  run = run_cli("plan --optimize-breakpoints flattest " + example_path("appendix_b_uniform.json"), true);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.out, HasSubstr("unknown value 'flattest'"));
}

// fk and ik from flags: the pose fk prints is one ik solves, back to the same joints when
// seeded with them; a pose out of reach exits 3 with the closest pose; bad flags exit 2.
TEST(Cli, ForwardAndInverseKinematicsRoundTrip) {
  const std::string joints = "0.3,-1.2,1.4,-0.8,1.1,0.5";
  CliRun run = run_cli("--json fk --robot ur5 --joints " + joints);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto fk = from_json<v1::ForwardKinematicsResponse>(run.out);
  EXPECT_TRUE(fk.within_limits());
  EXPECT_EQ(fk.jacobian_size(), 36);
  const auto& p = fk.pose().position();
  const auto& q = fk.pose().orientation();
  char target[256];
  std::snprintf(target, sizeof target, "--position %.17g,%.17g,%.17g --orientation %.17g,%.17g,%.17g,%.17g", p.x(),
                p.y(), p.z(), q.w(), q.x(), q.y(), q.z());
  run = run_cli("--json ik --robot ur5 --restarts 0 --seed " + joints + " " + target);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto ik = from_json<v1::InverseKinematicsResponse>(run.out);
  ASSERT_TRUE(ik.reachable());
  const std::vector<double> expected = {0.3, -1.2, 1.4, -0.8, 1.1, 0.5};
  ASSERT_EQ(ik.solutions(0).joints_size(), 6);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(ik.solutions(0).joints(i), expected[static_cast<std::size_t>(i)], 1e-6);

  run = run_cli("ik --robot ur5 --all " + std::string(target));
  EXPECT_EQ(run.exit_code, 0) << run.out;
  EXPECT_THAT(run.out, HasSubstr("8 solutions"));
  run = run_cli("ik --robot ur5 --position 2,0,0.5");
  EXPECT_EQ(run.exit_code, 3) << run.out;
  EXPECT_THAT(run.out, HasSubstr("out of reach"));
  run = run_cli("ik --robot ur5 --position 2,0", true);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.out, HasSubstr("--position takes x,y,z"));
  run = run_cli("fk --robot ur5 --joints 0,0", true);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.out, HasSubstr("joints: has 2 values for a 6-joint robot"));
}

// The same CLI against a server on a loopback port.
class CliRemote : public ServerTest {};

TEST_F(CliRemote, TalksToTheServerAndChecksHealth) {
  const CliRun plan = run_cli("--server " + address_ + " plan --json " + example_path("plan_demo_path_c.json"));
  ASSERT_EQ(plan.exit_code, 0) << plan.out;
  EXPECT_EQ(from_json<v1::PlanResponse>(plan.out).segments_size(), 3);

  const CliRun health = run_cli("--server " + address_ + " health");
  EXPECT_EQ(health.exit_code, 0);
  EXPECT_EQ(health.out, "SERVING\n");
}

// --token-file sends the token the file holds (its first line), not the file's name.
TEST(Cli, TokenFileSendsItsToken) {
  server::ServerOptions options;
  options.address = "127.0.0.1:0";
  options.log_level = "warning";
  options.auth_token = "file-token-0123456789abcdef";
  auto running = server::start_server(options);
  ASSERT_TRUE(running) << running.error();
  const std::string dir = ::testing::TempDir();
  const std::string good = dir + "/geotraj_token_good", empty = dir + "/geotraj_token_empty";
  std::FILE* f = std::fopen(good.c_str(), "w");
  std::fputs("file-token-0123456789abcdef\n", f);
  std::fclose(f);
  std::fclose(std::fopen(empty.c_str(), "w"));
  const std::string server = "--server 127.0.0.1:" + std::to_string(running->port);
  CliRun run = run_cli(server + " --token-file " + good + " robots", true);
  EXPECT_EQ(run.exit_code, 0) << run.out;
  EXPECT_THAT(run.out, HasSubstr("pa10"));
  run = run_cli(server + " --token-file " + empty + " robots", true);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.out, HasSubstr("holds no token"));
  run = run_cli(server + " --token-file " + dir + "/no_such_file robots", true);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_THAT(run.out, HasSubstr("cannot read"));
  server::stop_server(*running, std::chrono::seconds(1));
  std::remove(good.c_str());
  std::remove(empty.c_str());
}

TEST(Cli, UnreachableServerFails) {
  // Port 1 on loopback: nothing listens there in a test environment.
  const CliRun run = run_cli("--server 127.0.0.1:1 --timeout 5 health", /*merge_stderr=*/true);
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.out, HasSubstr("UNAVAILABLE"));
}

}  // namespace
}  // namespace geotraj::testing
