#include "terminal.hpp"

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>

namespace geotraj::cli {
namespace {

// Shared with the signal handler: only async-signal-safe calls on them (write, tcsetattr,
// signal, raise).
volatile std::sig_atomic_t g_interrupts = 0;
volatile std::sig_atomic_t g_raw = 0;  // 1 while stdin is in raw mode and g_saved holds its modes
int g_wake_write = -1;
termios g_saved{};

constexpr int kSignals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT};
struct sigaction g_previous[sizeof kSignals / sizeof kSignals[0]];

void restore_terminal() {
  if (g_raw != 0) {
    (void)::tcsetattr(STDIN_FILENO, TCSAFLUSH, &g_saved);
    g_raw = 0;
  }
}

extern "C" void on_signal(int sig) {
  const int saved_errno = errno;
  if ((sig == SIGINT || sig == SIGTERM) && g_interrupts == 0) {
    g_interrupts = 1;
    if (g_wake_write >= 0) (void)!::write(g_wake_write, "!", 1);
    errno = saved_errno;
    return;
  }
  restore_terminal();
  std::signal(sig, SIG_DFL);
  std::raise(sig);
  errno = saved_errno;
}

}  // namespace

LiveProcess::LiveProcess() {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC | O_NONBLOCK) != 0) return;
  read_fd_ = fds[0];
  g_wake_write = fds[1];
  g_interrupts = 0;
  struct sigaction action {};
  action.sa_handler = on_signal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;
  for (std::size_t i = 0; i < sizeof kSignals / sizeof kSignals[0]; ++i) {
    (void)::sigaction(kSignals[i], &action, &g_previous[i]);
  }
}

LiveProcess::~LiveProcess() {
  if (read_fd_ < 0) return;
  for (std::size_t i = 0; i < sizeof kSignals / sizeof kSignals[0]; ++i) {
    (void)::sigaction(kSignals[i], &g_previous[i], nullptr);
  }
  restore_terminal();
  ::close(g_wake_write);
  g_wake_write = -1;
  ::close(read_fd_);
}

bool LiveProcess::raw_keys() {
  // Only in the foreground: a background process that changes the terminal's modes (or reads
  // from it) is stopped by SIGTTOU (SIGTTIN).
  if (::isatty(STDIN_FILENO) == 0 || ::tcgetpgrp(STDIN_FILENO) != ::getpgrp()) return false;
  termios modes{};
  if (::tcgetattr(STDIN_FILENO, &modes) != 0) return false;
  g_saved = modes;
  modes.c_lflag &= ~static_cast<tcflag_t>(ICANON | ECHO);  // ISIG stays: Ctrl-C still signals
  modes.c_cc[VMIN] = 1;
  modes.c_cc[VTIME] = 0;
  g_raw = 1;  // before the change: a signal in between restores the saved modes
  if (::tcsetattr(STDIN_FILENO, TCSANOW, &modes) != 0) {
    g_raw = 0;
    return false;
  }
  return true;
}

void LiveProcess::wake() const {
  if (g_wake_write >= 0) (void)!::write(g_wake_write, "w", 1);
}

void LiveProcess::drain() const {
  char buf[64];
  while (::read(read_fd_, buf, sizeof buf) > 0) {
  }
}

int LiveProcess::interrupts() const { return static_cast<int>(g_interrupts); }

}  // namespace geotraj::cli
