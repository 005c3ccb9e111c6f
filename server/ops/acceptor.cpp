#include "server/ops/acceptor.hpp"

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>
#include <system_error>

#include <dirent.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <linux/tcp.h>  // struct tcp_info with tcpi_bytes_received (not in glibc's)
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

namespace geotraj::server {
namespace {

using Clock = std::chrono::steady_clock;

// After an accept error (descriptors exhausted), acceptance pauses this long.
constexpr auto kPause = std::chrono::milliseconds(100);
// The open-connection gauge is refreshed this often.
constexpr auto kCountEvery = std::chrono::seconds(1);
// At the cap, the descriptors are counted again at most this often.
constexpr auto kRescanEvery = std::chrono::milliseconds(20);
// A connection that has sent nothing this long after its accept may be closed at the cap.
constexpr auto kIdleGrace = std::chrono::milliseconds(250);
// The HTTP/2 client preface ("PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n"); a TLS ClientHello is longer.
constexpr std::uint64_t kPrefaceBytes = 24;

// Each descriptor of this process that is a socket, by inode.
std::unordered_map<ino_t, int> socket_descriptors() {
  std::unordered_map<ino_t, int> out;
  DIR* dir = ::opendir("/proc/self/fd");
  if (dir == nullptr) return out;
  char link[64];
  while (const dirent* entry = ::readdir(dir)) {
    if (entry->d_name[0] < '0' || entry->d_name[0] > '9') continue;
    const std::string path = std::string("/proc/self/fd/") + entry->d_name;
    const ssize_t n = ::readlink(path.c_str(), link, sizeof link);
    if (n <= 0) continue;
    constexpr std::string_view kPrefix = "socket:[";
    const std::string_view text(link, static_cast<std::size_t>(n));
    if (text.substr(0, kPrefix.size()) != kPrefix || text.back() != ']') continue;
    const auto inode = static_cast<ino_t>(std::strtoull(std::string(text.substr(kPrefix.size())).c_str(), nullptr, 10));
    out.emplace(inode, std::atoi(entry->d_name));
  }
  ::closedir(dir);
  return out;
}

int open_reserve() { return ::open("/dev/null", O_RDONLY | O_CLOEXEC); }

}  // namespace

tl::expected<std::unique_ptr<Acceptor>, std::string> Acceptor::listen(const std::string& address,
                                                                       const std::string& what) {
  auto socket = listen_tcp(address, what);
  if (!socket) return tl::make_unexpected(socket.error());
  int wake[2];
  if (::pipe2(wake, O_NONBLOCK | O_CLOEXEC) != 0) {
    const int error = errno;
    ::close(socket->fd);
    return tl::make_unexpected("cannot serve " + what + " \"" + address + "\": " + std::generic_category().message(error));
  }
  return std::unique_ptr<Acceptor>(new Acceptor(*socket, wake[0], wake[1]));
}

Acceptor::Acceptor(ListeningSocket socket, int wake_read, int wake_write)
    : socket_(socket), wake_read_(wake_read), wake_write_(wake_write), reserve_fd_(open_reserve()) {}

Acceptor::~Acceptor() {
  stop();
  if (socket_.fd >= 0) ::close(socket_.fd);
  if (reserve_fd_ >= 0) ::close(reserve_fd_);
  ::close(wake_read_);
  ::close(wake_write_);
}

void Acceptor::start(std::unique_ptr<grpc::experimental::ExternalConnectionAcceptor> sink, Options options,
                     Metrics& metrics, const Logger& logger) {
  sink_ = std::move(sink);
  options_ = std::move(options);
  metrics_ = &metrics;
  logger_ = &logger;
  metrics_->connections_open(options_.listener, 0);
  thread_ = std::thread(&Acceptor::run, this);
}

void Acceptor::stop() {
  const std::lock_guard lock(stop_mutex_);
  if (thread_.joinable()) {
    const char byte = 0;
    while (::write(wake_write_, &byte, 1) < 0 && errno == EINTR) {
    }
    thread_.join();
  }
  if (socket_.fd >= 0) {
    ::close(socket_.fd);
    socket_.fd = -1;
  }
}

std::size_t Acceptor::count_open() {
  const auto sockets = socket_descriptors();
  if (!sockets.empty()) {
    std::erase_if(live_, [&sockets](const auto& entry) { return !sockets.contains(entry.first); });
    std::erase_if(shut_down_, [this](ino_t inode) { return !live_.contains(inode); });
  }
  open_.store(live_.size());
  metrics_->connections_open(options_.listener, static_cast<std::int64_t>(live_.size()));
  return live_.size();
}

bool Acceptor::make_room() {
  // A flood at the cap scans /proc/self/fd (O(descriptors)) once per kRescanEvery at most.
  const auto now = Clock::now();
  if (now - last_scan_ < kRescanEvery) return false;
  last_scan_ = now;
  if (count_open() < options_.max_connections) return true;
  // Full: silent connections make room (they leave once gRPC sees them shut down).
  return close_idle() > 0;
}

std::size_t Acceptor::close_idle() {
  const auto sockets = socket_descriptors();
  const auto now = Clock::now();
  std::size_t closed = 0;
  for (const auto& [inode, accepted] : live_) {
    if (now - accepted < kIdleGrace || shut_down_.contains(inode)) continue;
    const auto found = sockets.find(inode);
    if (found == sockets.end()) continue;
    const int fd = found->second;
    tcp_info info{};
    socklen_t length = sizeof info;
    if (::getsockopt(fd, IPPROTO_TCP, TCP_INFO, &info, &length) != 0) continue;
    if (info.tcpi_bytes_received >= kPrefaceBytes) continue;
    // The descriptor is gRPC's: shut the connection down (gRPC then closes it), never close
    // the number. Checked again just before, in case gRPC closed it and the number was reused.
    struct stat st {};
    if (::fstat(fd, &st) != 0 || st.st_ino != inode) continue;
    if (::shutdown(fd, SHUT_RDWR) == 0) {
      shut_down_.insert(inode);
      ++closed;
      metrics_->connection_refused(options_.listener, "idle");
    }
  }
  return closed;
}

void Acceptor::set_accepting(bool accepting) {
  if (accepting_.exchange(accepting) == accepting) return;
  if (accepting) {
    logger_->log(LogLevel::kWarning, "accepting connections again", {{"listener", options_.listener}});
  } else {
    logger_->log(LogLevel::kError,
                 "out of file descriptors: new connections are closed on arrival until some are free (readiness "
                 "NOT_SERVING)",
                 {{"listener", options_.listener}, {"connections", static_cast<std::int64_t>(live_.size())}});
  }
  if (options_.on_accepting) options_.on_accepting(accepting);
}

void Acceptor::run() {
  Clock::time_point paused_until{};
  Clock::time_point next_count = Clock::now() + kCountEvery;
  for (;;) {
    const auto now = Clock::now();
    const bool paused = now < paused_until;
    pollfd fds[2] = {{wake_read_, POLLIN, 0}, {paused ? -1 : socket_.fd, POLLIN, 0}};
    const auto wake_at = paused ? std::min(paused_until, next_count) : next_count;
    const auto wait = std::chrono::ceil<std::chrono::milliseconds>(wake_at - now).count();
    if (::poll(fds, 2, static_cast<int>(std::clamp<decltype(wait)>(wait, 0, 1000))) < 0 && errno != EINTR) break;
    if (fds[0].revents != 0) break;  // stop()

    if (Clock::now() >= next_count) {
      if (accepting_.load()) {
        count_open();
      } else if (reserve_fd_ < 0) {
        reserve_fd_ = open_reserve();
      }
      if (!accepting_.load() && reserve_fd_ >= 0) {
        // Recovered once a descriptor beyond the reserve can be had again.
        const int probe = open_reserve();
        if (probe >= 0) {
          ::close(probe);
          set_accepting(true);
        }
      }
      next_count = Clock::now() + kCountEvery;
    }
    if (fds[1].revents == 0) continue;

    for (;;) {
      const int fd = ::accept4(socket_.fd, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (fd < 0) {
        if (errno == EINTR || errno == ECONNABORTED) continue;
        if (errno == EAGAIN || errno == EWOULDBLOCK) break;
        if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
          // Shed the connection waiting in the backlog (else poll() says readable forever):
          // the reserve descriptor makes room to accept it, and it is closed at once.
          if (reserve_fd_ >= 0) {
            ::close(reserve_fd_);
            reserve_fd_ = -1;
          }
          const int shed = ::accept4(socket_.fd, nullptr, nullptr, SOCK_CLOEXEC);
          if (shed >= 0) {
            metrics_->connection_refused(options_.listener, "descriptors");
            ::close(shed);
          }
          reserve_fd_ = open_reserve();
          set_accepting(false);
        }
        paused_until = Clock::now() + kPause;
        break;
      }
      if (!accepting_.load()) set_accepting(true);
      if (live_.size() >= options_.max_connections && !make_room()) {
        metrics_->connection_refused(options_.listener, "max_connections");  // counted before it is seen
        ::close(fd);  // its client retries with backoff
        continue;
      }
      const int on = 1;
      (void)::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
      struct stat st {};
      if (::fstat(fd, &st) == 0) live_[st.st_ino] = Clock::now();
      open_.store(live_.size());
      grpc::experimental::ExternalConnectionAcceptor::NewConnectionParameters connection;
      connection.listener_fd = socket_.fd;
      connection.fd = fd;
      sink_->HandleNewConnection(&connection);  // gRPC owns the descriptor from here
    }
  }
}

}  // namespace geotraj::server
