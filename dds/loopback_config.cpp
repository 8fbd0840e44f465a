#include "dds/loopback_config.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <regex>
#include <sstream>

namespace stroma {

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t\r\n") - a + 1);
}

/// A host this machine answers on only: 127.0.0.0/8, ::1, localhost (an optional :port or
/// [v6]:port stripped).
bool local_host(std::string h) {
  h = lower(trim(h));
  if (h.empty()) return false;
  if (h.front() == '[') {
    const size_t e = h.find(']');
    if (e == std::string::npos) return false;
    h = h.substr(1, e - 1);
  } else if (std::count(h.begin(), h.end(), ':') == 1) {
    h = h.substr(0, h.find(':'));  // v4:port or name:port
  }
  if (h == "localhost" || h == "::1") return true;
  static const std::regex v4(R"(127\.\d{1,3}\.\d{1,3}\.\d{1,3})");
  return std::regex_match(h, v4);
}

std::string attribute(const std::string& tag, const char* name) {
  const std::regex re(std::string(R"(\b)") + name + R"(\s*=\s*["']([^"']*)["'])", std::regex::icase);
  std::smatch m;
  return std::regex_search(tag, m, re) ? std::string(m[1]) : std::string();
}

bool fail(std::string* why, const std::string& what) {
  if (why) *why = what;
  return false;
}

}  // namespace

std::string cyclone_uri_text(const std::string& uri, bool* ok) {
  *ok = true;
  std::string out;
  // Items are separated by commas outside XML (an XML fragment may itself hold commas).
  size_t i = 0;
  while (i < uri.size()) {
    while (i < uri.size() && (uri[i] == ',' || std::isspace(static_cast<unsigned char>(uri[i])))) ++i;
    if (i >= uri.size()) break;
    if (uri[i] == '<') {
      // An XML fragment: up to the closing </CycloneDDS> (or the end).
      const size_t e = lower(uri).find("</cyclonedds>", i);
      const size_t end = e == std::string::npos ? uri.size() : e + 13;
      out += uri.substr(i, end - i) + "\n";
      i = end;
    } else {
      size_t e = uri.find(',', i);
      if (e == std::string::npos) e = uri.size();
      std::string item = trim(uri.substr(i, e - i));
      if (item.rfind("file://", 0) == 0) item = item.substr(7);
      std::ifstream f(item);
      if (!f) {
        *ok = false;
      } else {
        std::stringstream ss;
        ss << f.rdbuf();
        out += ss.str() + "\n";
      }
      i = e;
    }
  }
  return out;
}

bool is_loopback_only_config(const std::string& xml_in, std::string* why) {
  // Comments say nothing about what Cyclone does.
  const std::string xml = std::regex_replace(xml_in, std::regex(R"(<!--[\s\S]*?-->)"), " ");
  int interfaces = 0;
  static const std::regex iface(R"(<\s*NetworkInterface\b[^>]*>)", std::regex::icase);
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), iface); it != std::sregex_iterator(); ++it) {
    const std::string tag = it->str();
    const std::string name = lower(attribute(tag, "name")), address = attribute(tag, "address");
    if (lower(attribute(tag, "autodetermine")) == "true") return fail(why, "a NetworkInterface autodetermines");
    if (name.empty() && address.empty()) return fail(why, "a NetworkInterface names neither name nor address");
    if (!name.empty() && name != "lo") return fail(why, "interface '" + name + "' is not lo");
    if (!address.empty() && !local_host(address)) return fail(why, "interface address " + address + " is not loopback");
    ++interfaces;
  }
  static const std::regex old_iface(R"(<\s*NetworkInterfaceAddress\s*>([^<]*)<)", std::regex::icase);
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), old_iface); it != std::sregex_iterator(); ++it) {
    const std::string v = lower(trim((*it)[1]));
    if (v != "lo" && !local_host(v)) return fail(why, "NetworkInterfaceAddress " + v + " is not loopback");
    ++interfaces;
  }
  if (interfaces == 0) return fail(why, "no network interface named (Cyclone picks one itself)");
  static const std::regex mc(R"(<\s*AllowMulticast\s*>([^<]*)<)", std::regex::icase);
  int mc_settings = 0;
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), mc); it != std::sregex_iterator(); ++it) {
    if (lower(trim((*it)[1])) != "false") return fail(why, "AllowMulticast is not false");
    ++mc_settings;
  }
  if (mc_settings == 0) return fail(why, "AllowMulticast is not set to false (Cyclone's default multicasts)");
  static const std::regex peer(R"(<\s*Peer\b[^>]*>)", std::regex::icase);
  int peers = 0;
  for (auto it = std::sregex_iterator(xml.begin(), xml.end(), peer); it != std::sregex_iterator(); ++it) {
    const std::string a = attribute(it->str(), "address");
    if (!local_host(a)) return fail(why, "peer '" + a + "' is not on this host");
    ++peers;
  }
  if (why) *why = "loopback-only: " + std::to_string(interfaces) + " loopback interface(s), no multicast, " +
                  std::to_string(peers) + " local peer(s)";
  return true;
}

}  // namespace stroma
