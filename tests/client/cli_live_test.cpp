// The live subcommands of the `geotraj` CLI (execute, jog) run as subprocesses against a
// server on a loopback port: scripted speed override, pause, resume and stop; script errors
// named by line before any call; joint jogging to rest and against a position limit. Script
// times are the motion's own (Sample.t), so what the tests check does not hang on the wall
// clock; they check states and values, never durations.
#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>

#include "tests/client/cli_support.hpp"
#include "tests/server/support/test_server.hpp"

namespace geotraj::testing {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

// Runs the CLI with `args` (shell words), `stdin_text` (no single quotes) on its standard
// input when given, and captures its output (as cli_test.cpp does).
CliRun run_cli(const std::string& args, bool merge_stderr = false, const std::string& stdin_text = "") {
  const std::string feed = stdin_text.empty() ? "" : "printf '%s' '" + stdin_text + "' | ";
  // Without input, /dev/null: never the test's own stdin (a terminal would make execute
  // interactive).
  const std::string command = feed + "'" + build_paths::cli() + "' " + args + (stdin_text.empty() ? " < /dev/null" : "") +
                              (merge_stderr ? " 2>&1" : " 2>/dev/null");
  return run_shell(command);
}

std::string example_path(const std::string& name) { return std::string("'") + build_paths::examples_dir() + "/" + name + "'"; }

// Writes `text` to a file in the test's temporary directory; its path (with the process id:
// test programs running at once do not share it).
std::string write_file(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "/" + std::to_string(::getpid()) + "_" + name;
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fputs(text.c_str(), f);
  std::fclose(f);
  return path;
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::stringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream in(line);
  for (std::string field; std::getline(in, field, ',');) fields.push_back(field);
  return fields;
}

// The CSV output as rows of named columns.
struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  int column(const std::string& name) const {
    const auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? -1 : static_cast<int>(it - header.begin());
  }
  double number(std::size_t row, const std::string& name) const {
    return std::stod(rows[row][static_cast<std::size_t>(column(name))]);
  }
  const std::string& text(std::size_t row, const std::string& name) const {
    return rows[row][static_cast<std::size_t>(column(name))];
  }
};

Csv parse_csv(const std::string& out) {
  Csv csv;
  const auto lines = lines_of(out);
  if (lines.empty()) return csv;
  csv.header = csv_fields(lines[0]);
  for (std::size_t i = 1; i < lines.size(); ++i) csv.rows.push_back(csv_fields(lines[i]));
  return csv;
}

// The runs of equal values, in order (RUNNING, RUNNING, PAUSING -> RUNNING, PAUSING).
std::vector<std::string> runs(const Csv& csv, const std::string& column) {
  std::vector<std::string> out;
  for (std::size_t r = 0; r < csv.rows.size(); ++r) {
    if (out.empty() || out.back() != csv.text(r, column)) out.push_back(csv.text(r, column));
  }
  return out;
}

// The tests give a deadman of 5 s (heartbeats every 1.25 s) so that a loaded machine (the
// sanitizer builds, ctest -j) does not trip it; HeartbeatsOutlastTheDeadman checks that the
// heartbeats keep a call alive for several deadman times.
class CliLive : public ServerTest {
 protected:
  std::string server() const { return "--server " + address_ + " "; }
};

// Path C on the Panda at 1 kHz, its speed halved at 0.5 s, paused at 1 s, resumed at 1.5 s
// and stopped at 2 s: the states in that order, the plan time never going back, the speed
// factor back at the override (not the plan's full speed) after the resume, and a final
// sample at rest.
// Where the acceleration reserve changes the timing (the Panda's path C, timed by its limits,
// and its joint approach), execute says so on stderr at the start; with --acceleration-reserve
// 0.3 it names that reserve.
TEST_F(CliLive, ExecuteSaysWhereTheReserveChangesTheTiming) {
  const std::string script = write_file("geotraj_execute_reserve.txt", "0.2 stop\n");
  CliRun run = run_cli(server() + "execute " + example_path("plan_panda_path_c.json") + " --deadman 5 --script " +
                           script,
                       /*merge_stderr=*/true);
  ASSERT_EQ(run.exit_code, 0) << run.out.substr(0, 2000);
  EXPECT_THAT(run.out, HasSubstr("geotraj: execute: acceleration reserve 0.1: the motions the limits time"));
  EXPECT_THAT(run.out, HasSubstr("motion.accelerationScale x 0.9"));
  run = run_cli(server() + "execute " + example_path("plan_panda_path_c.json") +
                    " --deadman 5 --acceleration-reserve 0.3 --script " + script,
                /*merge_stderr=*/true);
  ASSERT_EQ(run.exit_code, 0) << run.out.substr(0, 2000);
  EXPECT_THAT(run.out, HasSubstr("geotraj: execute: acceleration reserve 0.3: "));
  EXPECT_THAT(run.out, HasSubstr("keep 30 % of every acceleration and jerk limit"));
}

TEST_F(CliLive, ExecuteFollowsItsScript) {
  const std::string script = write_file("geotraj_execute_script.txt",
                                        "# override, pause, resume, stop\n"
                                        "0.5 override 50\n"
                                        "1.0 pause   # slow to rest on the path\n"
                                        "1.5 resume\n"
                                        "\n"
                                        "2.0 stop\n");
  const CliRun run =
      run_cli(server() + "execute " + example_path("plan_panda_path_c.json") + " --deadman 5 --script " + script);
  ASSERT_EQ(run.exit_code, 0) << run.out.substr(0, 2000);
  const Csv csv = parse_csv(run.out);
  // The approach move and the path: a `step` column; the Panda's torques (mass properties).
  std::string expected = "t,u,s,segment,x,y,z,qw,qx,qy,qz,vx,vy,vz,ax,ay,az,speed,wx,wy,wz,step";
  for (const char* name : {"q", "qd", "qdd", "tau"}) {
    for (int j = 0; j < 7; ++j) expected += "," + std::string(name) + std::to_string(j);
  }
  expected += ",plan_time,speed_factor,state";
  ASSERT_EQ(lines_of(run.out).front(), expected);
  ASSERT_GT(csv.rows.size(), 100u);
  for (const auto& row : csv.rows) ASSERT_EQ(row.size(), csv.header.size());

  EXPECT_THAT(runs(csv, "state"),
              ::testing::ElementsAre("RUNNING", "PAUSING", "PAUSED", "RUNNING", "STOPPING", "STOPPED"));
  double previous = -1.0;
  for (std::size_t r = 0; r < csv.rows.size(); ++r) {
    const double plan_time = csv.number(r, "plan_time");
    ASSERT_GE(plan_time, previous) << "row " << r;
    previous = plan_time;
  }
  EXPECT_GT(csv.number(csv.rows.size() - 1, "plan_time"), csv.number(0, "plan_time"));

  // Before the pause the override has slowed the motion; after the resume it runs at the
  // override, never at the plan's own speed.
  std::size_t r = 0;
  double slowest_before_pause = 1.0;
  for (; csv.text(r, "state") == "RUNNING"; ++r) {
    slowest_before_pause = std::min(slowest_before_pause, csv.number(r, "speed_factor"));
  }
  EXPECT_LT(slowest_before_pause, 1.0);
  for (; csv.text(r, "state") != "RUNNING"; ++r) {
  }
  for (; csv.text(r, "state") == "RUNNING"; ++r) EXPECT_LE(csv.number(r, "speed_factor"), 0.5 + 1e-12) << "row " << r;

  const std::size_t last = csv.rows.size() - 1;
  EXPECT_EQ(csv.text(last, "state"), "STOPPED");
  EXPECT_EQ(csv.number(last, "speed_factor"), 0.0);
  EXPECT_EQ(csv.number(last, "speed"), 0.0);
  for (int j = 0; j < 7; ++j) EXPECT_EQ(csv.number(last, "qd" + std::to_string(j)), 0.0) << "qd" << j;
  EXPECT_LT(csv.number(last, "plan_time"), csv.number(last, "t")) << "the pause and the override took time";
}

// --json: one SampleBatch per line, each with its live status; a script from stdin.
TEST_F(CliLive, ExecuteJsonLinesAreSampleBatches) {
  const CliRun run = run_cli(server() + "--json execute " + example_path("plan_panda_path_c.json") +
                                 " --override 80 --deadman 5 --script -",
                             false, "0.3 stop\n");
  ASSERT_EQ(run.exit_code, 0) << run.out.substr(0, 2000);
  const auto lines = lines_of(run.out);
  ASSERT_GT(lines.size(), 2u);
  double previous_t = -1.0;
  for (const auto& line : lines) {
    const auto batch = from_json<v1::SampleBatch>(line);
    ASSERT_GT(batch.samples_size(), 0) << line;
    EXPECT_EQ(batch.live().speed_override(), 80.0);
    EXPECT_GT(batch.live().plan_duration_s(), 0.0);
    for (const auto& s : batch.samples()) {
      EXPECT_GT(s.t(), previous_t);
      previous_t = s.t();
      EXPECT_TRUE(s.has_plan_time());
      EXPECT_TRUE(s.has_speed_factor());
    }
  }
  const auto last = from_json<v1::SampleBatch>(lines.back());
  EXPECT_EQ(last.live().state(), v1::LIVE_STATE_STOPPED);
  EXPECT_EQ(last.samples(last.samples_size() - 1).speed_factor(), 0.0);
}

// Every bad line is named (the script's name, the line's number and text) and the call is
// not made: the server given does not exist, and no UNAVAILABLE is printed.
TEST(CliLiveScript, BadScriptLinesAreNamedBeforeTheCall) {
  const std::string script = write_file("geotraj_bad_execute_script.txt",
                                        "0.5 override 50\n"
                                        "# a comment\n"
                                        "1.0 faster\n"
                                        "1.5 override 120\n"
                                        "1.2 pause\n"
                                        "2 stop\n"
                                        "3 resume\n");
  const CliRun run = run_cli("--server 127.0.0.1:1 --timeout 5 execute " + example_path("plan_panda_path_c.json") +
                                 " --script " + script,
                             /*merge_stderr=*/true);
  EXPECT_EQ(run.exit_code, 2) << run.out;
  EXPECT_THAT(run.out, HasSubstr("line 3: unknown command \"faster\""));
  EXPECT_THAT(run.out, HasSubstr("line 4: override takes one percentage in [0, 100]: `1.5 override 120`"));
  EXPECT_THAT(run.out, HasSubstr("line 5: the time 1.2 s is before the previous line's"));
  EXPECT_THAT(run.out, HasSubstr("line 7: comes after the stop on line 6"));
  EXPECT_THAT(run.out, Not(HasSubstr("line 1:")));
  EXPECT_THAT(run.out, Not(HasSubstr("UNAVAILABLE")));

  const CliRun jog = run_cli("--server 127.0.0.1:1 --timeout 5 jog --robot panda --script -", true,
                             "0 joints 0.5 0 0\n0.5 joints 0.5 0\n1 twist base 1 0 0 0 0 0\n2 joints 2 0 0\n");
  EXPECT_EQ(jog.exit_code, 2) << jog.out;
  EXPECT_THAT(jog.out, HasSubstr("script (standard input), line 2: joints has 2 values, but line 1 has 3"));
  EXPECT_THAT(jog.out, HasSubstr("line 3: twist takes a frame (world or tool)"));
  EXPECT_THAT(jog.out, HasSubstr("line 4: value 1 \"2\" is not a fraction of the maximum in [-1, 1]"));
  EXPECT_THAT(jog.out, Not(HasSubstr("UNAVAILABLE")));
}

// A joint jog, then a stop: the joint moved, and the last set point is at rest.
TEST_F(CliLive, JogJointsThenStop) {
  const std::string script = write_file("geotraj_jog_script.txt",
                                        "0 joints 0.5 0 0 0 0 0 0   # joint 0 at half the jog speed\n"
                                        "0.5 stop\n");
  const CliRun run = run_cli(server() + "jog --deadman 5 --robot panda --script " + script);
  ASSERT_EQ(run.exit_code, 0) << run.out.substr(0, 2000);
  const Csv csv = parse_csv(run.out);
  ASSERT_GT(csv.rows.size(), 10u);
  for (const char* column : {"t", "q0", "q6", "qd0", "x", "y", "z", "damping", "sigma_min", "limited0", "state"}) {
    EXPECT_GE(csv.column(column), 0) << column;
  }
  const std::size_t last = csv.rows.size() - 1;
  EXPECT_EQ(csv.text(last, "state"), "STOPPED");
  for (int j = 0; j < 7; ++j) EXPECT_EQ(csv.number(last, "qd" + std::to_string(j)), 0.0) << "qd" << j;
  EXPECT_GT(csv.number(last, "q0"), csv.number(0, "q0"));
  for (int j = 1; j < 7; ++j) {
    EXPECT_EQ(csv.number(last, "q" + std::to_string(j)), csv.number(0, "q" + std::to_string(j))) << "q" << j;
  }
  EXPECT_THAT(runs(csv, "state"), ::testing::ElementsAre("JOGGING", "STOPPING", "STOPPED"));
}

// Joint 3 of the Panda jogged at full speed toward its upper limit: it brakes and comes to
// rest exactly there (reported in live.limitedJoints), never past it; the stop then ends
// the call at rest. A script without a stop is stopped at its last line's time.
TEST_F(CliLive, JogAgainstALimitStopsAtTheLimit) {
  const v1::RobotModel panda = robot_model("panda");
  ASSERT_EQ(panda.limits_size(), 7);
  const double q3_max = panda.limits(3).max_position();
  const std::string script = write_file("geotraj_jog_limit.txt", "0 joints 0 0 0 1 0 0 0\n2 joints 0 0 0 1 0 0 0\n");
  const CliRun run = run_cli(server() +
                             "--json jog --deadman 5 --robot panda --joints 0,-0.785398,0,-0.5,0,1.570796,0.785398 "
                             "--velocity-scale 0.5 --script " + script);
  ASSERT_EQ(run.exit_code, 0) << run.out.substr(0, 2000);
  bool limited = false;
  v1::Sample last;
  for (const auto& line : lines_of(run.out)) {
    const auto batch = from_json<v1::SampleBatch>(line);
    for (std::uint32_t j : batch.live().limited_joints()) limited = limited || j == 3;
    for (const auto& s : batch.samples()) {
      ASSERT_EQ(s.joints_size(), 7);
      EXPECT_LE(s.joints(3), q3_max) << "t " << s.t();
      last = s;
    }
  }
  EXPECT_TRUE(limited) << "joint 3 was never reported at its limit";
  EXPECT_EQ(last.joints(3), q3_max);
  for (int j = 0; j < 7; ++j) EXPECT_EQ(last.joint_velocities(j), 0.0) << "qd" << j;

  const CliRun warned =
      run_cli(server() + "jog --deadman 5 --robot panda --script -", true, "0.1 joints 0 0 0 0 0 0 0\n");
  EXPECT_EQ(warned.exit_code, 0) << warned.out;
  EXPECT_THAT(warned.out, HasSubstr("does not end with a stop: stopping at 0.1 s"));
}

// The script's joint count is checked against the robot's once its first sample is in: the
// line is named, the jog is stopped, exit 2.
TEST_F(CliLive, JogWithTheWrongJointCountNamesTheLine) {
  const CliRun run = run_cli(server() + "jog --deadman 5 --robot ur5 --script -", /*merge_stderr=*/true,
                             "0 joints 0.5 0 0 0 0 0 0\n1 stop\n");
  EXPECT_EQ(run.exit_code, 2) << run.out;
  EXPECT_THAT(run.out, HasSubstr("line 1: joints has 7 values, but the robot has 6 joints"));
}

// A call that lasts several deadman times is kept alive by the heartbeats alone (the script
// has nothing to say before its stop): path A at 20 Hz (no robot: light on any machine), a
// 1.5 s deadman, stopped at 4 s.
TEST_F(CliLive, HeartbeatsOutlastTheDeadman) {
  auto request = demo_example('a');
  request.mutable_motion()->set_cycle_rate_hz(20.0);
  std::string json;
  ASSERT_TRUE(google::protobuf::util::MessageToJsonString(request, &json).ok());
  const std::string path = write_file("geotraj_heartbeat_request.json", json);
  const CliRun run = run_cli(server() + "execute " + path + " --deadman 1.5 --script -", /*merge_stderr=*/true,
                             "4 stop\n");
  EXPECT_EQ(run.exit_code, 0) << run.out.substr(run.out.size() > 2000 ? run.out.size() - 2000 : 0);
  const auto lines = lines_of(run.out);
  ASSERT_FALSE(lines.empty());
  const auto last = csv_fields(lines.back());
  EXPECT_EQ(last.back(), "STOPPED");
  EXPECT_GE(std::stod(last.front()), 4.0);
}

// The CLI as a child process whose stdout the test reads line by line, to act on what the
// motion has done (not on the wall clock). With `tty`, its stdin and stderr are a pseudo
// terminal that is its controlling terminal, in the foreground: execute then reads keys.
class Child {
 public:
  Child(const std::vector<std::string>& args, bool tty) {
    int out[2];
    if (::pipe(out) != 0) return;
    if (tty) {
      master_ = ::posix_openpt(O_RDWR | O_NOCTTY);
      if (master_ < 0 || ::grantpt(master_) != 0 || ::unlockpt(master_) != 0) return;
      slave_ = ::open(::ptsname(master_), O_RDWR | O_NOCTTY);
      if (slave_ < 0) return;
      termios modes{};
      ::tcgetattr(slave_, &modes);
      modes_before_ = modes.c_lflag;
    }
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    const int null_fd = ::open("/dev/null", O_RDWR);
    pid_ = ::fork();
    if (pid_ == 0) {  // async-signal-safe calls only, up to exec
      if (tty) {
        ::setsid();
        ::ioctl(slave_, TIOCSCTTY, 0);
      }
      ::dup2(tty ? slave_ : null_fd, STDIN_FILENO);
      ::dup2(out[1], STDOUT_FILENO);
      ::dup2(tty ? slave_ : null_fd, STDERR_FILENO);
      ::execv(build_paths::cli(), argv.data());
      ::_exit(127);
    }
    ::close(null_fd);
    ::close(out[1]);
    out_ = ::fdopen(out[0], "r");
    if (tty) {  // the terminal's output (the status line), drained so that the child never blocks on it
      drainer_ = std::thread([this] {
        char buf[4096];
        while (!done_) {
          pollfd fd{master_, POLLIN, 0};
          if (::poll(&fd, 1, 50) <= 0) continue;
          const ssize_t n = ::read(master_, buf, sizeof buf);
          if (n <= 0) break;
          const std::lock_guard lock(terminal_mutex_);
          terminal_.append(buf, static_cast<std::size_t>(n));
        }
      });
    }
  }

  ~Child() {
    if (pid_ > 0 && exit_code_ == -2) {
      ::kill(pid_, SIGKILL);
      wait();
    }
    done_ = true;
    if (drainer_.joinable()) drainer_.join();
    if (out_ != nullptr) std::fclose(out_);
    if (slave_ >= 0) ::close(slave_);
    if (master_ >= 0) ::close(master_);
  }

  bool started() const { return pid_ > 0 && out_ != nullptr; }

  /// The next line of stdout (without its newline); false at its end.
  bool line(std::string& text) {
    char buf[8192];
    if (std::fgets(buf, sizeof buf, out_) == nullptr) return false;
    text = buf;
    if (!text.empty() && text.back() == '\n') text.pop_back();
    return true;
  }

  /// Reads lines until `until` holds for one (true) or stdout ends (false); every line read
  /// is kept in lines().
  bool read_until(const std::function<bool(const std::vector<std::string>&)>& until) {
    std::string text;
    while (line(text)) {
      lines_.push_back(text);
      if (lines_.size() > 1 && until(split(text))) return true;
    }
    return false;
  }

  void keys(const std::string& text) { (void)!::write(master_, text.data(), text.size()); }
  void signal(int sig) { ::kill(pid_, sig); }

  /// Reads the rest of stdout, waits for the child: its exit code (-1: killed by a signal).
  int wait() {
    std::string text;
    while (out_ != nullptr && line(text)) lines_.push_back(text);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return exit_code_;
  }

  const std::vector<std::string>& lines() const { return lines_; }
  /// For a failure message: the last line of stdout and the end of the terminal's output.
  std::string why() {
    const std::string t = terminal();
    return "last line: " + (lines_.empty() ? std::string() : lines_.back()) + "\nterminal: " +
           t.substr(t.size() > 600 ? t.size() - 600 : 0);
  }
  /// What the child wrote to its terminal (stderr) so far.
  std::string terminal() {
    const std::lock_guard lock(terminal_mutex_);
    return terminal_;
  }
  /// ICANON | ECHO of the terminal before the child ran, and now.
  tcflag_t modes_before() const { return modes_before_ & (ICANON | ECHO); }
  tcflag_t modes_now() const {
    termios modes{};
    ::tcgetattr(slave_, &modes);
    return modes.c_lflag & (ICANON | ECHO);
  }

  static std::vector<std::string> split(const std::string& line) { return csv_fields(line); }

 private:
  pid_t pid_ = -1;
  FILE* out_ = nullptr;
  int master_ = -1, slave_ = -1;
  tcflag_t modes_before_ = 0;
  std::atomic<bool> done_{false};
  std::mutex terminal_mutex_;
  std::string terminal_;  // what the child wrote to the terminal
  std::thread drainer_;
  std::vector<std::string> lines_;
  int exit_code_ = -2;
};

// The CSV columns of execute: t first, state last, speed_factor before it.
double t_of(const std::vector<std::string>& f) { return std::stod(f.front()); }
const std::string& state_of(const std::vector<std::string>& f) { return f.back(); }

// At a terminal the keys steer the motion: + raises the override, space pauses and resumes,
// s stops; each key is pressed once the motion shows the previous one's effect. At 30 to
// 40 % of its speed the motion is far from its end when the stop comes, however late the
// test reads its output. The terminal's modes are restored at the end.
TEST_F(CliLive, ExecuteAtATerminalFollowsTheKeys) {
  const std::string request = std::string(build_paths::examples_dir()) + "/plan_panda_path_c.json";
  Child cli({build_paths::cli(), "--server", address_, "execute", request, "--deadman", "5", "--override", "30"},
            /*tty=*/true);
  ASSERT_TRUE(cli.started());
  ASSERT_NE(cli.modes_before(), 0u);
  const auto speed_factor = [](const std::vector<std::string>& f) { return std::stod(f[f.size() - 2]); };
  ASSERT_TRUE(cli.read_until([](const auto& f) { return t_of(f) >= 0.2; })) << cli.why();
  cli.keys("+");  // the override to 40 %
  ASSERT_TRUE(cli.read_until([&](const auto& f) { return speed_factor(f) > 0.35; })) << cli.why();
  cli.keys(" ");  // pause
  ASSERT_TRUE(cli.read_until([](const auto& f) { return state_of(f) == "PAUSED"; })) << cli.why();
  cli.keys(" ");  // resume, and up to speed again (a stop from near rest could end within one batch)
  ASSERT_TRUE(cli.read_until([&](const auto& f) { return state_of(f) == "RUNNING" && speed_factor(f) > 0.2; }))
      << cli.why();
  cli.keys("s");  // stop
  EXPECT_EQ(cli.wait(), 0) << cli.why();
  std::vector<std::string> states;
  double fastest = 0.0;
  for (std::size_t i = 1; i < cli.lines().size(); ++i) {
    const auto f = Child::split(cli.lines()[i]);
    if (states.empty() || states.back() != state_of(f)) states.push_back(state_of(f));
    fastest = std::max(fastest, speed_factor(f));
  }
  EXPECT_THAT(states, ::testing::ElementsAre("RUNNING", "PAUSING", "PAUSED", "RUNNING", "STOPPING", "STOPPED"));
  EXPECT_LE(fastest, 0.4 + 1e-12) << "the override bounds the speed";
  EXPECT_EQ(cli.modes_now(), cli.modes_before()) << "the terminal's modes were not restored";
}

// The first SIGINT stops the motion on its path: a final sample at rest, exit 130. (At 30 %
// of its speed the motion is far from its end, however late the signal comes.)
TEST_F(CliLive, InterruptStopsTheMotion) {
  const std::string request = std::string(build_paths::examples_dir()) + "/plan_panda_path_c.json";
  Child cli({build_paths::cli(), "--server", address_, "execute", request, "--deadman", "5", "--override", "30"},
            /*tty=*/false);
  ASSERT_TRUE(cli.started());
  ASSERT_TRUE(cli.read_until([](const auto& f) { return t_of(f) >= 0.5; })) << cli.why();
  cli.signal(SIGINT);
  EXPECT_EQ(cli.wait(), 130);
  const auto last = Child::split(cli.lines().back());
  EXPECT_EQ(state_of(last), "STOPPED");
  EXPECT_EQ(std::stod(last[last.size() - 2]), 0.0);
}

}  // namespace
}  // namespace geotraj::testing
