// `geotraj plot`: the request planned, analysed and streamed through the service, then drawn
// by the plotting module (scripts/geotraj_plot.py, matplotlib) into a directory.
#include "commands.hpp"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <google/protobuf/util/json_util.h>
#include <grpcpp/client_context.h>
#include <tl/expected.hpp>

#include "geotraj/v1/geotraj.grpc.pb.h"
#include "planner/robots.hpp"
#include "report.hpp"
#include "server/wire/convert.hpp"

extern char** environ;

namespace geotraj::cli {
namespace fs = std::filesystem;

namespace {

constexpr const char* kModuleName = "geotraj_plot.py";
constexpr const char* kInstallHint =
    "install Debian's python3-matplotlib (apt-get install -y python3-matplotlib), or name a Python 3 that has "
    "matplotlib with --python or GEOTRAJ_PYTHON";
// Points of each path's AnalyzePath when the request gives no analysisPoints: smooth curves
// and peaks resolved to 1/2000 of a path, in a second or less.
constexpr std::uint32_t kDefaultPoints = 2001;

#ifndef GEOTRAJ_PLOT_DATADIR
#define GEOTRAJ_PLOT_DATADIR "/usr/local/share/geotraj"
#endif

void set_deadline(grpc::ClientContext& context, double timeout_s) {
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::microseconds(static_cast<long long>(timeout_s * 1e6)));
}

bool write_json(const google::protobuf::Message& message, const fs::path& file) {
  google::protobuf::util::JsonPrintOptions print;
  print.always_print_primitive_fields = true;
  std::string json;
  if (!google::protobuf::util::MessageToJsonString(message, &json, print).ok()) return false;
  std::ofstream out(file, std::ios::binary);
  out << json << '\n';
  return static_cast<bool>(out);
}

// A fresh private directory for the data handed to the plotting module.
tl::expected<fs::path, std::string> make_work_dir() {
  std::error_code ec;
  fs::path base = fs::temp_directory_path(ec);
  if (ec) base = "/tmp";
  std::string templ = (base / "geotraj-plot-XXXXXX").string();
  if (::mkdtemp(templ.data()) == nullptr) {
    return tl::unexpected("cannot create a temporary directory under " + base.string() + ": " + std::strerror(errno));
  }
  return fs::path(templ);
}

// Removes the work directory on every way out.
struct WorkDir {
  fs::path path;
  ~WorkDir() {
    std::error_code ec;
    if (!path.empty()) fs::remove_all(path, ec);
  }
};

// The request that analyses one path: the path alone, with the request's geometric
// optimisers (the plan draws the optimised curve) and the points asked for.
v1::PlanRequest analysis_request(const v1::PathSpec& path, const v1::PlanRequest& request, std::uint32_t points) {
  v1::PlanRequest analysis;
  *analysis.mutable_path() = path;
  if (request.has_optimize()) {
    const auto& o = request.optimize();
    if (o.has_tangent_scales()) *analysis.mutable_optimize()->mutable_tangent_scales() = o.tangent_scales();
    if (o.has_breakpoints()) *analysis.mutable_optimize()->mutable_breakpoints() = o.breakpoints();
    if (o.has_time_budget_s()) analysis.mutable_optimize()->set_time_budget_s(o.time_budget_s());
  }
  analysis.set_analysis_points(points);
  return analysis;
}

// The robot's model as the service knows it: a built-in one from ListRobots, the inline
// one, or the URDF document's chain. Absent (with a note on stderr) when it cannot be had;
// the joint figure is then left out.
std::optional<v1::RobotModel> robot_model(v1::TrajectoryService::Stub& stub, const v1::RobotSpec& robot,
                                          const CallOptions& options) {
  switch (robot.model_source_case()) {
    case v1::RobotSpec::kModel:
      return robot.model();
    case v1::RobotSpec::kUrdf: {
      planner::UrdfOptions urdf;
      urdf.base_link = robot.base_link();
      urdf.tip_link = robot.tip_link();
      for (const auto& named : robot.joint_limits()) {
        planner::NamedLimits limits{named.joint(), {}, {}, {}};
        if (named.has_max_velocity()) limits.max_velocity = named.max_velocity();
        if (named.has_max_acceleration()) limits.max_acceleration = named.max_acceleration();
        if (named.has_max_jerk()) limits.max_jerk = named.max_jerk();
        urdf.limits.push_back(std::move(limits));
      }
      auto model = planner::robot_from_urdf(robot.urdf(), urdf);
      if (!model) {
        std::cerr << "geotraj: plot: the robot's URDF could not be read here: no joint figure\n";
        return std::nullopt;
      }
      v1::RobotModel out;
      server::to_proto(*model, out);
      return out;
    }
    case v1::RobotSpec::kName: {
      grpc::ClientContext context;
      set_deadline(context, options.unary_timeout_s());
      v1::ListRobotsResponse robots;
      const grpc::Status status = stub.ListRobots(&context, v1::ListRobotsRequest{}, &robots);
      if (status.ok()) {
        for (const auto& model : robots.robots()) {
          if (model.name() == robot.name()) return model;
        }
      }
      std::cerr << "geotraj: plot: robot \"" << robot.name() << "\" not listed by the server: no joint figure\n";
      return std::nullopt;
    }
    default:
      return std::nullopt;
  }
}

// Runs `argv` (argv[0] looked up on PATH when it has no slash) with this process's standard
// streams; its exit code, or -1 with `error` set when it could not start.
int run_process(const std::vector<std::string>& argv, std::string& error) {
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  std::cout.flush();
  pid_t pid = 0;
  const int rc = ::posix_spawnp(&pid, args[0], nullptr, nullptr, args.data(), environ);
  if (rc != 0) {
    error = std::strerror(rc);
    return -1;
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) {
      error = std::strerror(errno);
      return -1;
    }
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  error = "ended by signal " + std::to_string(WTERMSIG(status));
  return -1;
}

// Where the plotting module may be, in order: --plot-module (or GEOTRAJ_PLOT_MODULE) alone
// when given; else beside the binary (<exe dir>/../share/geotraj/, the build tree's copy and
// an installed tree's), then the directory it was installed to.
std::vector<std::string> module_candidates(const PlotFlags& flags) {
  if (!flags.module.empty()) return {flags.module};  // --plot-module or GEOTRAJ_PLOT_MODULE
  std::vector<std::string> out;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) out.push_back((exe.parent_path() / ".." / "share" / "geotraj" / kModuleName).lexically_normal().string());
  out.push_back((fs::path(GEOTRAJ_PLOT_DATADIR) / kModuleName).string());
  return out;
}

// The Python that draws: --python (or GEOTRAJ_PYTHON), else Debian's, else python3 on PATH.
std::string python_of(const PlotFlags& flags) {
  if (!flags.python.empty()) return flags.python;  // --python or GEOTRAJ_PYTHON
  // Debian's interpreter first: python3-matplotlib installs there, whatever else is on PATH.
  if (::access("/usr/bin/python3", X_OK) == 0) return "/usr/bin/python3";
  return "python3";
}

}  // namespace

int run_plot(const Connection& connection, const CallOptions& options) {
  const PlotFlags& flags = options.plot;
  v1::PlanRequest request;
  if (!read_plan_request(options, request)) return 2;

  std::string module;
  const auto candidates = module_candidates(flags);
  for (const auto& c : candidates) {
    if (::access(c.c_str(), R_OK) == 0) {
      module = c;
      break;
    }
  }
  if (module.empty()) {
    std::cerr << "geotraj: plot: the plotting module " << kModuleName << " is not at";
    for (const auto& c : candidates) std::cerr << ' ' << c;
    std::cerr << " (give it with --plot-module or GEOTRAJ_PLOT_MODULE)\n";
    return 1;
  }
  std::error_code ec;
  fs::create_directories(flags.out_dir, ec);
  if (ec || !fs::is_directory(flags.out_dir)) {
    std::cerr << "geotraj: plot: cannot create the output directory \"" << flags.out_dir << "\""
              << (ec ? ": " + ec.message() : "") << '\n';
    return 2;
  }
  std::string stem = flags.name;
  if (stem.empty()) stem = options.input == "-" ? "request" : fs::path(options.input).stem().string();

  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  v1::PlanResponse plan;
  {
    grpc::ClientContext context;
    set_deadline(context, options.unary_timeout_s());
    const grpc::Status status = stub->PlanTrajectory(&context, request, &plan);
    if (!status.ok()) {
      print_error(status, std::cerr);
      if (status.error_code() == grpc::StatusCode::FAILED_PRECONDITION && request.has_robot() &&
          !request.robot().report_only()) {
        std::cerr << "geotraj: plot: nothing drawn; with \"robot\": {\"reportOnly\": true} the plan is drawn with "
                     "the limits it breaks\n";
      }
      return 1;
    }
  }
  auto made = make_work_dir();
  if (!made) {
    std::cerr << "geotraj: plot: " << made.error() << '\n';
    return 1;
  }
  WorkDir work{*made};
  int code = 0;

  // Every path's geometry: the request's path, or each path of its sequence.
  std::vector<const v1::PathSpec*> paths;
  if (request.sequence_size() > 0) {
    for (const auto& step : request.sequence()) {
      if (step.has_path()) paths.push_back(&step.path());
    }
  } else if (request.has_path()) {
    paths.push_back(&request.path());
  }
  const std::uint32_t points = flags.points ? *flags.points
                               : request.has_analysis_points() ? request.analysis_points()
                                                                : kDefaultPoints;
  std::vector<std::string> argv = {python_of(flags), module, "request"};
  for (std::size_t i = 0; i < paths.size(); ++i) {
    grpc::ClientContext context;
    set_deadline(context, options.unary_timeout_s());
    v1::PathProfile profile;
    const grpc::Status status =
        stub->AnalyzePath(&context, analysis_request(*paths[i], request, points), &profile);
    if (!status.ok()) {
      print_error(status, std::cerr);
      return 1;
    }
    const fs::path file = work.path / ("profile_" + std::to_string(i) + ".json");
    if (!write_json(profile, file)) {
      std::cerr << "geotraj: plot: cannot write " << file << '\n';
      return 1;
    }
    argv.insert(argv.end(), {"--profile", file.string()});
  }

  // The samples, when the request has a motion.
  if (request.has_motion() || request.sequence_size() > 0) {
    const fs::path file = work.path / "samples.csv";
    std::ofstream csv(file, std::ios::binary);
    grpc::ClientContext context;
    if (options.timeout_s > 0.0) set_deadline(context, options.timeout_s);
    auto reader = stub->StreamSamples(&context, request);
    v1::SampleBatch batch;
    bool header = false;
    const bool sequence = has_steps(request);
    while (reader->Read(&batch)) {
      for (const auto& s : batch.samples()) {
        if (!header) {
          print_sample_csv_header(s, sequence, csv);
          csv << '\n';
          header = true;
        }
        print_sample_csv(s, sequence, csv);
        csv << '\n';
      }
    }
    csv.close();
    const grpc::Status status = reader->Finish();
    if (!status.ok()) {
      print_error(status, std::cerr);
      std::cerr << "geotraj: plot: no samples: the speed and joint figures are left out\n";
      code = 1;
    } else if (header) {
      argv.insert(argv.end(), {"--samples", file.string()});
    }
  }

  if (request.has_robot()) {
    if (auto model = robot_model(*stub, request.robot(), options)) {
      const fs::path file = work.path / "robot.json";
      if (write_json(*model, file)) argv.insert(argv.end(), {"--robot", file.string()});
    }
  }
  const fs::path request_file = work.path / "request.json";
  const fs::path plan_file = work.path / "plan.json";
  if (!write_json(request, request_file) || !write_json(plan, plan_file)) {
    std::cerr << "geotraj: plot: cannot write the data under " << work.path << '\n';
    return 1;
  }
  argv.insert(argv.end(), {"--request", request_file.string(), "--plan", plan_file.string(), "--out", flags.out_dir,
                           "--name", stem});
  if (flags.png) argv.emplace_back("--png");

  std::string error;
  const int drawn = run_process(argv, error);
  if (drawn < 0) {
    std::cerr << "geotraj: plot: cannot run " << argv[0] << " (" << error << "): " << kInstallHint << '\n';
    return 1;
  }
  if (drawn == 3) {  // the module's own code for a missing matplotlib (it said so on stderr)
    std::cerr << "geotraj: plot: " << argv[0] << " has no matplotlib: " << kInstallHint << '\n';
    return 1;
  }
  if (drawn != 0) {
    std::cerr << "geotraj: plot: " << argv[0] << ' ' << module << " failed (exit " << drawn << ")\n";
    return 1;
  }
  return code;
}

}  // namespace geotraj::cli
