// Listening TCP sockets of geotrajd (the gRPC port, the health port, the metrics port): one
// parser of HOST:PORT and one bind, so that every port says the same about a bad address.
#pragma once

#include <string>

#include <tl/expected.hpp>

namespace geotraj::server {

/// A bound, listening, non-blocking socket and its port.
struct ListeningSocket {
  int fd = -1;
  int port = 0;
};

/// HOST:PORT or [IPV6]:PORT split into its host (empty for every address) and its port
/// (digits, 0 to 65535). The error starts with `quoted` (e.g. `the gRPC address "x"`) and
/// says what is wrong.
struct HostPort {
  std::string host;
  std::string port;
};
tl::expected<HostPort, std::string> split_host_port(const std::string& address, const std::string& quoted);

/// Binds `address` (HOST:PORT or [IPV6]:PORT; a host name is resolved; an empty host means
/// every address, IPv6 and IPv4; port 0 picks a free port) and listens. SO_REUSEADDR only
/// (a restart binds while old sockets sit in TIME_WAIT); never SO_REUSEPORT, so a second
/// server on a port in use fails here rather than taking part of its traffic. The error
/// names `what` and the address, e.g.
/// `cannot listen on the gRPC address "127.0.0.1:50051": Address already in use`.
tl::expected<ListeningSocket, std::string> listen_tcp(const std::string& address, const std::string& what,
                                                      int backlog = 1024);

/// The number of descriptors this process may open (RLIMIT_NOFILE's soft limit), after
/// raising the soft limit to the hard one (and returning what it then is).
long raise_descriptor_limit();

}  // namespace geotraj::server
