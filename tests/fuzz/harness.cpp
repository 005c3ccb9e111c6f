#include "harness.hpp"

#include <time.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <thread>
#include <utility>
#include <vector>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/stubs/logging.h>
#include <grpcpp/client_context.h>
#include <grpcpp/create_channel.h>
#include <grpcpp/server.h>
#include <grpcpp/support/channel_arguments.h>

#include "google/rpc/status.pb.h"
#include "server/server.hpp"
#include "server/wire/convert.hpp"

namespace geotraj::fuzz {
namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::Reflection;

struct InProcess {
  server::RunningServer running;
  std::unique_ptr<v1::TrajectoryService::Stub> stub;
};

InProcess& in_process() {
  // Leaked on purpose: the server serves every input of the run and ends with the process.
  static InProcess* const instance = [] {
    server::ServerOptions options;
    options.address.clear();  // no port: InProcessChannel only
    options.plaintext = true;  // nothing is exposed; some server versions ask for it with an empty address
    options.log_level = "error";  // one line per call would drown libFuzzer's output
    auto started = server::start_server(options);
    if (!started) {
      std::fprintf(stderr, "fuzz harness: cannot start the server: %s\n", started.error().c_str());
      std::abort();
    }
    auto* result = new InProcess{std::move(*started), nullptr};
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(-1);  // large answers are the service's business, not the channel's
    result->stub = v1::TrajectoryService::NewStub(result->running.server->InProcessChannel(args));
    return result;
  }();
  return *instance;
}

// GEOTRAJ_FUZZ_TRACE=1: one line per call on stderr (status, time, the server's overrun).
bool tracing() {
  static const bool on = [] {
    const char* value = std::getenv("GEOTRAJ_FUZZ_TRACE");
    return value != nullptr && value[0] != '\0' && value[0] != '0';
  }();
  return on;
}

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

void trace(std::string_view rpc, const grpc::Status& status, Clock::time_point start, double overrun) {
  if (!tracing()) return;
  std::fprintf(stderr, "[fuzz] %-18.*s %-3d %7.3f s (server overrun %.3f s) %s\n", static_cast<int>(rpc.size()),
               rpc.data(), static_cast<int>(status.error_code()), seconds_since(start), overrun,
               status.error_message().substr(0, 160).c_str());
}

void set_deadline(grpc::ClientContext& context) {
  context.set_deadline(std::chrono::system_clock::now() + kCallDeadline);
}

// kServerGrace, or GEOTRAJ_FUZZ_SERVER_GRACE_S [s].
std::chrono::steady_clock::duration server_grace() {
  static const auto grace = [] {
    const char* value = std::getenv("GEOTRAJ_FUZZ_SERVER_GRACE_S");
    if (value == nullptr || value[0] == '\0') return std::chrono::duration_cast<std::chrono::steady_clock::duration>(kServerGrace);
    return std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(std::atof(value)));
  }();
  return grace;
}

double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// After DEADLINE_EXCEEDED the client has its answer, but the server may still be working
// on the call (it checks the deadline between stages). Waits until the process is idle (the
// harness thread sleeps, so the CPU time is the server's), and calls it a hang when the
// server goes on for more than server_grace() of CPU time: an input whose work would
// otherwise run on, unseen, beside the following ones. CPU time, not wall time, so that the
// check does not depend on the machine's load; libFuzzer's -timeout bounds the wall time.
// Returns how long it waited [s].
double wait_for_idle_server(std::string_view rpc, const Message& request) {
  constexpr auto kWindow = std::chrono::milliseconds(50);
  constexpr double kIdleCpu = 0.2;  // of one core, over a window
  const double grace = std::chrono::duration<double>(server_grace()).count();
  const auto start = Clock::now();
  const double cpu_at_start = process_cpu_seconds();
  for (;;) {
    const double before = process_cpu_seconds();
    std::this_thread::sleep_for(kWindow);
    const double now = process_cpu_seconds();
    if (now - before < kIdleCpu * std::chrono::duration<double>(kWindow).count()) return seconds_since(start);
    if (now - cpu_at_start > grace) {
      fail(std::string(rpc) + ": the server went on computing for " + std::to_string(now - cpu_at_start) +
               " CPU seconds after the call's deadline passed (a stage of work that does not check the deadline)",
           request);
    }
  }
}

// One step of the path to a field, formatted only when a check fails.
struct Step {
  const FieldDescriptor* field;
  int index;  // -1: not repeated
};

std::string format_path(const std::vector<Step>& steps) {
  std::string path;
  for (const auto& step : steps) {
    if (!path.empty()) path += '.';
    path += step.field->json_name();
    if (step.index >= 0) path += "[" + std::to_string(step.index) + "]";
  }
  return path;
}

struct FiniteWalk {
  std::string_view what;
  const Message& context;
  std::vector<Step> steps;

  void value(double v) {
    if (std::isfinite(v)) return;
    fail(std::string(what) + ": " + format_path(steps) + " = " + std::to_string(v) + " is not finite", context);
  }

  void message(const Message& m) {
    const Reflection* reflection = m.GetReflection();
    std::vector<const FieldDescriptor*> fields;
    reflection->ListFields(m, &fields);
    for (const FieldDescriptor* field : fields) {
      const auto type = field->cpp_type();
      if (type != FieldDescriptor::CPPTYPE_DOUBLE && type != FieldDescriptor::CPPTYPE_FLOAT &&
          type != FieldDescriptor::CPPTYPE_MESSAGE) {
        continue;
      }
      if (field->is_repeated()) {
        const int n = reflection->FieldSize(m, field);
        for (int i = 0; i < n; ++i) {
          steps.push_back({field, i});
          if (type == FieldDescriptor::CPPTYPE_DOUBLE) {
            value(reflection->GetRepeatedDouble(m, field, i));
          } else if (type == FieldDescriptor::CPPTYPE_FLOAT) {
            value(static_cast<double>(reflection->GetRepeatedFloat(m, field, i)));
          } else {
            message(reflection->GetRepeatedMessage(m, field, i));
          }
          steps.pop_back();
        }
      } else {
        steps.push_back({field, -1});
        if (type == FieldDescriptor::CPPTYPE_DOUBLE) {
          value(reflection->GetDouble(m, field));
        } else if (type == FieldDescriptor::CPPTYPE_FLOAT) {
          value(static_cast<double>(reflection->GetFloat(m, field)));
        } else {
          message(reflection->GetMessage(m, field));
        }
        steps.pop_back();
      }
    }
  }
};

// The checks after a unary call.
void check_unary(const grpc::Status& status, const Message& response, std::string_view rpc, const Message& request,
                 Clock::time_point start) {
  const double overrun =
      status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED ? wait_for_idle_server(rpc, request) : 0.0;
  trace(rpc, status, start, overrun);
  require_status(status, rpc, request);
  if (status.ok()) require_finite(response, std::string(rpc) + " response", request);
}

}  // namespace

void initialize() {
  google::protobuf::SetLogHandler([](google::protobuf::LogLevel level, const char* file, int line,
                                     const std::string& message) {
    if (level >= google::protobuf::LOGLEVEL_FATAL) std::fprintf(stderr, "[libprotobuf %s:%d] %s\n", file, line, message.c_str());
  });
  (void)stub();
}

v1::TrajectoryService::Stub& stub() { return *in_process().stub; }

[[noreturn]] void fail(std::string_view why, const Message& request) {
  std::string text = request.ShortDebugString();
  constexpr std::size_t kMaxText = 4000;
  if (text.size() > kMaxText) text = text.substr(0, kMaxText) + " ...";
  std::fprintf(stderr, "\n==== geotraj fuzz check failed: %.*s\n==== request (%s): %s\n\n", static_cast<int>(why.size()),
               why.data(), request.GetTypeName().c_str(), text.c_str());
  std::fflush(stderr);
  std::abort();
}

void require_finite(const Message& message, std::string_view what, const Message& context) {
  FiniteWalk walk{what, context, {}};
  walk.message(message);
}

void require_status(const grpc::Status& status, std::string_view rpc, const Message& request) {
  switch (status.error_code()) {
    case grpc::StatusCode::UNKNOWN:
    case grpc::StatusCode::INTERNAL:
    case grpc::StatusCode::UNIMPLEMENTED:
    case grpc::StatusCode::DATA_LOSS:
      fail(std::string(rpc) + ": status " + std::to_string(status.error_code()) + " (" + status.error_message() + ")",
           request);
    default:
      break;
  }
  if (!status.error_details().empty()) {
    google::rpc::Status details;
    if (!details.ParseFromString(status.error_details())) {
      fail(std::string(rpc) + ": the error details are not a google.rpc.Status", request);
    }
    if (details.code() != static_cast<int>(status.error_code())) {
      fail(std::string(rpc) + ": the error details' code " + std::to_string(details.code()) +
               " differs from the status code " + std::to_string(status.error_code()),
           request);
    }
  }
}

void check_plan_request(const v1::PlanRequest& request) {
  auto& service = stub();
  bool planning_timed_out = false;
  {
    const auto start = Clock::now();
    grpc::ClientContext context;
    set_deadline(context);
    v1::PlanResponse response;
    const auto status = service.PlanTrajectory(&context, request, &response);
    check_unary(status, response, "PlanTrajectory", request, start);
    planning_timed_out = status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED;
  }
  {
    const auto start = Clock::now();
    grpc::ClientContext context;
    set_deadline(context);
    v1::PathProfile response;
    grpc::Status status;
    if (request.has_analysis_points() && request.analysis_points() > kFuzzAnalysisPoints &&
        request.analysis_points() <= server::ServiceLimits{}.max_analysis_points) {
      v1::PlanRequest fewer = request;
      fewer.set_analysis_points(kFuzzAnalysisPoints);
      status = service.AnalyzePath(&context, fewer, &response);
    } else {
      status = service.AnalyzePath(&context, request, &response);
    }
    check_unary(status, response, "AnalyzePath", request, start);
  }
  // StreamSamples plans as PlanTrajectory does (the same stages, robot pass included)
  // before its first batch: when that planning ran out of time, so would the stream's.
  if (planning_timed_out) return;
  {
    const auto start = Clock::now();
    grpc::ClientContext context;
    set_deadline(context);
    auto reader = service.StreamSamples(&context, request);
    v1::SampleBatch batch;
    int batches = 0;
    bool cancelled = false;
    while (reader->Read(&batch)) {
      require_finite(batch, "StreamSamples batch " + std::to_string(batches), request);
      if (++batches >= kMaxStreamBatches) {
        context.TryCancel();
        cancelled = true;
        break;
      }
    }
    const auto status = reader->Finish();
    const double overrun = status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED
                               ? wait_for_idle_server("StreamSamples", request)
                               : 0.0;
    trace("StreamSamples", status, start, overrun);
    if (status.error_code() == grpc::StatusCode::CANCELLED && !cancelled) {
      fail("StreamSamples: CANCELLED although the client did not cancel (" + status.error_message() + ")", request);
    }
    require_status(status, "StreamSamples", request);
  }
}

namespace {

// One unary call of the stub's `method` on `request`, with the deadline, checked.
template <class Response, class Request, class Method>
void checked_call(const Request& request, std::string_view rpc, Method method) {
  const auto start = Clock::now();
  grpc::ClientContext context;
  set_deadline(context);
  Response response;
  const auto status = (stub().*method)(&context, request, &response);
  check_unary(status, response, rpc, request, start);
}

}  // namespace

namespace {

// One live call of `open` with `messages`, checked (see check_execute).
template <class Request, class Open>
void check_live(std::vector<Request> messages, std::string_view rpc, Open open) {
  const auto start = Clock::now();
  grpc::ClientContext context;
  set_deadline(context);
  auto stream = open(context);
  std::size_t next = 0;
  stream->Write(messages[next++]);
  v1::SampleBatch batch;
  int after_last = 0;
  bool cancelled = false;
  while (stream->Read(&batch)) {
    require_finite(batch, std::string(rpc) + " batch", messages.front());
    if (next < messages.size()) {
      stream->Write(messages[next++]);
    } else if (++after_last >= kMaxStreamBatches) {
      context.TryCancel();
      cancelled = true;
      break;
    }
  }
  const auto status = stream->Finish();
  const double overrun =
      status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED ? wait_for_idle_server(rpc, messages.front()) : 0.0;
  trace(rpc, status, start, overrun);
  if (status.error_code() == grpc::StatusCode::CANCELLED && !cancelled) {
    fail(std::string(rpc) + ": CANCELLED although the client did not cancel (" + status.error_message() + ")",
         messages.front());
  }
  require_status(status, rpc, messages.front());
}

}  // namespace

void check_execute(const std::vector<v1::ExecuteRequest>& messages) {
  auto run = messages;
  for (auto& m : run) {
    if (m.has_plan()) {
      auto* motion = m.mutable_plan()->mutable_motion();
      if (motion->cycle_rate_hz() > kFuzzLiveRateHz && motion->cycle_rate_hz() <= 1e5) {
        motion->set_cycle_rate_hz(kFuzzLiveRateHz);
      }
    }
  }
  check_live(std::move(run), "Execute", [](grpc::ClientContext& context) { return stub().Execute(&context); });
}

void check_jog(const std::vector<v1::JogRequest>& messages) {
  auto run = messages;
  for (auto& m : run) {
    if (m.has_start() && m.start().cycle_rate_hz() > kFuzzLiveRateHz && m.start().cycle_rate_hz() <= 1e4) {
      m.mutable_start()->set_cycle_rate_hz(kFuzzLiveRateHz);
    }
  }
  check_live(std::move(run), "Jog", [](grpc::ClientContext& context) { return stub().Jog(&context); });
}

void check_convert_request(const v1::ConvertRequest& request) {
  checked_call<v1::ConvertResponse>(request, "ConvertConstraints", &v1::TrajectoryService::Stub::ConvertConstraints);
}

void check_kinematics_request(const v1::ForwardKinematicsRequest& request) {
  checked_call<v1::ForwardKinematicsResponse>(request, "ComputeForwardKinematics",
                                              &v1::TrajectoryService::Stub::ComputeForwardKinematics);
}

void check_kinematics_request(const v1::InverseKinematicsRequest& request) {
  v1::InverseKinematicsRequest bounded = request;
  if (request.has_restarts() && request.restarts() > kFuzzIkRestarts && request.restarts() <= 100000) {
    bounded.set_restarts(kFuzzIkRestarts);
  }
  checked_call<v1::InverseKinematicsResponse>(bounded, "ComputeInverseKinematics",
                                              &v1::TrajectoryService::Stub::ComputeInverseKinematics);
}

}  // namespace geotraj::fuzz
