// Loopback with the user's own configuration (issue 41 §6): which Cyclone configurations keep a
// participant on this host (dds/loopback_config.hpp), and which binds the sealed interposer
// redirects (dds/loopback_bind.hpp). No socket is opened here.

#include <gtest/gtest.h>

#include <filesystem>
#include <exception>
#include <fstream>
#include <string>

#include <dds/dds.h>

#include "dds/loopback_bind.hpp"
#include "dds/loopback_config.hpp"

namespace fs = std::filesystem;
using stroma::is_loopback_only_config;

namespace {

std::string shipped() {
  std::ifstream f(std::string(STROMA_SOURCE_DIR) + "/dds/cyclonedds-loopback.xml");
  return std::string(std::istreambuf_iterator<char>(f), {});
}

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? s : s.replace(at, from.size(), to);
}

int not_cyclone() { return 42; }

}  // namespace

TEST(LoopbackConfig, TheShippedTemplateAndItsVariantsOnThisHostAreLoopbackOnly) {
  std::string why;
  EXPECT_TRUE(is_loopback_only_config(shipped(), &why)) << why;
  EXPECT_TRUE(is_loopback_only_config(replaced(shipped(), "name=\"lo\"", "address=\"127.0.0.1\""), &why)) << why;
  EXPECT_TRUE(is_loopback_only_config(replaced(shipped(), "address=\"127.0.0.1\"", "address=\"localhost:7410\""), &why))
      << why;
  // A comment naming another interface changes nothing.
  EXPECT_TRUE(is_loopback_only_config("<!-- <NetworkInterface name=\"eth0\"/> -->" + shipped(), &why)) << why;
  // Deprecated form.
  EXPECT_TRUE(is_loopback_only_config(
      "<CycloneDDS><Domain><General><NetworkInterfaceAddress>127.0.0.1</NetworkInterfaceAddress>"
      "<AllowMulticast>false</AllowMulticast></General></Domain></CycloneDDS>",
      &why))
      << why;
}

TEST(LoopbackConfig, AnythingThatMayLeaveTheHostIsNot) {
  std::string why;
  EXPECT_FALSE(is_loopback_only_config(replaced(shipped(), "name=\"lo\"", "name=\"eth0\""), &why));
  EXPECT_NE(why.find("eth0"), std::string::npos) << why;
  EXPECT_FALSE(is_loopback_only_config(replaced(shipped(), "address=\"127.0.0.1\"", "address=\"192.168.1.20\""), &why));
  EXPECT_NE(why.find("192.168.1.20"), std::string::npos) << why;
  EXPECT_FALSE(is_loopback_only_config(replaced(shipped(), "<AllowMulticast>false</AllowMulticast>", ""), &why));
  EXPECT_FALSE(is_loopback_only_config(replaced(shipped(), ">false<", ">spdp<"), &why));
  EXPECT_FALSE(is_loopback_only_config(
      replaced(shipped(), "<NetworkInterface name=\"lo\"/>", "<NetworkInterface autodetermine=\"true\"/>"), &why));
  EXPECT_FALSE(is_loopback_only_config(replaced(shipped(), "<Interfaces><NetworkInterface name=\"lo\"/></Interfaces>", ""),
                                       &why));
  EXPECT_NE(why.find("no network interface"), std::string::npos) << why;
  EXPECT_FALSE(is_loopback_only_config("", &why));
}

TEST(LoopbackConfig, ACycloneUriIsReadItemByItem) {
  const fs::path f = fs::temp_directory_path() / ("stroma_lo_" + std::to_string(getpid()) + ".xml");
  std::ofstream(f) << shipped();
  bool ok = false;
  std::string text = stroma::cyclone_uri_text("file://" + f.string(), &ok);
  EXPECT_TRUE(ok && is_loopback_only_config(text));
  // A later fragment that adds a peer elsewhere makes the merged configuration non-local.
  text = stroma::cyclone_uri_text(
      "file://" + f.string() +
          ",<CycloneDDS><Domain><Discovery><Peers><Peer address=\"10.0.0.7\"/></Peers></Discovery></Domain></CycloneDDS>",
      &ok);
  EXPECT_TRUE(ok);
  EXPECT_FALSE(is_loopback_only_config(text));
  stroma::cyclone_uri_text("file:///nonexistent/stroma.xml", &ok);
  EXPECT_FALSE(ok);
  fs::remove(f);
}

TEST(LoopbackBind, AppliesOnlyToBindsCalledFromCycloneDds) {
  stroma::enable_loopback_bind();
  EXPECT_TRUE(stroma::loopback_bind_enabled());
  EXPECT_TRUE(stroma::loopback_bind_applies_to(reinterpret_cast<const void*>(&dds_create_topic)));
  EXPECT_FALSE(stroma::loopback_bind_applies_to(reinterpret_cast<const void*>(&not_cyclone)))
      << "the program's own binds are the C library's";
  EXPECT_FALSE(stroma::loopback_bind_applies_to(reinterpret_cast<const void*>(&std::terminate)))
      << "another library's binds are the C library's";
  EXPECT_EQ(not_cyclone(), 42);
}
