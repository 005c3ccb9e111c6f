// StreamReactor's members (stream_reactor.hpp): the call started, and its end handed to its
// connection.
#include "server/web/stream_reactor.hpp"

#include <mutex>
#include <utility>

namespace geotraj::server::web_detail {

void StreamReactor::start(Stub& stub, v1::PlanRequest request, const Request& req, const std::string& peer) {
  request_ = std::move(request);
  (void)pass_on(req, peer, context_);  // checked by the caller
  {
    const std::lock_guard lock(shared_.reactors_mutex);
    ++shared_.reactors;
  }
  stub.async()->StreamSamples(&context_, &request_, this);
  AddHold();
  handoff_release(this);
  StartRead(&batch_);
  StartCall();
}

void StreamReactor::OnDone(const grpc::Status& status) {
  handoff_acquire(this);
  // The connection deletes the reactor on its strand: until then it may still refer to it.
  Shared& shared = shared_;
  shared.streams.fetch_sub(1);
  {
    // This may be the connection's last reference: it goes (and the connection with it, on
    // this thread) before the count below says the reactor is done, so that a gateway
    // stopping, which waits for that count, never tears its io_context down under it.
    const auto sink = std::move(sink_);
    sink->stream_end(status, request_id_of(context_, true), this);
  }
  const std::lock_guard lock(shared.reactors_mutex);
  if (--shared.reactors == 0) shared.reactors_done.notify_all();
}

}  // namespace geotraj::server::web_detail
