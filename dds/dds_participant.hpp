#pragma once
/// \file dds_participant.hpp
/// Creating the DDS participant with Stroma's network policy: loopback only unless the user
/// says otherwise. Cyclone's default picks the external interface and multicasts; Stroma is
/// secure by default and ships dds/cyclonedds-loopback.xml (embedded here).

#include <string>

#include <dds/dds.h>

namespace stroma {

/// Cyclone configuration used when neither --dds-config nor CYCLONEDDS_URI is given: only the
/// loopback interface, no multicast, unicast discovery to 127.0.0.1.
extern const char* const kLoopbackDdsConfig;

/// A participant and where its configuration came from (for the log line at start-up).
struct DdsParticipant {
  dds_entity_t participant = 0;
  std::string config_source;  ///< "built-in loopback", "CYCLONEDDS_URI", or the file path
};

/// Creates the participant on `domain_id`. `config_file` (from --dds-config) wins, then the
/// CYCLONEDDS_URI environment variable, then the built-in loopback configuration. Throws
/// std::runtime_error with Cyclone's message on failure (e.g. an unreadable or invalid file).
/// `receive_priority` > 0: with the built-in configuration, Cyclone's receive thread (one
/// "recv" for all sockets instead of 0.10's default recv + recvUC, whose priority its
/// configuration cannot set; it takes every sample off the socket and delivers it to the
/// readers) runs under SCHED_FIFO at that priority, if the process may (else at normal
/// priority, and the source says so). A command then reaches the server's input thread without waiting behind whatever
/// else the machine runs (docs/REALTIME.md). A user's own configuration is left as it is.
///
/// `security_dir` (from --security; empty: none): the participant joins a protected domain as
/// `identity` ("server", "renderer" or a client's name) with the certificates and signed
/// documents of that directory (dds/dds_security.hpp); its <Security> settings are added to
/// whichever configuration is used. Throws std::runtime_error naming a missing file.
DdsParticipant create_participant(int domain_id, const std::string& config_file, int receive_priority = 0,
                                  const std::string& security_dir = "", const std::string& identity = "");

/// Deletes the participant and then every DDS entity of the process, its domains included, so
/// that Cyclone's threads have stopped before the process exits: with DDS Security they encrypt
/// with OpenSSL, whose clean-up at exit would otherwise pull its state from under them
/// (a segmentation fault at exit). For the end of `serve`, `tool` and `render`.
void close_dds(const DdsParticipant& p);

/// The built-in loopback configuration with Cyclone's receive thread at SCHED_FIFO `priority`.
std::string loopback_config_with_receive_priority(int priority);

/// Throws std::runtime_error("what: <dds_strretcode>") if rc < 0; returns rc otherwise.
dds_return_t dds_check(dds_return_t rc, const char* what);

}  // namespace stroma
