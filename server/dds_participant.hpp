#pragma once
/// \file dds_participant.hpp
/// Creating the DDS participant with Stroma's network policy: loopback only unless the user
/// says otherwise. Cyclone's default picks the external interface and multicasts; Stroma is
/// secure by default and ships server/cyclonedds-loopback.xml (embedded here).

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
DdsParticipant create_participant(int domain_id, const std::string& config_file);

/// Throws std::runtime_error("what: <dds_strretcode>") if rc < 0; returns rc otherwise.
dds_return_t dds_check(dds_return_t rc, const char* what);

}  // namespace stroma
