// geotrajd as a child process (the binary of tests/support/build_paths.hpp): its arguments
// and environment, its standard output read line by line, its standard error read at the end,
// signals and its exit code.
#pragma once

#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "tests/support/build_paths.hpp"

namespace geotraj::testing {

class Daemon {
 public:
  /// Starts geotrajd with `args`, after setting `env` (name, value) in the child.
  /// With `open_files` > 0, the child's descriptor limit (soft and hard) is set to it.
  explicit Daemon(const std::vector<std::string>& args,
                  const std::vector<std::pair<std::string, std::string>>& env = {}, long open_files = 0) {
    int out[2], err[2];
    if (::pipe(out) != 0 || ::pipe(err) != 0) return;
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(out[1], STDOUT_FILENO);
      ::dup2(err[1], STDERR_FILENO);
      for (int fd : {out[0], out[1], err[0], err[1]}) ::close(fd);
      for (const auto& [name, value] : env) ::setenv(name.c_str(), value.c_str(), 1);
      if (open_files > 0) {
        const rlimit limit{static_cast<rlim_t>(open_files), static_cast<rlim_t>(open_files)};
        if (::setrlimit(RLIMIT_NOFILE, &limit) != 0) std::_Exit(126);
      }
      std::vector<char*> argv{const_cast<char*>(build_paths::geotrajd())};
      for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
      argv.push_back(nullptr);
      ::execv(build_paths::geotrajd(), argv.data());
      std::_Exit(127);
    }
    ::close(out[1]);
    ::close(err[1]);
    out_ = out[0];
    err_ = err[0];
  }
  ~Daemon() {
    if (pid_ > 0 && !reaped_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    for (int fd : {out_, err_}) {
      if (fd >= 0) ::close(fd);
    }
  }
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  bool started() const { return pid_ > 0 && out_ >= 0 && err_ >= 0; }
  void signal(int sig) { ::kill(pid_, sig); }

  /// The next line of its standard output with its newline; "" at end of file or after
  /// `timeout`.
  std::string line(std::chrono::milliseconds timeout = std::chrono::seconds(60)) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      if (const auto nl = buffer_.find('\n'); nl != std::string::npos) {
        std::string l = buffer_.substr(0, nl + 1);
        buffer_.erase(0, nl + 1);
        return l;
      }
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(until - std::chrono::steady_clock::now()).count();
      if (left <= 0) return "";
      pollfd p{out_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left)) <= 0) continue;
      char buf[512];
      const auto n = ::read(out_, buf, sizeof buf);
      if (n <= 0) return "";
      buffer_.append(buf, static_cast<std::size_t>(n));
    }
  }

  /// Its whole standard error, to end of file (call once it has exited, or is exiting).
  std::string errors() {
    std::string text;
    char buf[512];
    for (ssize_t n; (n = ::read(err_, buf, sizeof buf)) > 0;) text.append(buf, static_cast<std::size_t>(n));
    return text;
  }

  /// Its exit code once it has exited (-1 when a signal ended it), or nullopt after `timeout`.
  std::optional<int> wait(std::chrono::milliseconds timeout) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        reaped_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      }
      if (std::chrono::steady_clock::now() >= until) return std::nullopt;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  /// Its exit code, waiting as long as it takes (-1 when a signal ended it).
  int wait() { return *wait(std::chrono::hours(24)); }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  int err_ = -1;
  bool reaped_ = false;
  std::string buffer_;
};

/// The port of geotrajd's first line, "geotrajd: serving ... on HOST:PORT (...)"; 0 if none.
inline int port_of(const std::string& line) {
  const auto paren = line.find(" (");
  const auto colon = line.rfind(':', paren);
  if (paren == std::string::npos || colon == std::string::npos) return 0;
  return std::atoi(line.substr(colon + 1, paren - colon - 1).c_str());
}

}  // namespace geotraj::testing
