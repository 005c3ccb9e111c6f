// geotrajd: serves the geotraj gRPC API (plaintext) until SIGINT or SIGTERM.
#include <pthread.h>
#include <signal.h>

#include <chrono>
#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>

#include "geotraj/server/server.hpp"

int main(int argc, char** argv) {
  geotraj::server::ServerOptions options;
  double grace_s = 5.0;
  CLI::App app{"geotrajd: the geotraj trajectory service (gRPC, plaintext). Every flag also reads "
               "the environment variable named beside it."};
  app.add_option("--address", options.address, "listening address HOST:PORT (port 0: any free port)")
      ->envname("GEOTRAJ_ADDRESS")
      ->capture_default_str();
  app.add_option("--shutdown-grace", grace_s,
                 "seconds that calls in flight may finish after SIGINT/SIGTERM; then they are cancelled "
                 "and idle client connections closed")
      ->envname("GEOTRAJ_SHUTDOWN_GRACE")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-request-bytes", options.max_receive_message_bytes, "largest request message [bytes]")
      ->envname("GEOTRAJ_MAX_REQUEST_BYTES")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--robot-model", options.robot_model_files,
                 "robot model file (proto3 JSON of geotraj.v1.RobotModel, as ListRobots prints it), served by its "
                 "name beside the built-in models; repeat for several (environment: comma-separated)")
      ->envname("GEOTRAJ_ROBOT_MODELS")
      ->delimiter(',');
  CLI11_PARSE(app, argc, argv);

  // Block the stop signals in every thread (gRPC's threads inherit the mask) and take them
  // synchronously below, so no handler runs in an arbitrary thread.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  auto running = geotraj::server::start_server(options);
  if (!running) {
    std::fprintf(stderr, "geotrajd: %s\n", running.error().c_str());
    return 1;
  }
  const auto host = options.address.substr(0, options.address.rfind(':'));
  std::printf("geotrajd: serving %s on %s:%d (health SERVING, reflection on)\n", geotraj::server::kServiceName,
              host.c_str(), running->port);
  std::fflush(stdout);

  int signal = 0;
  sigwait(&stop_signals, &signal);
  std::printf("geotrajd: %s received, shutting down (grace %.3g s)\n", signal == SIGINT ? "SIGINT" : "SIGTERM",
              grace_s);
  std::fflush(stdout);
  geotraj::server::stop_server(*running, std::chrono::milliseconds(static_cast<long long>(grace_s * 1000.0)));
  return 0;
}
