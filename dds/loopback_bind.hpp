#pragma once
/// \file loopback_bind.hpp
/// Keeps a loopback-only process's sockets on loopback. Cyclone DDS 0.10 binds its receive
/// sockets to the wildcard address (0.0.0.0) whatever interface it is configured for — no option
/// of the library changes that (eclipse-cyclonedds/cyclonedds#1923, #2090) — so with the
/// built-in "lo only" configuration another host could still send to its ports. This file's
/// bind() interposes the C library's in every Stroma executable that talks DDS: once
/// enable_loopback_bind() has run, a bind to the IPv4 or IPv6 wildcard address is made to the
/// loopback address of the same family instead (same port), so the kernel delivers nothing that
/// did not come from this host. Binds to a specific address are left alone, as is every bind
/// before the call (and every bind in a process using its own --dds-config or CYCLONEDDS_URI).
/// Verified by Serve.SocketsAreBoundToLoopbackOnly (the server's sockets, from /proc).

namespace stroma {

/// From now on, wildcard binds in this process go to loopback. Idempotent; never turned off.
void enable_loopback_bind();

/// Whether enable_loopback_bind() has run.
bool loopback_bind_enabled();

}  // namespace stroma
