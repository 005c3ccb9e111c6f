// `geotraj plot` run as a subprocess on the example requests: the figures it writes and what
// a reader checks in them (axis labels with units, one marker per key frame, the joint
// limits drawn, an acceleration beyond its limit written out, which limit binds), its errors
// (a bad request names the field, an unreadable file, no Python, no matplotlib, no module),
// in process and against a server on a loopback port.
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gmock/gmock.h>

#include "tests/client/cli_support.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

// Runs the CLI with `args` (shell words) after the environment assignments `env` (shell
// words too), stdout and stderr captured together.
CliRun run_cli(const std::string& args, const std::string& env = "") {
  const std::string command = env + (env.empty() ? "" : " ") + "'" + build_paths::cli() + "' " + args + " 2>&1";
  return run_shell(command);
}

std::string example_path(const std::string& name) {
  return std::string("'") + build_paths::examples_dir() + "/" + name + "'";
}

std::string read_file(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
  return n;
}

// A fresh output directory per test, removed afterwards.
class CliPlot : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string templ = (fs::temp_directory_path() / "geotraj-cli-plot-XXXXXX").string();
    ASSERT_NE(::mkdtemp(templ.data()), nullptr);
    dir_ = templ;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string out_flag() const { return "-o '" + dir_.string() + "'"; }
  fs::path dir_;
};

TEST_F(CliPlot, Pa10PathCDrawsThePathItsGeometrySpeedAndJointsAgainstTheirLimits) {
  const CliRun run = run_cli("plot " + out_flag() + " " + example_path("plan_pa10_path_c.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  for (const char* figure : {"path", "geometry", "speed", "joints"}) {
    const fs::path file = dir_ / (std::string("plan_pa10_path_c_") + figure + ".svg");
    EXPECT_THAT(run.out, HasSubstr("wrote " + file.string() + "\n"));
    EXPECT_TRUE(fs::exists(file)) << file;
  }
  EXPECT_FALSE(fs::exists(dir_ / "plan_pa10_path_c_binding.svg"));  // a fixed 10 s, not time-optimal

  // The path: coordinates in metres, one marker per key frame (4) in each of the 3 views,
  // the cusp (frames[2]) named.
  const std::string path = read_file(dir_ / "plan_pa10_path_c_path.svg");
  for (const char* label : {"x [m]", "y [m]", "z [m]", "top view (x-y)", "side view (x-z)", "2 (cusp)"}) {
    EXPECT_THAT(path, HasSubstr(label));
  }
  for (const char* view : {"3d", "top", "side"}) {
    EXPECT_EQ(count(path, std::string("id=\"keyframe-") + view + "-"), 4u) << view;
    EXPECT_THAT(path, HasSubstr(std::string("id=\"keyframe-") + view + "-3\""));
  }
  EXPECT_THAT(path, Not(HasSubstr("<dc:date>")));  // reproducible: no date

  // The geometry along s, with units; a vertical line per key frame.
  const std::string geometry = read_file(dir_ / "plan_pa10_path_c_geometry.svg");
  for (const char* label : {"arc length s [m]", "κ [1/m]", "τ [1/m]", "dκ/ds [1/m²]", "dτ/ds [1/m²]"}) {
    EXPECT_THAT(geometry, HasSubstr(label));
  }
  EXPECT_EQ(count(geometry, "id=\"keyframe-kappa-"), 4u);

  const std::string speed = read_file(dir_ / "plan_pa10_path_c_speed.svg");
  EXPECT_THAT(speed, HasSubstr("speed [m/s]"));
  EXPECT_THAT(speed, HasSubstr("time t [s]"));

  // The joints: the PA-10's seven joints, each with its position, velocity and acceleration
  // limits; the 100 % lines; path C at 10 s breaks an acceleration limit (reportOnly), and
  // the figure says so.
  const std::string joints = read_file(dir_ / "plan_pa10_path_c_joints.svg");
  for (const char* label : {"q [rad]", "q̇ [rad/s]", "q̈ [rad/s²]", "time t [s]", "of limit [%]"}) {
    EXPECT_THAT(joints, HasSubstr(label));
  }
  for (int j = 0; j < 7; ++j) {
    for (const char* key : {"q", "qd", "qdd"}) {
      for (const char* side : {"min", "max"}) {
        EXPECT_THAT(joints, HasSubstr("id=\"limit-" + std::string(key) + "-j" + std::to_string(j) + "-" + side + "\""));
      }
    }
  }
  EXPECT_EQ(count(joints, "id=\"limit-qdd-j"), 14u);
  EXPECT_THAT(joints, HasSubstr("id=\"limit-qdd-usage-max\""));
  EXPECT_THAT(joints, HasSubstr("id=\"peak-qdd\""));
  EXPECT_THAT(joints, HasSubstr("beyond its limit"));
}

TEST_F(CliPlot, TimeOptimalAddsWhichLimitBinds) {
  const CliRun run =
      run_cli("plot --time-optimal --name topt " + out_flag() + " " + example_path("plan_pa10_path_c.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const std::string binding = read_file(dir_ / "topt_binding.svg");
  EXPECT_THAT(binding, HasSubstr("id=\"binding-0\""));
  EXPECT_THAT(binding, HasSubstr("acceleration"));
  EXPECT_THAT(binding, HasSubstr("value / limit [%]"));
  EXPECT_THAT(binding, HasSubstr("time t [s]"));
  // Within every limit now: the joint figure says so.
  const std::string joints = read_file(dir_ / "topt_joints.svg");
  EXPECT_THAT(joints, HasSubstr("within its limit"));
  EXPECT_THAT(joints, Not(HasSubstr("beyond its limit")));
}

TEST_F(CliPlot, APathWithoutARobotHasNoJointFigure) {
  const CliRun run = run_cli("plot " + out_flag() + " " + example_path("plan_demo_path_c.json"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  for (const char* figure : {"path", "geometry", "speed"}) {
    EXPECT_TRUE(fs::exists(dir_ / (std::string("plan_demo_path_c_") + figure + ".svg"))) << figure;
  }
  EXPECT_FALSE(fs::exists(dir_ / "plan_demo_path_c_joints.svg"));
  const std::string path = read_file(dir_ / "plan_demo_path_c_path.svg");
  EXPECT_EQ(count(path, "id=\"keyframe-top-"), 4u);
}

// Without a robot, a path timed by the tool's limits has a binding figure too: the tool's
// limits measured on the samples (PlanResponse.motion.binding), the speed limit binding.
TEST_F(CliPlot, APathTimedByTheToolsLimitsWithoutARobotDrawsWhatBinds) {
  std::string request = read_file(build_paths::examples_dir() + std::string("/plan_demo_path_a.json"));
  const std::string timed = "\"durationS\": 10,";
  ASSERT_NE(request.find(timed), std::string::npos);
  request.replace(request.find(timed), timed.size(), "\"durationS\": 0, \"maxSpeed\": 0.05, \"maxAcceleration\": 0.5,");
  const fs::path file = dir_ / "path_a_by_speed.json";
  std::ofstream(file) << request;
  const CliRun run = run_cli("plot " + out_flag() + " '" + file.string() + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const fs::path figure = dir_ / "path_a_by_speed_binding.svg";
  ASSERT_TRUE(fs::exists(figure)) << run.out;
  const std::string svg = read_file(figure);
  EXPECT_THAT(svg, HasSubstr("id=\"binding-0\""));
  EXPECT_THAT(svg, HasSubstr("speed"));
}

TEST_F(CliPlot, BadRequestNamesTheFieldsAndDrawsNothing) {
  const CliRun run = run_cli("plot " + out_flag() + " " + example_path("bad_request.json"));
  EXPECT_EQ(run.exit_code, 1) << run.out;
  EXPECT_THAT(run.out, HasSubstr("INVALID_ARGUMENT"));
  EXPECT_THAT(run.out, HasSubstr("  path.frames[1].torsion: "));
  EXPECT_TRUE(fs::is_empty(dir_));
}

TEST_F(CliPlot, UnreadableRequestIsAUsageError) {
  CliRun run = run_cli("plot " + out_flag() + " '" + (dir_ / "no_such_request.json").string() + "'");
  EXPECT_EQ(run.exit_code, 2) << run.out;
  EXPECT_THAT(run.out, HasSubstr("cannot read"));
  EXPECT_THAT(run.out, HasSubstr("no_such_request.json"));
  const fs::path broken = dir_ / "broken.json";
  std::ofstream(broken) << R"({"path": {"frames": 3}})";
  run = run_cli("plot " + out_flag() + " '" + broken.string() + "'");
  EXPECT_EQ(run.exit_code, 2) << run.out;
  EXPECT_THAT(run.out, HasSubstr("geotraj.v1.PlanRequest"));
}

TEST_F(CliPlot, MissingPythonOrMatplotlibNamesTheDebianPackage) {
  // No interpreter at all.
  CliRun run = run_cli("plot " + out_flag() + " " + example_path("plan_demo_path_a.json"),
                       "GEOTRAJ_PYTHON='" + (dir_ / "no_python3").string() + "'");
  EXPECT_EQ(run.exit_code, 1) << run.out;
  EXPECT_THAT(run.out, HasSubstr("cannot run"));
  EXPECT_THAT(run.out, HasSubstr("python3-matplotlib"));

  // A Python 3 without matplotlib: Debian's, without its site packages (-S).
  if (::access("/usr/bin/python3", X_OK) != 0) GTEST_SKIP() << "no /usr/bin/python3";
  const fs::path bare = dir_ / "bare_python3";
  std::ofstream(bare) << "#!/bin/sh\nexec /usr/bin/python3 -S \"$@\"\n";
  fs::permissions(bare, fs::perms::owner_all);
  const fs::path out = dir_ / "figures";
  run = run_cli("plot -o '" + out.string() + "' " + example_path("plan_demo_path_a.json"),
                "GEOTRAJ_PYTHON='" + bare.string() + "'");
  EXPECT_EQ(run.exit_code, 1) << run.out;
  EXPECT_THAT(run.out, HasSubstr("has no matplotlib"));
  EXPECT_THAT(run.out, HasSubstr("apt-get install -y python3-matplotlib"));
}

TEST_F(CliPlot, TheModuleCanBeNamedAndAMissingOneIsSaid) {
  const std::string missing = (dir_ / "nowhere" / "geotraj_plot.py").string();
  CliRun run = run_cli("plot --plot-module '" + missing + "' " + out_flag() + " " +
                       example_path("plan_demo_path_a.json"));
  EXPECT_EQ(run.exit_code, 1) << run.out;
  EXPECT_THAT(run.out, HasSubstr(missing));
  EXPECT_THAT(run.out, HasSubstr("--plot-module"));
  // The source tree's module, by the environment variable.
  run = run_cli("plot --name a " + out_flag() + " " + example_path("plan_demo_path_a.json"),
                std::string("GEOTRAJ_PLOT_MODULE='") + build_paths::source_dir() + "/scripts/geotraj_plot.py'");
  EXPECT_EQ(run.exit_code, 0) << run.out;
  EXPECT_TRUE(fs::exists(dir_ / "a_path.svg"));
}

// The same against a server on a loopback port: the robot model comes from its ListRobots.
class CliPlotRemote : public ServerTest {};

TEST_F(CliPlotRemote, DrawsThroughAServer) {
  std::string templ = (fs::temp_directory_path() / "geotraj-cli-plot-XXXXXX").string();
  ASSERT_NE(::mkdtemp(templ.data()), nullptr);
  const fs::path dir = templ;
  const CliRun run = run_cli("--server " + address_ + " plot -o '" + dir.string() + "' " +
                             example_path("plan_pa10_path_c.json"));
  EXPECT_EQ(run.exit_code, 0) << run.out;
  const std::string joints = read_file(dir / "plan_pa10_path_c_joints.svg");
  EXPECT_THAT(joints, HasSubstr("id=\"limit-qdd-j6-max\""));
  std::error_code ec;
  fs::remove_all(dir, ec);
}

}  // namespace
}  // namespace geotraj::testing
