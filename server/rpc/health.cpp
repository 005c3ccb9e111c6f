#include "server/rpc/health.hpp"

#include <algorithm>

#include <grpcpp/support/server_callback.h>

#include "grpc/health/v1/health.grpc.pb.h"
#include "server/ops/runtime.hpp"

namespace geotraj::server {

using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

void HealthState::set(const std::string& name, bool serving) {
  const std::lock_guard lock(mutex_);
  status_[name] = serving;
  notify();
}

void HealthState::set_all(bool serving) {
  const std::lock_guard lock(mutex_);
  for (auto& [name, status] : status_) status = serving;
  notify();
}

void HealthState::set_accepting(const std::string& listener, bool accepting) {
  const std::lock_guard lock(mutex_);
  if (accepting) {
    not_accepting_.erase(listener);
  } else {
    not_accepting_.insert(listener);
  }
  notify();
}

std::optional<bool> HealthState::get(const std::string& name) const {
  const std::lock_guard lock(mutex_);
  return get_locked(name);
}

std::optional<bool> HealthState::get_locked(const std::string& name) const {
  const auto it = status_.find(name);
  if (it == status_.end()) return std::nullopt;
  return it->second && (not_accepting_.empty() || name != readiness_);
}

void HealthState::subscribe(Watcher* watcher) {
  const std::lock_guard lock(mutex_);
  watchers_.push_back(watcher);
  watcher->health_changed(get_locked(watcher->watched()));
}

void HealthState::unsubscribe(Watcher* watcher) {
  const std::lock_guard lock(mutex_);
  std::erase(watchers_, watcher);
}

bool HealthState::delivered() const {
  const std::lock_guard lock(mutex_);
  return std::all_of(watchers_.begin(), watchers_.end(), [](Watcher* w) { return w->delivered(); });
}

void HealthState::notify() {
  for (Watcher* w : watchers_) w->health_changed(get_locked(w->watched()));
}

namespace {

HealthCheckResponse::ServingStatus to_status(const std::optional<bool>& serving) {
  if (!serving) return HealthCheckResponse::SERVICE_UNKNOWN;
  return *serving ? HealthCheckResponse::SERVING : HealthCheckResponse::NOT_SERVING;
}

// One Watch: the current status, then every change, one write in flight; the newest status
// wins when several changes come during a write.
class HealthWatch final : public grpc::ServerWriteReactor<HealthCheckResponse>, public HealthState::Watcher {
 public:
  HealthWatch(std::shared_ptr<HealthState> state, std::shared_ptr<Runtime> runtime, std::string name)
      : state_(std::move(state)), runtime_(std::move(runtime)), name_(std::move(name)) {
    if (auto refused = runtime_->begin_watch()) {
      const std::lock_guard lock(mutex_);
      finished_ = true;
      Finish(*refused);
      return;
    }
    admitted_ = true;
    state_->subscribe(this);  // sends the status now
  }

  const std::string& watched() const override { return name_; }

  void health_changed(std::optional<bool> serving) override {
    const std::lock_guard lock(mutex_);
    latest_ = to_status(serving);
    if (finished_) return;
    if (writing_) {
      pending_ = true;
      return;
    }
    WriteIfChanged();
  }

  bool delivered() override {
    const std::lock_guard lock(mutex_);
    return finished_ || (!writing_ && !pending_ && sent_ && last_ == latest_);
  }

  void OnWriteDone(bool ok) override {
    const std::lock_guard lock(mutex_);
    writing_ = false;
    if (!ok) {
      End(grpc::Status(grpc::StatusCode::CANCELLED, "the watch ended"));
      return;
    }
    if (pending_ && !finished_) {
      pending_ = false;
      WriteIfChanged();
    }
  }

  void OnCancel() override {
    const std::lock_guard lock(mutex_);
    End(grpc::Status(grpc::StatusCode::CANCELLED, "the watch was cancelled"));
  }

  void OnDone() override {
    if (admitted_) {
      state_->unsubscribe(this);
      runtime_->end_watch();
    }
    delete this;
  }

 private:
  void End(const grpc::Status& status) {  // mutex_ held
    if (finished_) return;
    finished_ = true;
    Finish(status);
  }

  void WriteIfChanged() {  // mutex_ held, no write in flight
    const auto status = latest_;
    if (sent_ && status == last_) return;
    sent_ = true;
    last_ = status;
    response_.set_status(status);
    writing_ = true;
    StartWrite(&response_);
  }

  std::shared_ptr<HealthState> state_;
  std::shared_ptr<Runtime> runtime_;
  const std::string name_;
  std::mutex mutex_;
  bool admitted_ = false;
  bool finished_ = false;
  bool writing_ = false;
  bool pending_ = false;
  bool sent_ = false;
  HealthCheckResponse::ServingStatus last_ = HealthCheckResponse::UNKNOWN;    // last sent
  HealthCheckResponse::ServingStatus latest_ = HealthCheckResponse::UNKNOWN;  // newest known
  HealthCheckResponse response_;
};

class HealthService final : public grpc::health::v1::Health::CallbackService {
 public:
  HealthService(std::shared_ptr<HealthState> state, std::shared_ptr<Runtime> runtime)
      : state_(std::move(state)), runtime_(std::move(runtime)) {}

  grpc::ServerUnaryReactor* Check(grpc::CallbackServerContext* context, const HealthCheckRequest* request,
                                  HealthCheckResponse* response) override {
    auto* reactor = context->DefaultReactor();
    const auto serving = state_->get(request->service());
    if (!serving) {
      reactor->Finish(grpc::Status(grpc::StatusCode::NOT_FOUND, "no health status for this service name"));
      return reactor;
    }
    response->set_status(to_status(serving));
    reactor->Finish(grpc::Status::OK);
    return reactor;
  }

  grpc::ServerWriteReactor<HealthCheckResponse>* Watch(grpc::CallbackServerContext* /*context*/,
                                                       const HealthCheckRequest* request) override {
    return new HealthWatch(state_, runtime_, request->service());
  }

 private:
  std::shared_ptr<HealthState> state_;
  std::shared_ptr<Runtime> runtime_;
};

}  // namespace

std::unique_ptr<grpc::Service> make_health_service(std::shared_ptr<HealthState> state,
                                                   std::shared_ptr<Runtime> runtime) {
  return std::make_unique<HealthService>(std::move(state), std::move(runtime));
}

}  // namespace geotraj::server
