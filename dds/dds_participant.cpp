#include "dds/dds_participant.hpp"

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

#include "dds/dds_security.hpp"
#include "dds/loopback_bind.hpp"
#include "dds/loopback_config.hpp"
#include "runtime/realtime.hpp"

namespace stroma {

const char* const kLoopbackDdsConfig =
    "<CycloneDDS><Domain Id=\"any\">"
    "<General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General>"
    "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>20</MaxAutoParticipantIndex>"
    "<Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery>"
    "</Domain></CycloneDDS>";

std::string loopback_config_with_receive_priority(int priority) {
  std::string xml = kLoopbackDdsConfig;
  std::string threads = "<Threads>";
  for (const char* name : {"recv"})
    threads += fmt::format("<Thread Name=\"{}\"><Scheduling><Class>realtime</Class><Priority>{}</Priority>"
                           "</Scheduling></Thread>",
                           name, priority);
  threads += "</Threads>";
  // Cyclone 0.10 configures only "recv" by name; its extra unicast receive thread ("recvUC",
  // MultipleReceiveThreads) would stay at normal priority. One receive thread serves the few
  // loopback sockets as well, at the priority asked for.
  threads += "<Internal><MultipleReceiveThreads>false</MultipleReceiveThreads></Internal>";
  xml.insert(xml.find("</Domain>"), threads);
  return xml;
}

dds_return_t dds_check(dds_return_t rc, const char* what) {
  if (rc < 0) throw std::runtime_error(fmt::format("{}: {}", what, dds_strretcode(rc)));
  return rc;
}

DdsParticipant create_participant(int domain_id, const std::string& config_file, int receive_priority,
                                  const std::string& security_dir, const std::string& identity) {
  DdsParticipant p;
  std::string xml;
  const char* env_uri = std::getenv("CYCLONEDDS_URI");
  if (!config_file.empty()) {
    std::ifstream f(config_file);
    if (!f) throw std::runtime_error(fmt::format("--dds-config: cannot open '{}'", config_file));
    std::stringstream ss;
    ss << f.rdbuf();
    xml = ss.str();
    p.config_source = config_file;
  } else if (env_uri && *env_uri) {
    p.config_source = std::string("CYCLONEDDS_URI=") + env_uri;
  } else if (receive_priority > 0 && fifo_permitted(receive_priority)) {
    xml = loopback_config_with_receive_priority(receive_priority);
    p.config_source = fmt::format(
        "built-in loopback configuration (lo only, no multicast; receive thread SCHED_FIFO {})", receive_priority);
  } else {
    xml = kLoopbackDdsConfig;
    p.config_source = "built-in loopback configuration (lo only, no multicast)";
    if (receive_priority > 0) p.config_source += "; receive thread at normal priority (SCHED_FIFO denied)";
  }
  // The built-in configuration promises loopback only: its sockets are bound to loopback too
  // (dds/loopback_bind.hpp), not just told to use "lo". So is a user's own configuration when it
  // keeps to the same rule (dds/loopback_config.hpp); any other is used as given.
  if (config_file.empty() && !(env_uri && *env_uri)) {
    enable_loopback_bind();
  } else {
    bool readable = true;
    const std::string text = !config_file.empty() ? xml : cyclone_uri_text(env_uri, &readable);
    std::string why;
    if (readable && is_loopback_only_config(text, &why)) {
      enable_loopback_bind();
      p.config_source += "; " + why + ": sockets bound to loopback";
    }
  }
  if (!security_dir.empty()) {
    const std::string sec = security_config_element(security_dir, identity);
    if (xml.empty()) {
      // CYCLONEDDS_URI's configuration, then the security settings (a configuration string is
      // a comma-separated list of files and XML fragments, merged in order).
      xml = std::string(env_uri) + ",<CycloneDDS><Domain Id=\"any\">" + sec + "</Domain></CycloneDDS>";
    } else {
      xml.insert(xml.rfind("</Domain>"), sec);
    }
    p.config_source += fmt::format("; DDS Security as '{}' ({})", identity, security_dir);
    // Stroma's own identities begin every handshake with a client (dds_security.hpp): one made
    // before that rule lets a Fast DDS client begin, which fails against Cyclone.
    const bool stroma_side = identity == "server" || identity == "renderer";
    const HandshakeOrder want = stroma_side ? HandshakeOrder::Initiator : HandshakeOrder::Replier;
    if (identity_handshake_order(security_dir + "/" + identity + ".pem") != want)
      fmt::print(stderr,
                 "warning: the identity '{}' in {} was made by an older `stroma security init`: Fast DDS clients (ROS 2 "
                 "on rmw_fastrtps) may fail to authenticate with it (SECURITY.md); Cyclone clients are not affected. "
                 "Run `stroma security init NEW_DIR` with the same clients to fix it\n",
                 identity, security_dir);
  }
  if (!xml.empty()) {
    const dds_entity_t d = dds_create_domain(static_cast<dds_domainid_t>(domain_id), xml.c_str());
    // A domain already created in this process (a second participant) keeps its configuration.
    if (d < 0 && d != DDS_RETCODE_PRECONDITION_NOT_MET)
      throw std::runtime_error(fmt::format("DDS domain {} with {}: {}", domain_id, p.config_source,
                                           dds_strretcode(d)));
  }
  p.participant = dds_create_participant(static_cast<dds_domainid_t>(domain_id), nullptr, nullptr);
  if (p.participant < 0)
    throw std::runtime_error(fmt::format("DDS participant on domain {}: {}", domain_id,
                                         dds_strretcode(p.participant)));
  return p;
}

void close_dds(const DdsParticipant& p) {
  if (p.participant > 0) dds_delete(p.participant);
  dds_delete(DDS_CYCLONEDDS_HANDLE);
}

}  // namespace stroma
