#pragma once
/// \file dds_security.hpp
/// DDS Security (OMG DDS-Security 1.1, Cyclone's built-in plugins: PKI-DH authentication,
/// signed governance and permissions, AES-GCM crypto) for Stroma's processes.
///
/// `stroma security init DIR` (init_security_dir) makes a self-contained test PKI with the
/// `openssl` command: an identity CA and a permissions CA; identities (key + certificate) for
/// the server, the renderer and each tool client; a governance document (no unauthenticated
/// participant joins; every topic's reads and writes access-controlled, its data and metadata
/// encrypted) and one permissions document per identity, all signed by the permissions CA.
/// `serve`, `tool` and `render --security DIR` then run the protected domain:
///  - the server may publish every server→client topic and read ToolCommand (any tool) and
///    Control;
///  - a tool client may write ToolCommand only in the partitions named after its tools (and
///    Control), and read ToolFeedback and SimStatus;
///  - the renderer may read what it draws, and write nothing.
/// In a protected domain ToolCommand travels in a partition named after its tool, and the
/// server reads each tool's commands in that tool's partition only, rejecting a command whose
/// `tool` field names another: a client's permissions decide which tools it can move.

#include <string>
#include <vector>

namespace stroma {

/// A tool client's identity and the tools it may command.
struct SecurityClient {
  std::string name;                ///< file names NAME.pem, NAME_key.pem, permissions_NAME.p7s
  std::vector<std::string> tools;  ///< tool names (ToolCommand partitions) it may write
  bool control = false;            ///< an operator: may also write Control (pause, step, reset, stop)
};

/// What `stroma security init` makes. Invariants: names are [A-Za-z0-9_-], unique, and none is
/// "server", "renderer" or a CA's name; every client has at least one tool.
struct SecurityInitOptions {
  std::string dir;                  ///< must not exist yet (nothing is overwritten)
  /// The default: one client that commands `probe` and operates the session (its owner's).
  std::vector<SecurityClient> clients{{"tool", {"probe"}, true}};
  int days = 3650;                  ///< certificate and permission validity
  int domain_min = 0, domain_max = 230;  ///< the domains the documents cover (DDS Security: at most 230)
};

/// Who begins DDS Security's authentication handshake between two participants: the one whose
/// GUID, which the specification derives from the SHA-256 of the certificate's subject (first
/// bit 1, then 47 bits of the hash), is smaller. It matters across implementations: Cyclone
/// begins with ECDH, which Fast DDS 2.9 answers; Fast DDS 2.9 begins with DH-MODP, whose public
/// key it encodes in a way Cyclone 0.10 cannot read ("Failed to convert octet sequence to ASN1
/// integer"; cyclonedds#701, Fast-DDS#3259). So `security init` gives Stroma's own identities
/// (server, renderer) subjects whose hash starts below 0x80 and clients' from 0x80: every
/// handshake with a client is begun by Stroma's side, and a Fast DDS client authenticates.
enum class HandshakeOrder { Initiator, Replier };

/// The handshake order of a certificate (PEM file) by that rule. Throws std::runtime_error when
/// the file cannot be read or parsed.
HandshakeOrder identity_handshake_order(const std::string& certificate_pem);

/// Creates the directory with every file (see the file comment). Writes into a temporary
/// sibling and renames it at the end: on any failure (openssl missing or failing, a bad name)
/// nothing is left behind. Throws std::runtime_error saying which step failed.
void init_security_dir(const SecurityInitOptions& o);

/// The <Security> element of a Cyclone configuration for identity `identity` ("server",
/// "renderer" or a client's name) from a directory made by init_security_dir. Throws
/// std::runtime_error naming the first missing file.
std::string security_config_element(const std::string& dir, const std::string& identity);

/// Where Cyclone's security plugins are (Debian: a private directory beside libddsc).
std::string security_plugin_dir();

}  // namespace stroma
