// StreamReactor, private to server/web: the StreamSamples call of POST /v1/stream read with
// gRPC's callback API, its lines handed to the connection it answers (StreamSink).
#pragma once

#include <memory>
#include <string>
#include <utility>

#include <grpcpp/client_context.h>
#include <grpcpp/support/client_callback.h>

#include "server/ops/tsan.hpp"
#include "server/web/http.hpp"
#include "server/web/session.hpp"

namespace geotraj::server::web_detail {

class StreamReactor;

// Where a stream's lines go: the connection it answers. Called from gRPC's threads; the
// connection takes them on its strand.
class StreamSink {
 public:
  virtual ~StreamSink() = default;
  virtual void stream_line(std::string line, std::string request_id) = 0;
  // The stream's end; the reactor (done) is the connection's to delete.
  virtual void stream_end(grpc::Status status, std::string request_id, StreamReactor* done) = 0;
};

// One StreamSamples call read with gRPC's callback API: no thread waits on it between
// batches. One read at a time: the next starts once the connection has sent the last
// line (a client that reads slowly slows its stream, and holds no more than one batch).
// A hold keeps OnDone back until the connection is done with reads: the stream ends after
// its last read returned, or after its connection went away and the call was cancelled.
class StreamReactor final : public grpc::ClientReadReactor<v1::SampleBatch> {
 public:
  StreamReactor(Shared& shared, std::shared_ptr<StreamSink> sink) : shared_(shared), sink_(std::move(sink)) {}

  void start(Stub& stub, v1::PlanRequest request, const Request& req, const std::string& peer);
  // The connection sent the last line: the next batch.
  void next() {
    handoff_release(this);
    StartRead(&batch_);
  }
  // The connection will read no more (it went away, or a write failed).
  void abandon() {
    context_.TryCancel();
    handoff_release(this);
    RemoveHold();
  }
  void cancel() { context_.TryCancel(); }

  void OnReadDone(bool ok) override {
    handoff_acquire(this);
    if (!ok) {
      RemoveHold();
      return;
    }
    sink_->stream_line(to_json(batch_) + "\n", request_id_of(context_, false));
  }
  void OnDone(const grpc::Status& status) override;

 private:
  Shared& shared_;
  std::shared_ptr<StreamSink> sink_;
  grpc::ClientContext context_;
  v1::PlanRequest request_;
  v1::SampleBatch batch_;
};

}  // namespace geotraj::server::web_detail
