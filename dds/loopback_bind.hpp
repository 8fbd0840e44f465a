#pragma once
/// \file loopback_bind.hpp
/// Keeps a loopback-only process's sockets on loopback. Cyclone DDS 0.10 binds its receive
/// sockets to the wildcard address (0.0.0.0) whatever interface it is configured for — no option
/// of the library changes that (eclipse-cyclonedds/cyclonedds#1923, #2090) — so with the
/// built-in "lo only" configuration another host could still send to its ports. This file's
/// bind() interposes the C library's in every Stroma executable that talks DDS, sealed to
/// Cyclone: once enable_loopback_bind() has run, a bind *called from libddsc* to the IPv4 or IPv6
/// wildcard address is made to the loopback address of the same family instead (same port), so
/// the kernel delivers nothing that did not come from this host. Binds from any other library or
/// from the program itself, binds to a specific address, and every bind before the call are left
/// alone. It is enabled for the built-in configuration and for a user's own configuration that
/// is loopback-only (dds/loopback_config.hpp); any other user configuration is used as given.
/// Verified by Serve.SocketsAreBoundToLoopbackOnly and Serve.AUserLoopbackConfigurationIsBoundToLoopback
/// (the server's sockets, from /proc), and LoopbackBind.* (which callers it applies to).

namespace stroma {

/// From now on, wildcard binds in this process go to loopback. Idempotent; never turned off.
void enable_loopback_bind();

/// Whether enable_loopback_bind() has run.
bool loopback_bind_enabled();

/// Whether a bind called from `caller` (a return address) would be redirected: enabled, and the
/// address lies in Cyclone DDS's library.
bool loopback_bind_applies_to(const void* caller);

}  // namespace stroma
