// The fuzz targets' shared harness: the real TrajectoryService, started once in process
// (start_server with an empty address), called through a stub on its in-process channel,
// and the checks every answer must pass. A failed check prints what failed and the request
// (text format), then aborts: libFuzzer saves the input as crash-<sha1>.
//
// What a fuzzed request may get: any status but UNKNOWN, INTERNAL, UNIMPLEMENTED and
// DATA_LOSS (the service answers bad input with INVALID_ARGUMENT or FAILED_PRECONDITION,
// slow input with DEADLINE_EXCEEDED), error details that parse as a google.rpc.Status with
// the same code, and responses whose every double and float is finite.
//
// Environment: GEOTRAJ_FUZZ_TRACE=1 prints one line per call (status, time, the server's
// work after the deadline); GEOTRAJ_FUZZ_SERVER_GRACE_S overrides kServerGrace.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <google/protobuf/message.h>
#include <grpcpp/support/status.h>

#include "geotraj/v1/geotraj.grpc.pb.h"

namespace geotraj::fuzz {

/// Each RPC's deadline: a slow input ends with DEADLINE_EXCEEDED instead of hanging the
/// fuzzer (libFuzzer's -timeout bounds the whole input).
inline constexpr std::chrono::milliseconds kCallDeadline{2000};

/// CPU time the server may go on spending on a call after its deadline passed before the
/// harness calls it a hang (the service checks its deadline between stages of work).
/// Generous: the fuzz build is ASan + UBSan at -O1, 5-10 times slower than a release build.
/// GEOTRAJ_FUZZ_SERVER_GRACE_S overrides it.
inline constexpr std::chrono::milliseconds kServerGrace{5000};

/// AnalyzePath: a fuzzed analysisPoints in (kFuzzAnalysisPoints, 1000000] is lowered to
/// this. core::analyze runs as one stage without deadline checks, and 40001 points (the
/// appendix B examples) take 2-15 s under the sanitizers on a loaded 2-core machine: the
/// fuzzer would spend its time there, and the server-overrun check would fire on valid
/// requests. Counts outside [2, 1000000] are passed on unchanged (INVALID_ARGUMENT).
inline constexpr std::uint32_t kFuzzAnalysisPoints = 1001;

/// StreamSamples: batches read before the harness cancels the stream.
inline constexpr int kMaxStreamBatches = 4;

/// For LLVMFuzzerInitialize: starts the server (so that its start-up is not charged to the
/// first input) and silences protobuf's log (a fuzzed message with invalid UTF-8 in a
/// string field logs an error each time it is parsed).
void initialize();

/// The stub of the in-process server, started on first use and never stopped.
v1::TrajectoryService::Stub& stub();

/// PlanTrajectory, AnalyzePath and StreamSamples on `request`, each checked (AnalyzePath
/// with analysisPoints lowered to kFuzzAnalysisPoints, see there; StreamSamples skipped
/// when PlanTrajectory ran out of time, as its planning is the same).
void check_plan_request(const v1::PlanRequest& request);

/// ConvertConstraints on `request`, checked.
void check_convert_request(const v1::ConvertRequest& request);

/// ComputeInverseKinematics: a fuzzed restarts above this is lowered to it (a valid 100000
/// restarts is a second of solves, ten under the sanitizers: the deadline would end it, and
/// the fuzzer would spend its time there). Larger values are passed on (INVALID_ARGUMENT).
inline constexpr std::uint32_t kFuzzIkRestarts = 1000;

/// ComputeForwardKinematics and ComputeInverseKinematics on `request`, checked.
void check_kinematics_request(const v1::ForwardKinematicsRequest& request);
void check_kinematics_request(const v1::InverseKinematicsRequest& request);

/// Execute and Jog: the most messages of one fuzzed call (harness of fuzz_live).
inline constexpr std::size_t kMaxLiveMessages = 8;

/// Execute with `messages` (the first opens the call; each later one follows a batch read),
/// cancelled after kMaxStreamBatches batches past the last message; every batch finite, the
/// status allowed. A plan's cycle rate above kFuzzLiveRateHz is lowered to it (a fuzzed 1e5 Hz
/// plan is 100 samples per 10 ms batch of IK: the fuzzer would spend its time there).
void check_execute(const std::vector<v1::ExecuteRequest>& messages);
/// Jog with `messages`, the same way.
void check_jog(const std::vector<v1::JogRequest>& messages);
inline constexpr double kFuzzLiveRateHz = 1000.0;

/// Aborts (after printing `what`, the field path and `context`) when some double or float
/// of `message`, at any depth, repeated or not, is NaN or infinite.
void require_finite(const google::protobuf::Message& message, std::string_view what,
                    const google::protobuf::Message& context);

/// Aborts when `status` is a code that no request may produce, or carries error details
/// that are not a google.rpc.Status of the same code.
void require_status(const grpc::Status& status, std::string_view rpc, const google::protobuf::Message& request);

/// Prints `why` and the request (text format, truncated), then aborts.
[[noreturn]] void fail(std::string_view why, const google::protobuf::Message& request);

}  // namespace geotraj::fuzz
