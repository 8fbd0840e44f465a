#include "dds/loopback_bind.hpp"

#include <dlfcn.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cstring>

#include <dds/dds.h>

namespace {
std::atomic<bool> g_loopback_only{false};
/// Where Cyclone DDS's library is mapped (dladdr's dli_fbase of one of its functions): only binds
/// called from it are redirected.
std::atomic<const void*> g_ddsc_base{nullptr};
}

namespace stroma {

void enable_loopback_bind() {
  Dl_info info{};
  if (dladdr(reinterpret_cast<const void*>(&dds_create_participant), &info) && info.dli_fbase)
    g_ddsc_base.store(info.dli_fbase, std::memory_order_release);
  g_loopback_only.store(true, std::memory_order_release);
}

bool loopback_bind_enabled() { return g_loopback_only.load(std::memory_order_acquire); }

bool loopback_bind_applies_to(const void* caller) {
  const void* base = g_ddsc_base.load(std::memory_order_acquire);
  Dl_info info{};
  return base && caller && dladdr(caller, &info) && info.dli_fbase == base;
}

}  // namespace stroma

// The executable's definition interposes the C library's for every shared library it loads
// (libddsc among them): the linker exports it because they reference bind. It is sealed to
// Cyclone: a bind is redirected only when it was called from libddsc's own code (the return
// address lies in the library's mapping); every other library's and the program's binds are the
// C library's, unchanged. The system call is made directly, so nothing here depends on the C
// library's symbol.
extern "C" int bind(int fd, const struct sockaddr* addr, socklen_t len) noexcept {
  if (addr && g_loopback_only.load(std::memory_order_acquire) &&
      stroma::loopback_bind_applies_to(__builtin_return_address(0))) {
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
