// A live call (Execute, Jog) from a C++ client: what it streamed and how it ended, for the
// tests of live calls.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "geotraj/v1/geotraj.grpc.pb.h"

namespace geotraj::testing {

// What a live call streamed and how it ended.
struct LiveRun {
  grpc::Status status;
  std::string reason;  // the trailer geotraj-stop-reason
  std::vector<v1::Sample> samples;
  v1::LiveStatus last;
  v1::LiveStatus first;  // the first batch's
};

inline std::string trailer(const grpc::ClientContext& context, const std::string& key) {
  const auto& trailers = context.GetServerTrailingMetadata();
  const auto found = trailers.find(key);
  return found == trailers.end() ? "" : std::string(found->second.data(), found->second.size());
}

// Runs a live call: writes `first`, then on each batch calls `on_batch` (which may write);
// a heartbeat follows every batch unless `heartbeats` is false.
template <class Request>
LiveRun run_live(std::unique_ptr<grpc::ClientReaderWriter<Request, v1::SampleBatch>> stream, grpc::ClientContext& context,
                 const Request& first,
                 const std::function<void(grpc::ClientReaderWriter<Request, v1::SampleBatch>&, const LiveRun&)>& on_batch,
                 bool heartbeats = true) {
  LiveRun run;
  stream->Write(first);
  v1::SampleBatch batch;
  while (stream->Read(&batch)) {
    if (run.samples.empty()) run.first = batch.live();
    for (const auto& s : batch.samples()) run.samples.push_back(s);
    run.last = batch.live();
    if (on_batch) on_batch(*stream, run);
    if (heartbeats) {
      Request beat;
      beat.mutable_heartbeat();
      stream->Write(beat);
    }
  }
  stream->WritesDone();
  run.status = stream->Finish();
  run.reason = trailer(context, "geotraj-stop-reason");
  return run;
}

// A client that (optionally) sets a speed override once the samples reach `override_at`
// [s], pauses once they reach `pause_at`, and resumes `hold_s` after the arm reports
// LIVE_STATE_PAUSED: an on_batch of run_live for Execute.
class PauseResume {
 public:
  PauseResume(double pause_at, double hold_s, double override_at = -1.0, double override_percent = 100.0)
      : pause_at_(pause_at), hold_s_(hold_s), override_at_(override_at), override_(override_percent) {
    if (override_at_ < 0.0) step_ = 1;  // no override step
  }
  void operator()(grpc::ClientReaderWriter<v1::ExecuteRequest, v1::SampleBatch>& stream, const LiveRun& r) {
    const double t = r.samples.back().t();
    v1::ExecuteRequest c;
    if (step_ == 0 && t >= override_at_) {
      c.set_speed_override(override_);
    } else if (step_ == 1 && t >= pause_at_) {
      c.mutable_pause();
    } else if (step_ == 2 && r.last.state() == v1::LIVE_STATE_PAUSED) {
      paused_at_ = t;
      ++step_;
      return;
    } else if (step_ == 3 && t >= paused_at_ + hold_s_) {
      c.mutable_resume();
    } else {
      return;
    }
    ++step_;
    stream.Write(c);
  }
  bool resumed() const { return step_ == 4; }  ///< every step taken
  double paused_at() const { return paused_at_; }  ///< when the arm was first seen paused [s]

 private:
  double pause_at_, hold_s_, override_at_, override_;
  int step_ = 0;
  double paused_at_ = 0.0;
};

}  // namespace geotraj::testing
