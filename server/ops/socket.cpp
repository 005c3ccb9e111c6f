#include "server/ops/socket.hpp"

#include <algorithm>
#include <cerrno>
#include <system_error>
#include <vector>

#include <netdb.h>
#include <netinet/in.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

namespace geotraj::server {
namespace {

std::string errno_text(int error) { return std::generic_category().message(error); }

}  // namespace

tl::expected<HostPort, std::string> split_host_port(const std::string& address, const std::string& quoted) {
  HostPort out;
  if (!address.empty() && address.front() == '[') {
    const std::size_t close = address.find(']');
    if (close == std::string::npos || close + 1 >= address.size() || address[close + 1] != ':') {
      return tl::make_unexpected(quoted + " is not [IPV6]:PORT");
    }
    out.host = address.substr(1, close - 1);
    out.port = address.substr(close + 2);
  } else {
    const std::size_t colon = address.rfind(':');
    if (colon == std::string::npos) return tl::make_unexpected(quoted + " has no port: write HOST:PORT");
    out.host = address.substr(0, colon);
    out.port = address.substr(colon + 1);
    if (out.host.find(':') != std::string::npos) {
      return tl::make_unexpected(quoted + " is not HOST:PORT (write an IPv6 address as [ADDRESS]:PORT)");
    }
  }
  const bool digits = !out.port.empty() && out.port.size() <= 5 &&
                      std::all_of(out.port.begin(), out.port.end(), [](char c) { return c >= '0' && c <= '9'; });
  if (!digits || std::stoi(out.port) > 65535) return tl::make_unexpected(quoted + " has no port number from 0 to 65535");
  return out;
}

tl::expected<ListeningSocket, std::string> listen_tcp(const std::string& address, const std::string& what,
                                                      int backlog) {
  const std::string quoted = what + " \"" + address + "\"";
  auto parts = split_host_port(address, quoted);
  if (!parts) return tl::make_unexpected(parts.error());
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const std::string& host = parts->host;
  if (const int rc = ::getaddrinfo(host.empty() ? nullptr : host.c_str(), parts->port.c_str(), &hints, &found); rc != 0) {
    const std::string why = rc == EAI_SYSTEM ? errno_text(errno) : ::gai_strerror(rc);
    return tl::make_unexpected("cannot resolve " + quoted + ": " + why);
  }
  std::vector<const addrinfo*> candidates;
  for (const addrinfo* a = found; a != nullptr; a = a->ai_next) candidates.push_back(a);
  // For "every address" try IPv6 first: on Linux a [::] socket also accepts IPv4.
  if (host.empty()) {
    std::stable_partition(candidates.begin(), candidates.end(), [](const addrinfo* a) { return a->ai_family == AF_INET6; });
  }
  ListeningSocket out;
  int error = 0;
  for (const addrinfo* a : candidates) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) {
      error = errno;
      continue;
    }
    const int on = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
    if (a->ai_family == AF_INET6 && host.empty()) {
      const int off = 0;  // [::] takes IPv4 too
      ::setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &off, sizeof off);
    }
    if (::bind(fd, a->ai_addr, a->ai_addrlen) == 0 && ::listen(fd, backlog) == 0) {
      out.fd = fd;
      break;
    }
    error = errno;
    ::close(fd);
  }
  ::freeaddrinfo(found);
  if (out.fd < 0) return tl::make_unexpected("cannot listen on " + quoted + ": " + errno_text(error));

  sockaddr_storage bound{};
  socklen_t length = sizeof bound;
  if (::getsockname(out.fd, reinterpret_cast<sockaddr*>(&bound), &length) == 0) {
    if (bound.ss_family == AF_INET) out.port = ntohs(reinterpret_cast<const sockaddr_in*>(&bound)->sin_port);
    if (bound.ss_family == AF_INET6) out.port = ntohs(reinterpret_cast<const sockaddr_in6*>(&bound)->sin6_port);
  }
  return out;
}

long raise_descriptor_limit() {
  rlimit limit{};
  if (::getrlimit(RLIMIT_NOFILE, &limit) != 0) return 1024;
  if (limit.rlim_cur < limit.rlim_max) {
    rlimit raised = limit;
    raised.rlim_cur = limit.rlim_max;
    if (::setrlimit(RLIMIT_NOFILE, &raised) == 0) limit = raised;
  }
  if (limit.rlim_cur == RLIM_INFINITY) return 1L << 20;
  return static_cast<long>(limit.rlim_cur);
}

}  // namespace geotraj::server
