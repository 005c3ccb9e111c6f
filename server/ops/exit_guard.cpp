#include <atomic>
#include <cstdio>
#include <cstdlib>

#include <unistd.h>

#include "server/ops/exit_guard.hpp"

namespace geotraj::server {
namespace {

std::atomic<bool> exit_allowed{true};

void on_exit() {
  if (exit_allowed.load()) return;
  static constexpr char kMessage[] =
      "geotrajd: the process was ended by a library call to exit(), not by a shutdown: exiting with status 70\n";
  (void)!::write(STDERR_FILENO, kMessage, sizeof kMessage - 1);
  ::_exit(kAbnormalExitStatus);
}

}  // namespace

void guard_exit() {
  static const bool registered = std::atexit(on_exit) == 0;
  (void)registered;
  exit_allowed.store(false);
}

void allow_exit() { exit_allowed.store(true); }

}  // namespace geotraj::server
