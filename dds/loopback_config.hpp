#pragma once
/// \file loopback_config.hpp
/// Whether a Cyclone DDS configuration keeps a participant on this host: the rule Stroma's
/// built-in configuration follows (interface `lo`, no multicast, unicast peers on 127.0.0.1), read
/// from a user's own (--dds-config FILE or CYCLONEDDS_URI). When it holds, the process's DDS
/// sockets are bound to loopback as with the built-in one (dds/loopback_bind.hpp).
///
/// The check is conservative: anything it cannot prove local (no interface named, an interface
/// other than lo / 127.x / ::1, autodetermine, multicast allowed or left at its default, a peer off
/// this host, an unreadable file) makes it false, and the configuration is used as given.

#include <string>

namespace stroma {

/// The text of a CYCLONEDDS_URI value: its comma-separated items, `file://PATH` items read,
/// XML fragments as they are, in order (Cyclone merges them in that order). A file that cannot
/// be read makes `ok` false.
std::string cyclone_uri_text(const std::string& uri, bool* ok);

/// True iff the configuration text keeps every socket's traffic on this host. `why` (if given)
/// says what made it false, or what made it true.
bool is_loopback_only_config(const std::string& xml, std::string* why = nullptr);

}  // namespace stroma
