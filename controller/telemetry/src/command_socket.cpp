#include "pneu/telemetry/command_socket.hpp"

#include <arpa/inet.h>
#include <ifaddrs.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace pneu::telemetry {

UdpmAddress parse_udpm_url(std::string_view url) {
  constexpr std::string_view scheme = "udpm://";
  if (url.substr(0, scheme.size()) != scheme)
    throw std::invalid_argument("'" + std::string(url) + "' is not a udpm:// URL: commands need LCM's UDP multicast transport");
  std::string_view rest = url.substr(scheme.size());
  rest = rest.substr(0, rest.find('?'));
  const auto colon = rest.rfind(':');
  const std::string host(rest.substr(0, colon));
  UdpmAddress a;
  if (inet_pton(AF_INET, host.c_str(), &a.group) != 1 || !IN_MULTICAST(ntohl(a.group.s_addr)))
    throw std::invalid_argument("'" + std::string(url) + "': '" + host + "' is not an IPv4 multicast group");
  int port = 7667;  // LCM's default
  if (colon != std::string_view::npos) {
    const std::string p(rest.substr(colon + 1));
    char* end = nullptr;
    const long v = std::strtol(p.c_str(), &end, 10);
    if (p.empty() || *end != '\0' || v < 1 || v > 65535)
      throw std::invalid_argument("'" + std::string(url) + "': bad port '" + p + "'");
    port = static_cast<int>(v);
  }
  a.port = static_cast<std::uint16_t>(port);
  return a;
}

CommandSocket::CommandSocket(std::string_view lcm_url) {
  const UdpmAddress a = parse_udpm_url(lcm_url);
  fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0) throw std::runtime_error(std::string("command socket: ") + std::strerror(errno));
  const auto fail = [this](const char* what) {
    const std::string why = std::string("command socket: ") + what + ": " + std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
    throw std::runtime_error(why);
  };
  const int one = 1, zero = 0;
  // LCM's own sockets (other processes on this host) share the port the same way.
  if (setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0) fail("SO_REUSEADDR");
  // Only the groups this socket joined, not every group some socket on the host joined.
  if (setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_ALL, &zero, sizeof zero) != 0) fail("IP_MULTICAST_ALL");
  sockaddr_in bind_to{};
  bind_to.sin_family = AF_INET;
  bind_to.sin_port = htons(a.port);
  bind_to.sin_addr = a.group;  // the group, not INADDR_ANY: unicast to the port is not delivered
  if (::bind(fd_, reinterpret_cast<const sockaddr*>(&bind_to), sizeof bind_to) != 0) fail("bind");
  ip_mreq join{};
  join.imr_multiaddr = a.group;
  join.imr_interface.s_addr = htonl(INADDR_ANY);  // the interface the multicast route names, as LCM does
  local_multicast_group_ = (ntohl(a.group.s_addr) & 0xffffff00u) == 0xe0000000u;  // 224.0.0.0/24
  if (setsockopt(fd_, IPPROTO_IP, IP_ADD_MEMBERSHIP, &join, sizeof join) != 0)
    fail("joining the LCM group (no multicast route? `ip route add 224.0.0.0/4 dev lo` keeps LCM on this host)");
  refresh_local_addresses();
}

CommandSocket::~CommandSocket() {
  if (fd_ >= 0) ::close(fd_);
}

// getifaddrs() needs a netlink socket: under the systemd unit (RestrictAddressFamilies without
// AF_NETLINK) it fails, the list stays empty, and only loopback and zero sources count as this
// host, which is what the unit's IPAddressAllow= lets in anyway.
void CommandSocket::refresh_local_addresses() {
  local_.clear();
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) == 0) {
    for (const ifaddrs* i = list; i; i = i->ifa_next)
      if (i->ifa_addr && i->ifa_addr->sa_family == AF_INET)
        local_.push_back(reinterpret_cast<const sockaddr_in*>(i->ifa_addr)->sin_addr.s_addr);
    freeifaddrs(list);
  }
  refreshed_ = std::chrono::steady_clock::now();
}

bool CommandSocket::is_local(in_addr a) {
  if ((ntohl(a.s_addr) >> 24) == 127) return true;  // 127.0.0.0/8: loopback
  // 0.0.0.0: what this host's multicast carries out of `lo` when the route names no source
  // (`ip route add 224.0.0.0/4 dev lo`; with `src 127.0.0.1` it carries 127.0.0.1). Linux drops
  // datagrams from outside with a zero source unless they go to 224.0.0.0/24 (ip_route_input_mc).
  if (a.s_addr == htonl(INADDR_ANY)) return !local_multicast_group_;
  const auto known = [&] { return std::find(local_.begin(), local_.end(), a.s_addr) != local_.end(); };
  if (known()) return true;
  if (std::chrono::steady_clock::now() - refreshed_ > std::chrono::seconds(1)) {
    refresh_local_addresses();
    return known();
  }
  return false;
}

bool CommandSocket::receive(std::span<std::uint8_t> buffer, Datagram& out) {
  sockaddr_in from{};
  socklen_t from_len = sizeof from;
  // MSG_TRUNC: the datagram's real length, however long, so an oversized one is seen as such.
  const ssize_t n = ::recvfrom(fd_, buffer.data(), buffer.size(), MSG_TRUNC, reinterpret_cast<sockaddr*>(&from), &from_len);
  if (n < 0) return false;  // EAGAIN: nothing waiting (other errors: try again next time)
  out.bytes = static_cast<std::size_t>(n);
  out.stored = std::min(out.bytes, buffer.size());
  out.source = from.sin_addr;
  out.from_this_host = from.sin_family == AF_INET && is_local(from.sin_addr);
  return true;
}

}  // namespace pneu::telemetry
