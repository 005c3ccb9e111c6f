// The live subcommands: `execute` (Execute) and `jog` (Jog). Each call runs on two threads,
// as gRPC's synchronous bidirectional stream allows one reader and one writer at a time:
//   the main thread   reads the SampleBatches, prints them (and a status line when stderr is
//                     a terminal), and publishes how far the motion has come: the t of the
//                     last sample received;
//   the sender        writes every message: the first one; each script step once a sample at
//                     or after its time has arrived; the commands of the keys (execute, with
//                     stdin a terminal); a stop on the first Ctrl-C (SIGINT or SIGTERM); and
//                     a heartbeat whenever nothing was sent for deadman / 4, until the call
//                     ends, so that the server's deadman never trips while the client runs.
// Script times are the motion's own (Sample.t), not the wall clock: planning before the first
// sample does not count, and a stalled stream holds the script with it.
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <limits>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <google/protobuf/util/json_util.h>
#include <grpcpp/client_context.h>

#include "commands.hpp"
#include "geotraj/v1/geotraj.grpc.pb.h"
#include "report.hpp"
#include "script.hpp"
#include "terminal.hpp"

namespace geotraj::cli {
namespace {

using Clock = std::chrono::steady_clock;

constexpr double kDefaultDeadmanS = 1.0;  // the server's, when the first message gives none

/// A message the sender writes once the motion's time reaches t_s.
template <class Request>
struct Timed {
  double t_s = 0.0;
  Request message;
};

/// What the reader (main thread) tells the sender.
struct Progress {
  std::mutex mutex;
  double motion_t = -1.0;  ///< t of the last sample received [s]; < 0: none yet
  bool ended = false;      ///< the stream has ended: nothing more to send
  bool halt = false;       ///< stop the motion now and send no more script steps
  /// The time of the sender's next script step [s] (infinity: none): the reader wakes the
  /// sender when a sample reaches it.
  std::atomic<double> next_step_t{std::numeric_limits<double>::infinity()};
};

template <class Request>
struct SenderSetup {
  Request first;
  Request heartbeat;
  Request stop;
  std::vector<Timed<Request>> script;
  double heartbeat_s = kDefaultDeadmanS / 4.0;
  /// The messages for a key (interactive only; empty: no keys are read).
  std::function<std::vector<Request>(char)> key;
};

// The sender thread's body (see the file comment). Returns when the stream has ended or a
// write fails (the call is over).
template <class Request>
void send_all(grpc::ClientReaderWriter<Request, v1::SampleBatch>& stream, const SenderSetup<Request>& setup,
              const LiveProcess& process, Progress& progress) {
  const auto heartbeat = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(setup.heartbeat_s));
  Clock::time_point last_sent = Clock::now();
  if (!stream.Write(setup.first)) return;
  std::size_t next = 0;
  bool stopped = false;  // a stop was sent: only heartbeats from here
  const auto publish_next = [&] {
    progress.next_step_t = !stopped && next < setup.script.size() ? setup.script[next].t_s
                                                                  : std::numeric_limits<double>::infinity();
  };
  publish_next();
  std::vector<Request> pending;  // from the keys
  bool keys = static_cast<bool>(setup.key);
  for (;;) {
    double motion_t = -1.0;
    bool halt = false;
    {
      const std::lock_guard lock(progress.mutex);
      if (progress.ended) return;
      motion_t = progress.motion_t;
      halt = progress.halt;
    }
    std::vector<const Request*> out;
    if ((halt || process.interrupts() > 0) && !stopped) {
      out.push_back(&setup.stop);
      stopped = true;
    }
    while (!stopped && next < setup.script.size() && motion_t >= setup.script[next].t_s) {
      out.push_back(&setup.script[next].message);
      stopped = setup.script[next].message.has_stop();
      ++next;
    }
    for (const Request& r : pending) {
      if (stopped) break;
      out.push_back(&r);
      stopped = r.has_stop();
    }
    publish_next();
    for (const Request* r : out) {
      if (!stream.Write(*r)) return;
      last_sent = Clock::now();
    }
    pending.clear();
    if (Clock::now() - last_sent >= heartbeat) {
      if (!stream.Write(setup.heartbeat)) return;
      last_sent = Clock::now();
    }
    // Wait for the next heartbeat, a wake-up (a sample at the next step's time, the end, an
    // interrupt) or a key.
    const auto left = last_sent + heartbeat - Clock::now();
    const int timeout_ms =
        static_cast<int>(std::max<long long>(0, std::chrono::ceil<std::chrono::milliseconds>(left).count()));
    pollfd fds[2] = {{process.wake_fd(), POLLIN, 0}, {STDIN_FILENO, POLLIN, 0}};
    if (::poll(fds, keys ? 2 : 1, timeout_ms) > 0) {
      if (fds[0].revents != 0) process.drain();
      if (keys && fds[1].revents != 0) {
        char buf[32];
        const ssize_t n = ::read(STDIN_FILENO, buf, sizeof buf);
        if (n <= 0) {
          keys = false;  // end of input: no more keys
        } else {
          for (ssize_t i = 0; i < n; ++i) {
            for (auto& r : setup.key(buf[i])) pending.push_back(std::move(r));
          }
        }
      }
    }
  }
}

/// How the reader shows a batch: printed to stdout, and a status line (without newline) for
/// stderr when it is a terminal.
struct BatchView {
  std::function<void(const v1::SampleBatch&)> print;
  std::function<std::string(const v1::SampleBatch&)> status;
  /// Checks the first batch; a message (the call is then stopped, exit 2) or "".
  std::function<std::string(const v1::SampleBatch&)> check_first;
  /// What the first batch says once, on stderr (or "").
  std::function<std::string(const v1::SampleBatch&)> first_note;
};

std::string short_name(const std::string& name, const std::string& prefix) {
  return name.rfind(prefix, 0) == 0 ? name.substr(prefix.size()) : name;
}

std::string state_name(v1::LiveState state) { return short_name(v1::LiveState_Name(state), "LIVE_STATE_"); }

// Runs one live call: the sender on its thread, the reader here. The exit code (see
// run_execute), with the error or the stop reason printed on stderr.
template <class Request>
int drive(grpc::ClientContext& context, std::unique_ptr<grpc::ClientReaderWriter<Request, v1::SampleBatch>> stream,
          const SenderSetup<Request>& setup, const BatchView& view, const LiveProcess& process, const char* what) {
  Progress progress;
  std::thread sender([&] { send_all(*stream, setup, process, progress); });
  const bool status_line = ::isatty(STDERR_FILENO) != 0;
  if (status_line && setup.key) {
    std::fprintf(stderr, "keys: space pause/resume, + and - the speed override by 10 %%, s or q stop (Ctrl-C too)\n");
  }
  Clock::time_point shown{};
  std::string last_status;  // of the last batch (status_line only)
  std::string check_error;
  bool first = true;
  v1::SampleBatch batch;
  while (stream->Read(&batch)) {
    if (first && !batch.samples().empty()) {
      first = false;
      if (view.check_first) check_error = view.check_first(batch);
      if (view.first_note) {
        if (const std::string note = view.first_note(batch); !note.empty()) {
          std::fprintf(stderr, "geotraj: %s: %s\n", what, note.c_str());
        }
      }
      if (!check_error.empty()) {
        {
          const std::lock_guard lock(progress.mutex);
          progress.halt = true;
        }
        process.wake();
      }
    }
    if (check_error.empty()) view.print(batch);
    if (!batch.samples().empty()) {
      const double t = batch.samples(batch.samples_size() - 1).t();
      {
        const std::lock_guard lock(progress.mutex);
        progress.motion_t = t;
      }
      if (t >= progress.next_step_t) process.wake();
    }
    if (status_line) {
      last_status = view.status(batch);
      const auto now = Clock::now();
      if (now - shown > std::chrono::milliseconds(100)) {
        shown = now;
        std::fprintf(stderr, "\r%s\033[K", last_status.c_str());
      }
    }
  }
  {
    const std::lock_guard lock(progress.mutex);
    progress.ended = true;
  }
  process.wake();
  sender.join();
  stream->WritesDone();
  const grpc::Status status = stream->Finish();
  std::cout.flush();
  std::string reason;
  const auto& trailers = context.GetServerTrailingMetadata();
  if (const auto it = trailers.find("geotraj-stop-reason"); it != trailers.end()) {
    reason.assign(it->second.data(), it->second.size());
  }
  if (status_line) std::fprintf(stderr, "\r%s\033[K\n", last_status.c_str());
  if (!check_error.empty()) {
    std::cerr << "geotraj: " << check_error << '\n';
    return 2;
  }
  if (!status.ok()) {
    print_error(status, std::cerr);
    return 1;
  }
  if (status_line && !reason.empty()) std::cerr << "geotraj: " << what << ": " << reason << '\n';
  if (process.interrupts() > 0) {
    std::cerr << "geotraj: " << what << ": interrupted: the motion was stopped and brought to rest\n";
    return 130;  // 128 + SIGINT, as a shell reports an interrupted command
  }
  return 0;
}

void set_deadline(grpc::ClientContext& context, double timeout_s) {
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::microseconds(static_cast<long long>(timeout_s * 1e6)));
}

// The script named by --script ("-": stdin), read whole; false (with a message) when it
// cannot be.
bool read_script(const std::string& path, std::string& text) {
  if (read_text(path, text)) return true;
  std::cerr << "geotraj: --script: cannot read \"" << path << "\"\n";
  return false;
}

std::string script_name(const std::string& path) { return path == "-" ? "(standard input)" : path; }

void print_errors(const ScriptErrors& errors) {
  for (const auto& e : errors) std::cerr << "geotraj: " << e << '\n';
}

std::string json_line(const google::protobuf::Message& message) {
  google::protobuf::util::JsonPrintOptions print;
  print.add_whitespace = false;
  std::string json;
  (void)google::protobuf::util::MessageToJsonString(message, &json, print);
  return json;
}

}  // namespace

int run_execute(const Connection& connection, const CallOptions& options) {
  const LiveFlags& flags = options.live;
  if (options.input == "-" && flags.script == "-") {
    std::cerr << "geotraj: execute: the request and the script cannot both come from standard input\n";
    return 2;
  }
  v1::ExecuteRequest first;
  if (!read_plan_request(options, *first.mutable_plan())) return 2;
  auto* execute_options = first.mutable_options();
  if (flags.deadman_s) execute_options->set_deadman_s(*flags.deadman_s);
  if (flags.override_percent) execute_options->set_speed_override(*flags.override_percent);
  if (flags.reserve) execute_options->set_acceleration_reserve(*flags.reserve);

  SenderSetup<v1::ExecuteRequest> setup;
  setup.first = first;
  setup.heartbeat.mutable_heartbeat();
  setup.stop.mutable_stop();
  setup.heartbeat_s = flags.deadman_s.value_or(kDefaultDeadmanS) / 4.0;
  if (!flags.script.empty()) {
    std::string text;
    if (!read_script(flags.script, text)) return 2;
    auto steps = parse_execute_script(text, script_name(flags.script));
    if (!steps) {
      print_errors(steps.error());
      return 2;
    }
    for (const auto& step : *steps) {
      Timed<v1::ExecuteRequest> timed{step.t_s, {}};
      switch (step.kind) {
        case ExecuteStep::Kind::kOverride: timed.message.set_speed_override(step.percent); break;
        case ExecuteStep::Kind::kPause: timed.message.mutable_pause(); break;
        case ExecuteStep::Kind::kResume: timed.message.mutable_resume(); break;
        case ExecuteStep::Kind::kStop: timed.message.mutable_stop(); break;
      }
      setup.script.push_back(std::move(timed));
    }
  }

  LiveProcess process;
  if (!process.ok()) {
    std::cerr << "geotraj: execute: cannot make a pipe\n";
    return 1;
  }
  // The keys, when a person is at the terminal (and stdin holds neither request nor script).
  double override_percent = flags.override_percent.value_or(100.0);
  bool paused = false;
  if (flags.script.empty() && options.input != "-" && process.raw_keys()) {
    setup.key = [&override_percent, &paused](char c) {
      std::vector<v1::ExecuteRequest> out(1);
      switch (c) {
        case ' ':
          if (paused) {
            out[0].mutable_resume();
          } else {
            out[0].mutable_pause();
          }
          paused = !paused;
          break;
        case '+':
        case '=':
          override_percent = std::min(100.0, override_percent + 10.0);
          out[0].set_speed_override(override_percent);
          break;
        case '-':
        case '_':
          override_percent = std::max(0.0, override_percent - 10.0);
          out[0].set_speed_override(override_percent);
          break;
        case 's':
        case 'S':
        case 'q':
        case 'Q': out[0].mutable_stop(); break;
        default: out.clear();
      }
      return out;
    };
  }

  const bool sequence = has_steps(first.plan());  // a `step` column, as in `stream`
  bool header_written = options.json;
  BatchView view;
  view.print = [&](const v1::SampleBatch& batch) {
    if (options.json) {
      std::cout << json_line(batch) << '\n';
    } else {
      const std::string state = state_name(batch.live().state());
      char tail[128];
      for (const auto& s : batch.samples()) {
        if (!header_written) {
          print_sample_csv_header(s, sequence, std::cout);
          std::cout << ",plan_time,speed_factor,state\n";
          header_written = true;
        }
        print_sample_csv(s, sequence, std::cout);
        std::snprintf(tail, sizeof tail, ",%.17g,%.17g,", s.plan_time(), s.speed_factor());
        std::cout << tail << state << '\n';
      }
    }
    std::cout.flush();
  };
  view.first_note = [](const v1::SampleBatch& batch) {
    const auto& live = batch.live();
    if (live.acceleration_reserve() <= 0.0) return std::string();
    char reserve[32];
    std::snprintf(reserve, sizeof reserve, "%.4g", live.acceleration_reserve());
    return "acceleration reserve " + std::string(reserve) + ": " + live.reserve_note();
  };
  view.status = [](const v1::SampleBatch& batch) {
    const auto& live = batch.live();
    const double t = batch.samples().empty() ? 0.0 : batch.samples(batch.samples_size() - 1).t();
    const double plan_t = batch.samples().empty() ? 0.0 : batch.samples(batch.samples_size() - 1).plan_time();
    char line[200];
    std::snprintf(line, sizeof line, "%-9s override %5.1f %%  plan time %7.3f / %.3f s  t %7.3f s",
                  state_name(live.state()).c_str(), live.speed_override(), plan_t, live.plan_duration_s(), t);
    return std::string(line);
  };

  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  grpc::ClientContext context;
  if (options.timeout_s > 0.0) set_deadline(context, options.timeout_s);  // else none, as for `stream`
  return drive(context, stub->Execute(&context), setup, view, process, "execute");
}

int run_jog(const Connection& connection, const CallOptions& options) {
  const LiveFlags& flags = options.live;
  v1::JogRequest first;
  auto* start = first.mutable_start();
  auto* robot = start->mutable_robot();
  const int sources = static_cast<int>(!flags.robot.empty()) + static_cast<int>(!flags.robot_file.empty()) +
                      static_cast<int>(!flags.urdf.empty());
  if (sources != 1) {
    std::cerr << "geotraj: jog: give the robot by exactly one of --robot NAME, --robot-file MODEL.json and "
                 "--urdf FILE\n";
    return 2;
  }
  if ((flags.robot_file == "-" || flags.urdf == "-") && flags.script == "-") {
    std::cerr << "geotraj: jog: the robot and the script cannot both come from standard input\n";
    return 2;
  }
  if (!set_robot_source(flags.robot, flags.urdf, flags.tip_link, *robot)) return 2;
  if (!flags.robot_file.empty() && !read_request(flags.robot_file, *robot->mutable_model())) return 2;
  for (double q : flags.joints) robot->add_initial_joints(q);
  if (flags.rate_hz) start->set_cycle_rate_hz(*flags.rate_hz);
  if (flags.deadman_s) start->set_deadman_s(*flags.deadman_s);
  if (flags.velocity_scale) start->set_velocity_scale(*flags.velocity_scale);
  if (flags.max_linear_speed) start->set_max_linear_speed(*flags.max_linear_speed);
  if (flags.max_angular_speed) start->set_max_angular_speed(*flags.max_angular_speed);

  std::string text;
  if (!read_script(flags.script, text)) return 2;
  auto steps = parse_jog_script(text, script_name(flags.script));
  if (!steps) {
    print_errors(steps.error());
    return 2;
  }
  if (steps->empty() || steps->back().kind != JogStep::Kind::kStop) {
    // Without a stop the last command would go on for ever (the heartbeats keep it alive).
    JogStep stop;
    stop.t_s = steps->empty() ? 0.0 : steps->back().t_s;
    std::cerr << "geotraj: jog: script " << script_name(flags.script) << " does not end with a stop: stopping at "
              << stop.t_s << " s, its last line's time\n";
    steps->push_back(stop);
  }
  SenderSetup<v1::JogRequest> setup;
  setup.first = first;
  setup.heartbeat.mutable_heartbeat();
  setup.stop.mutable_stop();
  setup.heartbeat_s = flags.deadman_s.value_or(kDefaultDeadmanS) / 4.0;
  for (const auto& step : *steps) {
    Timed<v1::JogRequest> timed{step.t_s, {}};
    switch (step.kind) {
      case JogStep::Kind::kJoints:
        for (double v : step.values) timed.message.mutable_joints()->add_velocities(v);
        break;
      case JogStep::Kind::kTwist: {
        auto* twist = timed.message.mutable_twist();
        twist->mutable_linear()->set_x(step.values[0]);
        twist->mutable_linear()->set_y(step.values[1]);
        twist->mutable_linear()->set_z(step.values[2]);
        twist->mutable_angular()->set_x(step.values[3]);
        twist->mutable_angular()->set_y(step.values[4]);
        twist->mutable_angular()->set_z(step.values[5]);
        twist->set_frame(step.tool_frame ? v1::COORDINATE_MODE_TOOL : v1::COORDINATE_MODE_WORLD);
        break;
      }
      case JogStep::Kind::kStop: timed.message.mutable_stop(); break;
    }
    setup.script.push_back(std::move(timed));
  }

  LiveProcess process;
  if (!process.ok()) {
    std::cerr << "geotraj: jog: cannot make a pipe\n";
    return 1;
  }
  bool header_written = options.json;
  BatchView view;
  view.check_first = [&](const v1::SampleBatch& batch) -> std::string {
    const auto dof = static_cast<std::size_t>(batch.samples(0).joints_size());
    for (const auto& step : *steps) {
      if (step.kind == JogStep::Kind::kJoints && step.values.size() != dof) {
        return "script " + script_name(flags.script) + ", line " + std::to_string(step.line) + ": joints has " +
               std::to_string(step.values.size()) + " values, but the robot has " + std::to_string(dof) +
               " joints (the jog was stopped)";
      }
    }
    return "";
  };
  view.print = [&](const v1::SampleBatch& batch) {
    if (options.json) {
      std::cout << json_line(batch) << '\n';
      std::cout.flush();
      return;
    }
    const int n = batch.samples().empty() ? 0 : batch.samples(0).joints_size();
    if (!header_written && n > 0) {
      std::cout << 't';
      for (const char* name : {"q", "qd"}) {
        for (int j = 0; j < n; ++j) std::cout << ',' << name << j;
      }
      std::cout << ",x,y,z,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz,damping,sigma_min";
      for (int j = 0; j < n; ++j) std::cout << ",limited" << j;
      std::cout << ",state\n";
      header_written = true;
    }
    std::vector<bool> limited(static_cast<std::size_t>(n), false);
    for (std::uint32_t j : batch.live().limited_joints()) {
      if (j < limited.size()) limited[j] = true;
    }
    const std::string state = state_name(batch.live().state());
    char cell[64];
    for (const auto& s : batch.samples()) {
      std::snprintf(cell, sizeof cell, "%.9g", s.t());
      std::cout << cell;
      for (const auto* values : {&s.joints(), &s.joint_velocities()}) {
        for (double x : *values) {
          std::snprintf(cell, sizeof cell, ",%.17g", x);
          std::cout << cell;
        }
      }
      const auto& p = s.position();
      const auto& q = s.orientation();
      const auto& v = s.velocity();
      const auto& w = s.angular_velocity();
      for (double x : {p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z(), v.x(), v.y(), v.z(), w.x(), w.y(), w.z(),
                       s.damping(), s.smallest_singular_value()}) {
        std::snprintf(cell, sizeof cell, ",%.17g", x);
        std::cout << cell;
      }
      for (bool l : limited) std::cout << (l ? ",1" : ",0");
      std::cout << ',' << state << '\n';
    }
    std::cout.flush();
  };
  view.status = [](const v1::SampleBatch& batch) {
    const double t = batch.samples().empty() ? 0.0 : batch.samples(batch.samples_size() - 1).t();
    std::string line = state_name(batch.live().state());
    char buf[64];
    std::snprintf(buf, sizeof buf, "  t %7.3f s", t);
    line += buf;
    if (!batch.live().limited_joints().empty()) {
      line += "  at a limit: joint";
      for (std::uint32_t j : batch.live().limited_joints()) line += ' ' + std::to_string(j);
    }
    return line;
  };

  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  grpc::ClientContext context;
  if (options.timeout_s > 0.0) set_deadline(context, options.timeout_s);
  return drive(context, stub->Jog(&context), setup, view, process, "jog");
}

}  // namespace geotraj::cli
