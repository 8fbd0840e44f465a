#include "dds/loopback_bind.hpp"

#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cstring>

namespace {
std::atomic<bool> g_loopback_only{false};
}

namespace stroma {

void enable_loopback_bind() { g_loopback_only.store(true, std::memory_order_release); }

bool loopback_bind_enabled() { return g_loopback_only.load(std::memory_order_acquire); }

}  // namespace stroma

// The executable's definition interposes the C library's for every shared library it loads
// (libddsc among them): the linker exports it because they reference bind. The system call is
// made directly, so nothing here depends on the C library's symbol.
extern "C" int bind(int fd, const struct sockaddr* addr, socklen_t len) noexcept {
  if (addr && g_loopback_only.load(std::memory_order_acquire)) {
    if (addr->sa_family == AF_INET && len >= static_cast<socklen_t>(sizeof(sockaddr_in))) {
      sockaddr_in a;
      std::memcpy(&a, addr, sizeof a);
      if (a.sin_addr.s_addr == htonl(INADDR_ANY)) {
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        return static_cast<int>(syscall(SYS_bind, fd, reinterpret_cast<const sockaddr*>(&a), sizeof a));
      }
    } else if (addr->sa_family == AF_INET6 && len >= static_cast<socklen_t>(sizeof(sockaddr_in6))) {
      sockaddr_in6 a;
      std::memcpy(&a, addr, sizeof a);
      if (std::memcmp(&a.sin6_addr, &in6addr_any, sizeof in6addr_any) == 0) {
        a.sin6_addr = in6addr_loopback;
        return static_cast<int>(syscall(SYS_bind, fd, reinterpret_cast<const sockaddr*>(&a), sizeof a));
      }
    }
  }
  return static_cast<int>(syscall(SYS_bind, fd, addr, len));
}
