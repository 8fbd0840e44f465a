#include "dds/dds_security.hpp"

#include <dlfcn.h>
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <stdexcept>

#include <dds/dds.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509.h>
#include <fmt/format.h>

extern char** environ;

namespace stroma {

namespace fs = std::filesystem;

namespace {

/// A CRTK device's topics under rt/<tool>/ (server/crtk_bridge.cpp): what a client writes, what
/// the server writes.
const char* const kCrtkDeviceIn[] = {"servo_cp", "state_command", "jaw/servo_jp"};
const char* const kCrtkDeviceOut[] = {"measured_cp", "measured_cf", "operating_state", "jaw/measured_js"};
/// What every ROS 2 node (rclcpp/rclpy on rmw_cyclonedds_cpp) writes and reads besides its own
/// topics: the graph's discovery info, its log, parameter events and its parameter services. A
/// client identity gets them so that an SROS2-enforced node built on it can start (docs/CRTK.md);
/// the server reads none of them.
const char* const kRos2NodeTopics[] = {"ros_discovery_info", "rt/rosout", "rt/parameter_events", "rq/*", "rr/*"};

/// Server → client topics (the server writes them; readers as permitted).
const char* const kServerTopics[] = {"stroma_ToolFeedback", "stroma_TissueMesh",     "stroma_TissueState",
                                     "stroma_ToolState",    "stroma_Scene",          "stroma_DamageEvent",
                                     "stroma_SimStatus",    "stroma_TopologyEvent",  "stroma_RigidBody",
                                     "stroma_RigidBodyState", "stroma_NeedleEvent",   "stroma_ThreadState"};
/// What the renderer reads.
const char* const kRendererTopics[] = {"stroma_TissueMesh", "stroma_TissueState",    "stroma_ToolState",
                                       "stroma_Scene",      "stroma_DamageEvent",    "stroma_SimStatus",
                                       "stroma_TopologyEvent", "stroma_RigidBody",   "stroma_RigidBodyState",
                                       "stroma_ThreadState"};

/// Certificate subjects: no spaces (Cyclone compares subject names token by token). `group`
/// (empty, or an organisational unit chosen by make_identity) steers the handshake order.
std::string subject(const std::string& name, const std::string& group) {
  return "CN=stroma-" + name + (group.empty() ? "" : ",OU=" + group) + ",O=Stroma";
}

bool valid_name(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-')) return false;
  return true;
}

/// Runs `openssl ARGS…` in `cwd` (no shell), its output discarded; throws with `step` on failure.
void openssl(const fs::path& cwd, const std::vector<std::string>& args, const std::string& step) {
  std::vector<std::string> full = {"openssl"};
  full.insert(full.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : full) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addchdir_np(&fa, cwd.c_str());
  posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  const fs::path err = cwd / ".openssl_errors";
  posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, "openssl", &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0)
    throw std::runtime_error(fmt::format("security init: {}: cannot run 'openssl' ({}): install it (scripts/setup.sh)",
                                         step, std::strerror(rc)));
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::ifstream e(err);
    std::string line, last;
    while (std::getline(e, line))
      if (!line.empty()) last = line;
    throw std::runtime_error(fmt::format("security init: {}: openssl failed: {}", step, last));
  }
}

void write_file(const fs::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
  if (!f) throw std::runtime_error(fmt::format("security init: cannot write '{}'", p.string()));
}

std::string topic_list(const std::vector<std::string>& topics) {
  std::string s;
  for (const auto& t : topics) s += fmt::format("            <topic>{}</topic>\n", t);
  return s;
}

/// One allow_rule: publish `pub` in partitions `pub_parts` ("*" when empty), subscribe `sub`.
std::string allow_rule(const SecurityInitOptions& o, const std::vector<std::string>& pub,
                       const std::vector<std::string>& pub_parts, const std::vector<std::string>& sub) {
  std::string s = fmt::format(
      "      <allow_rule>\n        <domains><id_range><min>{}</min><max>{}</max></id_range></domains>\n",
      o.domain_min, o.domain_max);
  if (!pub.empty()) {
    s += "        <publish>\n          <topics>\n" + topic_list(pub) + "          </topics>\n";
    s += "          <partitions>\n";
    if (pub_parts.empty()) s += "            <partition>*</partition>\n";
    for (const auto& p : pub_parts) s += fmt::format("            <partition>{}</partition>\n", p);
    s += "          </partitions>\n        </publish>\n";
  }
  if (!sub.empty())
    s += "        <subscribe>\n          <topics>\n" + topic_list(sub) +
         "          </topics>\n          <partitions><partition>*</partition></partitions>\n        </subscribe>\n";
  s += "      </allow_rule>\n";
  return s;
}

std::string permissions_xml(const SecurityInitOptions& o, const std::string& name, const std::string& group,
                            const std::string& rules) {
  return fmt::format(R"(<?xml version="1.0" encoding="utf-8"?>
<!-- Stroma: what identity '{0}' may do (stroma security init). Signed: permissions_{0}.p7s -->
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="https://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="{0}">
      <subject_name>{1}</subject_name>
      <validity><not_before>2020-01-01T00:00:00</not_before><not_after>2100-01-01T00:00:00</not_after></validity>
{2}      <default>DENY</default>
    </grant>
  </permissions>
</dds>
)",
                     name, subject(name, group), rules);
}

std::string governance_xml(const SecurityInitOptions& o) {
  return fmt::format(R"(<?xml version="1.0" encoding="utf-8"?>
<!-- Stroma's protected domain (stroma security init): only authenticated participants join;
     every topic's readers and writers are access-controlled (permissions_*.p7s), its data and
     metadata encrypted (AES-GCM). Signed: governance.p7s -->
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="https://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id_range><min>{}</min><max>{}</max></id_range></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>NONE</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
)",
                     o.domain_min, o.domain_max);
}

/// Makes identity `name` (key and certificate signed by the identity CA) whose authentication
/// handshake order is `order` (identity_handshake_order): its subject gets an organisational unit
/// g0, g1, ... until it has that order (about two tries). Returns the unit.
std::string make_identity(const fs::path& d, const std::string& name, int days, HandshakeOrder order) {
  const std::string key = name + "_key.pem", csr = name + ".csr", cert = name + ".pem";
  openssl(d, {"genrsa", "-out", key, "2048"}, "key of '" + name + "'");
  for (int k = 0; k < 256; ++k) {
    const std::string group = fmt::format("g{}", k);
    openssl(d, {"req", "-new", "-key", key, "-out", csr, "-subj", "/O=Stroma/OU=" + group + "/CN=stroma-" + name},
            "certificate request of '" + name + "'");
    openssl(d, {"x509", "-req", "-CA", "identity_ca.pem", "-CAkey", "identity_ca_key.pem", "-CAcreateserial", "-days",
                std::to_string(days), "-in", csr, "-out", cert},
            "certificate of '" + name + "'");
    fs::remove(d / csr);
    if (identity_handshake_order((d / cert).string()) == order) return group;
  }
  throw std::runtime_error(fmt::format("security init: no subject for '{}' with the handshake order asked", name));
}

void sign(const fs::path& d, const std::string& xml, const std::string& p7s) {
  openssl(d, {"smime", "-sign", "-in", xml, "-text", "-out", p7s, "-signer", "permissions_ca.pem", "-inkey",
              "permissions_ca_key.pem"},
          "signing " + xml);
}

}  // namespace

void init_security_dir(const SecurityInitOptions& o) {
  if (o.dir.empty()) throw std::runtime_error("security init: no directory given");
  const fs::path dir = fs::path(o.dir);
  if (fs::exists(dir))
    throw std::runtime_error(fmt::format("security init: '{}' exists: give a new directory (nothing is overwritten)",
                                         o.dir));
  if (o.clients.empty()) throw std::runtime_error("security init: at least one client is needed");
  std::set<std::string> names = {"server", "renderer", "identity_ca", "permissions_ca"};
  for (const SecurityClient& c : o.clients) {
    if (!valid_name(c.name))
      throw std::runtime_error(fmt::format("security init: client name '{}' must be 1-64 of A-Z a-z 0-9 _ -", c.name));
    if (!names.insert(c.name).second)
      throw std::runtime_error(fmt::format("security init: client name '{}' is taken (server, renderer, the CAs, "
                                           "or another client)",
                                           c.name));
    if (c.tools.empty()) throw std::runtime_error(fmt::format("security init: client '{}' has no tool", c.name));
    for (const std::string& t : c.tools)
      if (!valid_name(t))
        throw std::runtime_error(fmt::format("security init: tool name '{}' must be 1-64 of A-Z a-z 0-9 _ -", t));
  }
  if (o.days < 1) throw std::runtime_error("security init: --days must be at least 1");
  // Everything is made in a temporary sibling, renamed into place at the end.
  const fs::path parent = dir.has_parent_path() ? dir.parent_path() : fs::path(".");
  if (!fs::is_directory(parent))
    throw std::runtime_error(fmt::format("security init: '{}' is not a directory", parent.string()));
  const fs::path tmp = parent / (dir.filename().string() + ".incomplete-" + std::to_string(getpid()));
  fs::remove_all(tmp);
  fs::create_directory(tmp);
  fs::permissions(tmp, fs::perms::owner_all);  // private keys inside
  try {
    const std::string days = std::to_string(o.days);
    openssl(tmp, {"genrsa", "-out", "identity_ca_key.pem", "2048"}, "identity CA key");
    openssl(tmp, {"req", "-x509", "-key", "identity_ca_key.pem", "-out", "identity_ca.pem", "-days", days, "-subj",
                  "/O=Stroma/CN=stroma-identity-ca"},
            "identity CA certificate");
    openssl(tmp, {"genrsa", "-out", "permissions_ca_key.pem", "2048"}, "permissions CA key");
    openssl(tmp, {"req", "-x509", "-key", "permissions_ca_key.pem", "-out", "permissions_ca.pem", "-days", days, "-subj",
                  "/O=Stroma/CN=stroma-permissions-ca"},
            "permissions CA certificate");
    write_file(tmp / "governance.xml", governance_xml(o));
    sign(tmp, "governance.xml", "governance.p7s");

    std::vector<std::string> server_pub(std::begin(kServerTopics), std::end(kServerTopics));
    std::vector<std::string> server_sub{"stroma_ToolCommand", "stroma_Control"};
    // `serve --crtk` (docs/CRTK.md): every tool as a CRTK device in ROS 2's topic names.
    for (const char* leaf : kCrtkDeviceOut) server_pub.push_back(fmt::format("rt/*/{}", leaf));
    for (const char* leaf : kCrtkDeviceIn) server_sub.push_back(fmt::format("rt/*/{}", leaf));
    // Stroma's own participants come first in the handshake order, clients after (see
    // identity_handshake_order): a Fast DDS client then always lets Cyclone begin.
    const std::string server_group = make_identity(tmp, "server", o.days, HandshakeOrder::Initiator);
    write_file(tmp / "permissions_server.xml",
               permissions_xml(o, "server", server_group, allow_rule(o, server_pub, {}, server_sub)));
    sign(tmp, "permissions_server.xml", "permissions_server.p7s");

    const std::string renderer_group = make_identity(tmp, "renderer", o.days, HandshakeOrder::Initiator);
    write_file(tmp / "permissions_renderer.xml",
               permissions_xml(o, "renderer", renderer_group,
                               allow_rule(o, {}, {}, {std::begin(kRendererTopics), std::end(kRendererTopics)})));
    sign(tmp, "permissions_renderer.xml", "permissions_renderer.p7s");

    for (const SecurityClient& c : o.clients) {
      const std::string group = make_identity(tmp, c.name, o.days, HandshakeOrder::Replier);
      // Commands only in its tools' partitions; Control (pause, step, reset, stop) only for an
      // operator: a trainee's client cannot stop the session.
      std::string rules = allow_rule(o, {"stroma_ToolCommand"}, c.tools, {"stroma_ToolFeedback", "stroma_SimStatus"});
      // The same tools as CRTK devices (`serve --crtk`): command them, read what they measure.
      std::vector<std::string> crtk_pub, crtk_sub;
      for (const std::string& t : c.tools) {
        for (const char* leaf : kCrtkDeviceIn) crtk_pub.push_back(fmt::format("rt/{}/{}", t, leaf));
        for (const char* leaf : kCrtkDeviceOut) crtk_sub.push_back(fmt::format("rt/{}/{}", t, leaf));
      }
      for (const char* t : kRos2NodeTopics) {
        crtk_pub.emplace_back(t);
        crtk_sub.emplace_back(t);
      }
      rules += allow_rule(o, crtk_pub, {}, crtk_sub);
      if (c.control) rules += allow_rule(o, {"stroma_Control"}, {}, {});
      write_file(tmp / ("permissions_" + c.name + ".xml"), permissions_xml(o, c.name, group, rules));
      sign(tmp, "permissions_" + c.name + ".xml", "permissions_" + c.name + ".p7s");
    }
    fs::remove(tmp / ".openssl_errors");
    fs::remove(tmp / "identity_ca.srl");
    fs::rename(tmp, dir);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
}

HandshakeOrder identity_handshake_order(const std::string& certificate_pem) {
  std::FILE* f = std::fopen(certificate_pem.c_str(), "r");
  if (!f) throw std::runtime_error(fmt::format("{}: cannot read the certificate", certificate_pem));
  X509* cert = PEM_read_X509(f, nullptr, nullptr, nullptr);
  std::fclose(f);
  if (!cert) throw std::runtime_error(fmt::format("{}: not a PEM certificate", certificate_pem));
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int n = 0;
  const int ok = X509_NAME_digest(X509_get_subject_name(cert), EVP_sha256(), md, &n);
  X509_free(cert);
  if (!ok || n < 1) throw std::runtime_error(fmt::format("{}: cannot hash the subject", certificate_pem));
  return md[0] < 0x80 ? HandshakeOrder::Initiator : HandshakeOrder::Replier;
}

std::string security_plugin_dir() {
  // The plugins sit beside libddsc (upstream) or in its Debian private directory.
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&dds_create_participant), &info) && info.dli_fname) {
    const fs::path lib = fs::path(info.dli_fname).parent_path();
    for (const fs::path& d : {lib / "libddsc0debian", lib})
      if (fs::exists(d / "libdds_security_auth.so")) return d.string();
  }
  return "";
}

std::string security_config_element(const std::string& dir, const std::string& identity) {
  const fs::path d = fs::absolute(dir);
  const std::string files[] = {"identity_ca.pem", identity + ".pem", identity + "_key.pem", "permissions_ca.pem",
                               "governance.p7s", "permissions_" + identity + ".p7s"};
  for (const std::string& f : files)
    if (!fs::exists(d / f))
      throw std::runtime_error(fmt::format("--security {}: no '{}' (identity '{}'; make the directory with "
                                           "'stroma security init')",
                                           dir, f, identity));
  const std::string plugins = security_plugin_dir();
  if (plugins.empty())
    throw std::runtime_error("--security: Cyclone DDS's security plugins (libdds_security_auth.so) are not installed");
  auto lib = [&](const char* name) { return (fs::path(plugins) / (std::string("lib") + name + ".so")).string(); };
  auto uri = [&](const std::string& f) { return "file:" + (d / f).string(); };
  return fmt::format(
      "<Security>"
      "<Authentication><Library initFunction=\"init_authentication\" finalizeFunction=\"finalize_authentication\" "
      "path=\"{}\"/><IdentityCA>{}</IdentityCA><IdentityCertificate>{}</IdentityCertificate>"
      "<PrivateKey>{}</PrivateKey></Authentication>"
      "<Cryptographic><Library initFunction=\"init_crypto\" finalizeFunction=\"finalize_crypto\" path=\"{}\"/>"
      "</Cryptographic>"
      "<AccessControl><Library initFunction=\"init_access_control\" finalizeFunction=\"finalize_access_control\" "
      "path=\"{}\"/><PermissionsCA>{}</PermissionsCA><Governance>{}</Governance><Permissions>{}</Permissions>"
      "</AccessControl></Security>",
      lib("dds_security_auth"), uri("identity_ca.pem"), uri(identity + ".pem"), uri(identity + "_key.pem"),
      lib("dds_security_crypto"), lib("dds_security_ac"), uri("permissions_ca.pem"), uri("governance.p7s"),
      uri("permissions_" + identity + ".p7s"));
}

}  // namespace stroma
