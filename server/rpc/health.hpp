// grpc.health.v1.Health, served by geotrajd itself rather than gRPC's default service, so
// that Watch streams count against --max-streams (gRPC's default service serves any number,
// with no cap and no token) and readiness can follow the acceptor.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <grpcpp/impl/service_type.h>

namespace geotraj::server {

class Runtime;

/// The serving status of each health service name, shared by the health services of the
/// gRPC port and of the health-only port. Thread-safe.
class HealthState {
 public:
  /// Someone to tell when a status may have changed (a Watch stream).
  class Watcher {
   public:
    /// The name watched.
    virtual const std::string& watched() const = 0;
    /// Its status now (SERVING, NOT_SERVING, or nullopt: not known). Called with the
    /// state's lock held: it must not call back into the state.
    virtual void health_changed(std::optional<bool> serving) = 0;
    /// Whether the newest status it was told has been written to its client (or the watch
    /// has ended). Called with the state's lock held.
    virtual bool delivered() = 0;

   protected:
    ~Watcher() = default;
  };

  /// Sets `name`'s status ("" is the server as a whole).
  void set(const std::string& name, bool serving);
  /// Sets every known name's status.
  void set_all(bool serving);
  /// Readiness also needs the ports to accept connections (acceptor.hpp): while one of them
  /// (`listener`) cannot, `readiness` reads NOT_SERVING whatever was set.
  void set_accepting(const std::string& listener, bool accepting);
  void set_readiness_name(std::string readiness) { readiness_ = std::move(readiness); }

  /// SERVING (true), NOT_SERVING (false), or nullopt for a name not known.
  std::optional<bool> get(const std::string& name) const;

  /// Tells `watcher` the status now, then at every change (the first under the same lock
  /// as the changes, so it is never older than one that follows).
  void subscribe(Watcher* watcher);
  /// After it returns, `watcher` is not called again.
  void unsubscribe(Watcher* watcher);
  /// Whether every watcher has written the newest status (a drain waits for it, within its
  /// time, so that each Watch sees NOT_SERVING before the server ends it).
  bool delivered() const;

 private:
  void notify();  // mutex_ held
  std::optional<bool> get_locked(const std::string& name) const;

  mutable std::mutex mutex_;
  std::map<std::string, bool, std::less<>> status_;
  std::vector<Watcher*> watchers_;
  std::set<std::string, std::less<>> not_accepting_;  // listeners that cannot accept now
  std::string readiness_;
};

/// A grpc.health.v1.Health service on `state`: Check answers at once on gRPC's thread
/// (NOT_FOUND for an unknown name, as the protocol says); Watch sends the status now and at
/// every change, admitted against the runtime's stream cap.
std::unique_ptr<grpc::Service> make_health_service(std::shared_ptr<HealthState> state,
                                                   std::shared_ptr<Runtime> runtime);

}  // namespace geotraj::server
