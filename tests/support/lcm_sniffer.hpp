// Test support: LCM messages read off the group with a plain socket (LCM's short-message form:
// "LC02" | sequence | channel NUL | payload). The tests listen this way rather than through
// LCM 1.3.1's C++ subscriptions, which crash under AddressSanitizer/UBSan even in a ten-line
// program (a bad user_data in lcm-cpp-impl.hpp's cb_func); pneud listens the same way.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace pneu::test {

class LcmSniffer {
 public:
  explicit LcmSniffer(const char* group = "239.255.76.67", int port = 7667) {
    fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    const int one = 1;
    setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    inet_pton(AF_INET, group, &a.sin_addr);
    ip_mreq join{};
    join.imr_multiaddr = a.sin_addr;
    join.imr_interface.s_addr = htonl(INADDR_ANY);
    good_ = bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 &&
            setsockopt(fd_, IPPROTO_IP, IP_ADD_MEMBERSHIP, &join, sizeof join) == 0;
  }
  ~LcmSniffer() { close(fd_); }
  LcmSniffer(const LcmSniffer&) = delete;
  LcmSniffer& operator=(const LcmSniffer&) = delete;

  [[nodiscard]] bool good() const { return good_; }

  // Waits up to `timeout_ms` for one short message; false when none came (fragments and other
  // datagrams are skipped).
  bool receive(std::string& channel, std::vector<std::uint8_t>& payload, int timeout_ms) {
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, timeout_ms) <= 0) return false;
    std::uint8_t buf[65536];
    const ssize_t n = recv(fd_, buf, sizeof buf, 0);
    if (n < 9 || std::memcmp(buf, "LC02", 4) != 0) return false;
    const auto* name = reinterpret_cast<const char*>(buf + 8);
    const void* nul = std::memchr(name, '\0', static_cast<std::size_t>(n) - 8);
    if (!nul) return false;
    channel.assign(name, static_cast<const char*>(nul));
    const auto* data = static_cast<const std::uint8_t*>(nul) + 1;
    payload.assign(data, static_cast<const std::uint8_t*>(buf + n));
    return true;
  }

 private:
  int fd_ = -1;
  bool good_ = false;
};

}  // namespace pneu::test
