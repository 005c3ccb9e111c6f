// What a live subcommand (execute, jog) needs from the process: a wake-up pipe for its
// sender thread, the interrupt signals turned into a graceful stop, and the terminal in raw
// mode for single keys, restored however the process ends.
#pragma once

namespace geotraj::cli {

/// One per process at a time (it owns the signal handlers). While it lives:
/// - SIGINT and SIGTERM: the first one wakes wake_fd() and counts (interrupts()): the
///   caller sends a stop and the motion comes to rest; a second one restores the terminal
///   and ends the process by the signal's default action;
/// - SIGHUP and SIGQUIT restore the terminal and end the process at once.
/// The destructor restores the terminal and the previous handlers.
class LiveProcess {
 public:
  LiveProcess();
  ~LiveProcess();
  LiveProcess(const LiveProcess&) = delete;
  LiveProcess& operator=(const LiveProcess&) = delete;

  /// False when the wake-up pipe could not be made (errno says why).
  bool ok() const { return read_fd_ >= 0; }
  /// Standard input in raw mode (each key at once, no echo; Ctrl-C still signals). False
  /// when it is not a terminal, or not this process's foreground terminal.
  bool raw_keys();
  /// Readable after wake() or an interrupt; drain() empties it.
  int wake_fd() const { return read_fd_; }
  /// Wakes whoever polls wake_fd() (any thread).
  void wake() const;
  void drain() const;
  /// The SIGINT and SIGTERM received so far.
  int interrupts() const;

 private:
  int read_fd_ = -1;
};

}  // namespace geotraj::cli
