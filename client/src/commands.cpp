#include "commands.hpp"

#include <unistd.h>

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstdio>
#include <cstring>

#include <chrono>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <type_traits>

#include <google/protobuf/util/json_util.h>
#include <grpcpp/client_context.h>

#include "geotraj/v1/geotraj.grpc.pb.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "planner/robots.hpp"
#include "report.hpp"
#include "waypoints.hpp"

namespace geotraj::cli {

bool read_text(const std::string& input, std::string& text) {
  if (input == "-") {
    text.assign(std::istreambuf_iterator<char>(std::cin), std::istreambuf_iterator<char>());
    return true;
  }
  std::ifstream file(input, std::ios::binary);
  if (!file) return false;
  text.assign(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
  return true;
}

bool read_request(const std::string& input, google::protobuf::Message& request) {
  const std::string name = input == "-" ? "standard input" : input;
  std::string text;
  if (!read_text(input, text)) {
    std::cerr << "geotraj: cannot read " << name << '\n';
    return false;
  }
  google::protobuf::util::JsonParseOptions parse;
  parse.ignore_unknown_fields = false;
  const auto status = google::protobuf::util::JsonStringToMessage(text, &request, parse);
  if (!status.ok()) {
    std::cerr << "geotraj: " << name << " is not a " << request.GetDescriptor()->full_name()
              << " in the proto JSON mapping: " << status.message() << '\n';
    return false;
  }
  return true;
}

namespace {

// The request's paths: its `path`, or every path of its sequence.
std::vector<v1::PathSpec*> paths_of(v1::PlanRequest& request) {
  if (request.sequence_size() == 0) return {request.mutable_path()};
  std::vector<v1::PathSpec*> paths;
  for (auto& step : *request.mutable_sequence()) {
    if (step.has_path()) paths.push_back(step.mutable_path());
  }
  return paths;
}

}  // namespace

bool set_robot_source(const std::string& name, const std::string& urdf_file, const std::string& tip_link,
                      v1::RobotSpec& robot) {
  if (!name.empty() && !urdf_file.empty()) {
    std::cerr << "geotraj: give the robot by --robot NAME or --urdf FILE, not both\n";
    return false;
  }
  if (!tip_link.empty() && urdf_file.empty()) {
    std::cerr << "geotraj: --tip-link names the tip link of an --urdf FILE's chain: give --urdf\n";
    return false;
  }
  if (!tip_link.empty()) robot.set_tip_link(tip_link);
  if (!name.empty()) robot.set_name(name);
  if (urdf_file.empty()) return true;
  std::string text;
  if (!read_text(urdf_file, text)) {
    std::cerr << "geotraj: --urdf: cannot read \"" << urdf_file << "\"\n";
    return false;
  }
  robot.set_urdf(std::move(text));
  return true;
}

bool read_plan_request(const CallOptions& options, v1::PlanRequest& request) {
  const OptimizeFlags& flags = options.optimize;
  if (options.input.empty()) {
    request.mutable_motion()->set_duration_s(0.0);  // a request made of the flags
  } else if (!read_request(options.input, request)) {
    return false;
  }
  if ((!flags.robot.empty() || !flags.urdf.empty() || !flags.tip_link.empty()) &&
      !set_robot_source(flags.robot, flags.urdf, flags.tip_link, *request.mutable_robot()))
    return false;
  if (flags.rate_hz > 0.0) request.mutable_motion()->set_cycle_rate_hz(flags.rate_hz);
  if (!flags.waypoints.empty()) {
    WaypointFile file;
    std::string error;
    if (!read_waypoints(flags.waypoints, file, error)) {
      std::cerr << "geotraj: --waypoints: " << error << '\n';
      return false;
    }
    // The joints in the model's order, where the CLI knows the model (a built-in one).
    std::vector<std::string> names;
    if (const auto* model = planner::find_builtin_robot(request.robot().name()); model && request.has_robot()) {
      for (const auto& joint : model->joints) names.push_back(joint.name);
    }
    if (!set_joint_path(file, names, flags.blend_tolerance, request, error)) {
      std::cerr << "geotraj: --waypoints: " << error << '\n';
      return false;
    }
  } else if (flags.blend_tolerance >= 0.0) {
    if (!request.has_joint_path()) {
      std::cerr << "geotraj: --blend-tolerance sets a jointPath's: the request has none (give --waypoints)\n";
      return false;
    }
    request.mutable_joint_path()->set_blend_tolerance(flags.blend_tolerance);
  }
  return apply_flags(flags, request);
}


// --optimize-redundancy "acceleration=1,range=0.1": each criterion's weight (the server checks
// the values); an unknown key or a value that is not a number is refused here.
bool set_redundancy(const std::string& text, v1::RedundancyOptimization& out) {
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, end - start);
    const std::size_t eq = item.find('=');
    const std::string key = item.substr(0, eq);
    double value = 0.0;
    bool number = false;
    if (eq != std::string::npos) {
      try {
        std::size_t used = 0;
        value = std::stod(item.substr(eq + 1), &used);
        number = used == item.size() - eq - 1;
      } catch (const std::exception&) {
        number = false;
      }
    }
    if (!number) {
      std::cerr << "geotraj: --optimize-redundancy: \"" << item
                << "\" is not criterion=weight (range, velocity, acceleration, jerk, manipulability)\n";
      return false;
    }
    if (key == "range") out.set_joint_range_weight(value);
    else if (key == "velocity") out.set_velocity_weight(value);
    else if (key == "acceleration") out.set_acceleration_weight(value);
    else if (key == "jerk") out.set_jerk_weight(value);
    else if (key == "manipulability") out.set_manipulability_weight(value);
    else {
      std::cerr << "geotraj: --optimize-redundancy: unknown criterion \"" << key
                << "\" (range, velocity, acceleration, jerk, manipulability)\n";
      return false;
    }
    start = end + 1;
  }
  return true;
}

bool apply_flags(const OptimizeFlags& flags, v1::PlanRequest& request) {
  auto enum_value = [](const std::string& name, const std::string& prefix,
                       const google::protobuf::EnumDescriptor* descriptor, int& out) {
    std::string upper = prefix;
    for (char c : name) upper += c == '-' ? '_' : static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    const auto* value = descriptor->FindValueByName(upper);
    if (value == nullptr || value->number() == 0) {
      std::cerr << "geotraj: unknown value '" << name << "' (" << prefix << "...)\n";
      return false;
    }
    out = value->number();
    return true;
  };
  if (!flags.unspecified.empty()) {
    int reading = 0;
    if (!enum_value(flags.unspecified, "UNSPECIFIED_CONSTRAINTS_", v1::UnspecifiedConstraints_descriptor(), reading)) {
      return false;
    }
    for (auto* path : paths_of(request)) path->set_unspecified(static_cast<v1::UnspecifiedConstraints>(reading));
  }
  if (flags.max_curvature > 0.0) {
    for (auto* path : paths_of(request)) path->set_max_curvature(flags.max_curvature);
  }
  if (flags.velocity_scale || flags.acceleration_scale) {
    if (!request.has_robot()) {
      std::cerr << "geotraj: --velocity-scale and --acceleration-scale scale a robot's joint limits: the request has "
                   "no robot\n";
      return false;
    }
    if (flags.velocity_scale) request.mutable_robot()->set_velocity_scale(*flags.velocity_scale);
    if (flags.acceleration_scale) request.mutable_robot()->set_acceleration_scale(*flags.acceleration_scale);
  }
  if (!flags.payload.empty() || !flags.max_torque.empty()) {
    if (!request.has_robot()) {
      std::cerr << "geotraj: --payload and --max-torque are a robot's: the request has no robot (--robot NAME)\n";
      return false;
    }
    if (flags.payload.size() != 1 && flags.payload.size() != 4 && !flags.payload.empty()) {
      std::cerr << "geotraj: --payload takes MASS or MASS,X,Y,Z\n";
      return false;
    }
    if (!flags.payload.empty()) {
      auto* payload = request.mutable_robot()->mutable_payload();
      payload->set_mass(flags.payload[0]);
      if (flags.payload.size() == 4) {
        payload->mutable_center_of_mass()->set_x(flags.payload[1]);
        payload->mutable_center_of_mass()->set_y(flags.payload[2]);
        payload->mutable_center_of_mass()->set_z(flags.payload[3]);
      }
    }
    std::stringstream items(flags.max_torque);
    for (std::string item; std::getline(items, item, ',');) {
      const auto eq = item.find('=');
      char* end = nullptr;
      const double value = eq == std::string::npos ? 0.0 : std::strtod(item.c_str() + eq + 1, &end);
      if (eq == std::string::npos || eq == 0 || end == item.c_str() + eq + 1 || *end != '\0' || !std::isfinite(value)) {
        std::cerr << "geotraj: --max-torque takes JOINT=N_M,...: '" << item << "' is not one\n";
        return false;
      }
      auto* limits = request.mutable_robot()->add_joint_limits();
      limits->set_joint(item.substr(0, eq));
      limits->set_max_torque(value);
    }
  }
  if (!flags.joint_limits.empty()) {
    if (!request.has_robot()) {
      std::cerr << "geotraj: --joint-limits gives a robot's limits: the request has no robot (--robot NAME)\n";
      return false;
    }
    std::ifstream file(flags.joint_limits, std::ios::binary);
    std::stringstream text;
    if (file) text << file.rdbuf();
    if (!file) {
      std::cerr << "geotraj: --joint-limits: cannot read " << flags.joint_limits << '\n';
      return false;
    }
    request.mutable_robot()->set_joint_limits_yaml(text.str());
  }
  if (!flags.approach.empty()) {
    if (!request.has_robot()) {
      std::cerr << "geotraj: --approach moves a robot to the path's start: the request has no robot\n";
      return false;
    }
    request.mutable_robot()->set_approach(flags.approach == "joint" ? v1::APPROACH_MOVE_JOINT : v1::APPROACH_MOVE_LINEAR);
  }
  if (flags.tool_axis_free) {
    if (!request.has_robot()) {
      std::cerr << "geotraj: --tool-axis-free frees a robot's tool roll: the request has no robot (--robot NAME)\n";
      return false;
    }
    request.mutable_robot()->set_tool_axis_free(true);
  }
  const bool any = !flags.tangent_scales.empty() || !flags.breakpoints.empty() || flags.time_optimal ||
                   flags.jerk_limited || flags.budget_s > 0.0 || flags.length_weight || !flags.redundancy.empty();
  if (!any) return true;  // the request's own `optimize`, if any, stays as it is
  auto* optimize = request.mutable_optimize();
  int value = 0;
  if (!flags.tangent_scales.empty()) {
    if (!enum_value(flags.tangent_scales, "TANGENT_SCALE_OBJECTIVE_", v1::TangentScaleObjective_descriptor(), value)) {
      return false;
    }
    optimize->mutable_tangent_scales()->set_objective(static_cast<v1::TangentScaleObjective>(value));
  }
  if (flags.length_weight) {
    if (!optimize->has_tangent_scales()) {
      std::cerr << "geotraj: --length-weight needs --optimize-tangent-scales (or a request with "
                   "optimize.tangentScales)\n";
      return false;
    }
    optimize->mutable_tangent_scales()->set_length_weight(*flags.length_weight);
  }
  if (!flags.breakpoints.empty()) {
    if (!enum_value(flags.breakpoints, "BREAKPOINT_OBJECTIVE_", v1::BreakpointObjective_descriptor(), value)) {
      return false;
    }
    optimize->mutable_breakpoints()->set_objective(static_cast<v1::BreakpointObjective>(value));
  }
  if (flags.time_optimal) optimize->mutable_timing()->set_time_optimal(true);
  if (flags.jerk_limited) optimize->mutable_timing()->set_jerk_limited(true);
  if (flags.budget_s > 0.0) optimize->set_time_budget_s(flags.budget_s);
  if (!flags.redundancy.empty() && !set_redundancy(flags.redundancy, *optimize->mutable_redundancy())) return false;
  return true;
}

namespace {

void set_deadline(grpc::ClientContext& context, double timeout_s) {
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::microseconds(static_cast<long long>(timeout_s * 1e6)));
}

void print_json(const google::protobuf::Message& message) {
  google::protobuf::util::JsonPrintOptions print;
  print.add_whitespace = true;
  print.always_print_primitive_fields = true;
  std::string json;
  (void)google::protobuf::util::MessageToJsonString(message, &json, print);
  std::cout << json;
  if (json.empty() || json.back() != '\n') std::cout << '\n';
}

// Prints the response (table or JSON) or the error; the exit code.
template <class Response>
int answer(const CallOptions& options, const grpc::Status& status, const Response& response) {
  if (!status.ok()) {
    print_error(status, std::cerr);
    return 1;
  }
  if (options.json) {
    print_json(response);
  } else {
    print_table(response, std::cout);
  }
  return 0;
}

// Reads the request, makes the call, prints the response or the error.
template <class Request, class Response, class Call>
int run(const CallOptions& options, Call call) {
  Request request;
  if constexpr (std::is_same_v<Request, v1::PlanRequest>) {
    if (!read_plan_request(options, request)) return 2;
  } else if (!read_request(options.input, request)) {
    return 2;
  }
  grpc::ClientContext context;
  set_deadline(context, options.unary_timeout_s());
  Response response;
  return answer(options, call(context, request, response), response);
}

}  // namespace

int run_convert(const Connection& connection, const CallOptions& options) {
  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  return run<v1::ConvertRequest, v1::ConvertResponse>(options, [&](auto& context, auto& request, auto& response) {
    return stub->ConvertConstraints(&context, request, &response);
  });
}

int run_plan(const Connection& connection, const CallOptions& options) {
  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  return run<v1::PlanRequest, v1::PlanResponse>(options, [&](auto& context, auto& request, auto& response) {
    return stub->PlanTrajectory(&context, request, &response);
  });
}

int run_analyze(const Connection& connection, const CallOptions& options) {
  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  return run<v1::PlanRequest, v1::PathProfile>(options, [&](auto& context, auto& request, auto& response) {
    return stub->AnalyzePath(&context, request, &response);
  });
}

int run_stream(const Connection& connection, const CallOptions& options) {
  v1::PlanRequest request;
  if (!read_plan_request(options, request)) return 2;
  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  // The expected count, for the progress bar (a plan costs far less than its stream).
  std::uint64_t expected = 0;
  const bool progress = ::isatty(STDERR_FILENO) != 0;
  if (progress) {
    grpc::ClientContext context;
    set_deadline(context, options.unary_timeout_s());
    v1::PlanResponse plan;
    if (stub->PlanTrajectory(&context, request, &plan).ok()) expected = plan.motion().sample_count();
  }
  grpc::ClientContext context;
  if (options.timeout_s > 0.0) set_deadline(context, options.timeout_s);  // else none: see CallOptions
  auto reader = stub->StreamSamples(&context, request);
  bool header_written = options.json;
  const bool sequence = has_steps(request);  // a `step` column after the tool's state
  google::protobuf::util::JsonPrintOptions print;
  print.add_whitespace = false;
  v1::SampleBatch batch;
  std::uint64_t received = 0;
  int shown = -1;
  while (reader->Read(&batch)) {
    for (const auto& s : batch.samples()) {
      if (options.json) {
        std::string json;
        (void)google::protobuf::util::MessageToJsonString(s, &json, print);
        std::cout << json << '\n';
      } else {
        if (!header_written) {
          print_sample_csv_header(s, sequence, std::cout);
          std::cout << '\n';
          header_written = true;
        }
        print_sample_csv(s, sequence, std::cout);
        std::cout << '\n';
      }
    }
    received += static_cast<std::uint64_t>(batch.samples_size());
    if (progress && expected > 0) {
      const int percent = static_cast<int>(100 * received / expected);
      if (percent != shown) {
        shown = percent;
        const int bar = percent / 4;
        std::fprintf(stderr, "\r[%-25.*s] %3d%% %llu/%llu samples", bar, "#########################", percent,
                     static_cast<unsigned long long>(received), static_cast<unsigned long long>(expected));
      }
    }
  }
  if (progress) std::fputc('\n', stderr);
  const grpc::Status status = reader->Finish();
  if (!status.ok()) {
    print_error(status, std::cerr);
    return 1;
  }
  return 0;
}

int run_fk(const Connection& connection, const CallOptions& options) {
  v1::ForwardKinematicsRequest request;
  if (!options.input.empty() && !read_request(options.input, request)) return 2;
  const auto& k = options.kinematics;
  if ((!k.robot.empty() || !k.urdf.empty() || !k.tip_link.empty()) &&
      !set_robot_source(k.robot, k.urdf, k.tip_link, *request.mutable_robot()))
    return 2;
  if (!k.joints.empty()) {
    request.clear_joints();
    for (double q : k.joints) request.add_joints(q);
  }
  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  grpc::ClientContext context;
  set_deadline(context, options.unary_timeout_s());
  v1::ForwardKinematicsResponse response;
  return answer(options, stub->ComputeForwardKinematics(&context, request, &response), response);
}

int run_ik(const Connection& connection, const CallOptions& options) {
  v1::InverseKinematicsRequest request;
  if (!options.input.empty() && !read_request(options.input, request)) return 2;
  const auto& k = options.kinematics;
  if ((!k.robot.empty() || !k.urdf.empty() || !k.tip_link.empty()) &&
      !set_robot_source(k.robot, k.urdf, k.tip_link, *request.mutable_robot()))
    return 2;
  if (!k.seed.empty()) {
    request.mutable_robot()->clear_initial_joints();
    for (double q : k.seed) request.mutable_robot()->add_initial_joints(q);
  }
  if (!k.position.empty()) {
    if (k.position.size() != 3) {
      std::cerr << "geotraj: --position takes x,y,z [m]\n";
      return 2;
    }
    auto* p = request.mutable_target()->mutable_position();
    p->set_x(k.position[0]);
    p->set_y(k.position[1]);
    p->set_z(k.position[2]);
  }
  if (!k.orientation.empty()) {
    if (k.orientation.size() != 4) {
      std::cerr << "geotraj: --orientation takes a quaternion w,x,y,z\n";
      return 2;
    }
    auto* q = request.mutable_target()->mutable_orientation();
    q->set_w(k.orientation[0]);
    q->set_x(k.orientation[1]);
    q->set_y(k.orientation[2]);
    q->set_z(k.orientation[3]);
  }
  if (k.restarts) request.set_restarts(*k.restarts);
  if (k.all_solutions) request.set_all_solutions(true);
  if (k.max_solutions) request.set_max_solutions(*k.max_solutions);
  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  grpc::ClientContext context;
  set_deadline(context, options.unary_timeout_s());
  v1::InverseKinematicsResponse response;
  const int code = answer(options, stub->ComputeInverseKinematics(&context, request, &response), response);
  return code == 0 && !response.reachable() ? 3 : code;
}

int run_robots(const Connection& connection, const CallOptions& options) {
  auto stub = v1::TrajectoryService::NewStub(connection.channel);
  grpc::ClientContext context;
  set_deadline(context, options.unary_timeout_s());
  v1::ListRobotsResponse response;
  return answer(options, stub->ListRobots(&context, v1::ListRobotsRequest{}, &response), response);
}

int run_health(const Connection& connection, const std::string& service, double timeout_s) {
  auto stub = grpc::health::v1::Health::NewStub(connection.channel);
  grpc::ClientContext context;
  set_deadline(context, timeout_s);
  grpc::health::v1::HealthCheckRequest request;
  request.set_service(service);
  grpc::health::v1::HealthCheckResponse response;
  const grpc::Status status = stub->Check(&context, request, &response);
  if (!status.ok()) {
    print_error(status, std::cerr);
    return 1;
  }
  std::cout << grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status()) << '\n';
  return response.status() == grpc::health::v1::HealthCheckResponse::SERVING ? 0 : 1;
}

}  // namespace geotraj::cli
