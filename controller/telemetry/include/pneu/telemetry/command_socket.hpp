// The command channel's own receiving socket. LCM has no authentication, and its UDP multicast
// transport hands a subscriber every datagram that reaches the port, from any host (ttl=0 only
// limits what this host sends). pneud therefore does not subscribe through LCM: this socket
// joins the LCM group itself, bound to the group's address (unicast datagrams sent to the port
// never reach it), and tells, for each datagram, whether it came from this host: its source
// address is one of this host's own (loopback, an address of one of its interfaces, or the zero
// address of multicast routed through `lo`; Linux drops datagrams arriving from outside with a
// local or zero source address as martians).
#pragma once

#include <netinet/in.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pneu::telemetry {

/// The group and port of an LCM `udpm://GROUP:PORT?...` URL.
struct UdpmAddress {
  in_addr group{};
  std::uint16_t port = 0;
};
/// Parses an LCM udpm URL; throws std::invalid_argument naming what is wrong.
[[nodiscard]] UdpmAddress parse_udpm_url(std::string_view url);

class CommandSocket {
 public:
  /// Binds to the group and port of `lcm_url` and joins the group. Throws std::runtime_error.
  explicit CommandSocket(std::string_view lcm_url);
  ~CommandSocket();
  CommandSocket(const CommandSocket&) = delete;
  CommandSocket& operator=(const CommandSocket&) = delete;

  [[nodiscard]] int fd() const noexcept { return fd_; }

  struct Datagram {
    std::size_t bytes = 0;       ///< the datagram's real length (may exceed the buffer)
    std::size_t stored = 0;      ///< bytes stored in the buffer
    bool from_this_host = false;
    in_addr source{};
  };
  /// Receives one datagram without blocking. Returns false when none is waiting.
  bool receive(std::span<std::uint8_t> buffer, Datagram& out);

  /// Whether `a` is one of this host's addresses (refreshes the list at most once a second when
  /// an address is not in it, so that an address added at run time is learnt).
  [[nodiscard]] bool is_local(in_addr a);

 private:
  void refresh_local_addresses();

  int fd_ = -1;
  bool local_multicast_group_ = false;  // 224.0.0.0/24: zero sources may come from outside
  std::vector<in_addr_t> local_;  // network byte order
  std::chrono::steady_clock::time_point refreshed_{};
};

}  // namespace pneu::telemetry
