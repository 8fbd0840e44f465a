// DDS Security (issue 15 §2): a protected domain made by `stroma security init`, on loopback.
// Who may command a tool, who may read the tissue, and that the renderer works with its own
// identity. The server's --stats file says what reached physics.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "dds/dds_participant.hpp"
#include "stroma.h"
#include "tests/server/process.hpp"

namespace fs = std::filesystem;
using stroma::test::Process;

namespace {

const std::string kLiver = std::string(STROMA_SOURCE_DIR) + "/scenarios/liver.yaml";
const std::string kPress = std::string(STROMA_SOURCE_DIR) + "/scenarios/trajectories/liver_press.yaml";

/// A security directory for this test binary: clients 'tool' (may command probe, and operate the
/// session) and 'intruder' (may command scalpel only). Made once.
const fs::path& security_dir() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("stroma_security_" + std::to_string(getpid()));
    fs::remove_all(d);
    Process init({STROMA_BINARY, "security", "init", d.string(), "--client", "tool=probe", "--client",
                  "intruder=scalpel", "--operator", "tool"});
    EXPECT_EQ(init.wait_exit(60), 0) << "stroma security init failed";
    return d;
  }();
  return dir;
}

std::string read_file(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// A protected server on `domain`, writing its statistics to `stats`.
Process secure_server(int domain, const fs::path& stats) {
  return Process({STROMA_BINARY, "serve", kLiver, "--domain", std::to_string(domain), "--realtime", "off", "--duration",
                  "60", "--security", security_dir().string(), "--stats", stats.string()});
}

}  // namespace

TEST(Security, InitMakesEveryIdentityAndSignedDocumentAndOverwritesNothing) {
  const fs::path& d = security_dir();
  for (const char* f : {"identity_ca.pem", "permissions_ca.pem", "governance.p7s", "server.pem", "server_key.pem",
                        "renderer.pem", "tool.pem", "tool_key.pem", "intruder.pem", "permissions_server.p7s",
                        "permissions_renderer.p7s", "permissions_tool.p7s", "permissions_intruder.p7s"})
    EXPECT_TRUE(fs::exists(d / f)) << f;
  // The private keys are the owner's only.
  EXPECT_EQ(fs::status(d).permissions() & (fs::perms::group_all | fs::perms::others_all), fs::perms::none);
  // The tool client may write commands in its tool's partition only.
  const std::string perm = read_file(d / "permissions_tool.xml");
  EXPECT_NE(perm.find("<partition>probe</partition>"), std::string::npos) << perm;
  EXPECT_EQ(perm.find("<partition>scalpel</partition>"), std::string::npos);
  EXPECT_NE(perm.find("<default>DENY</default>"), std::string::npos);
  // Control (pause, step, reset, stop) is the operator's only.
  EXPECT_NE(perm.find("stroma_Control"), std::string::npos) << perm;
  EXPECT_EQ(read_file(d / "permissions_intruder.xml").find("stroma_Control"), std::string::npos);
  // Nothing is overwritten; a bad request leaves nothing behind.
  Process again({STROMA_BINARY, "security", "init", d.string()});
  EXPECT_EQ(again.wait_exit(30), 2);
  const fs::path bad = fs::temp_directory_path() / ("stroma_security_bad_" + std::to_string(getpid()));
  Process bad_init({STROMA_BINARY, "security", "init", bad.string(), "--client", "server=probe"});
  EXPECT_EQ(bad_init.wait_exit(30), 2);
  EXPECT_FALSE(fs::exists(bad));
  Process bad_operator({STROMA_BINARY, "security", "init", bad.string(), "--client", "a=probe", "--operator", "b"});
  EXPECT_EQ(bad_operator.wait_exit(30), 2);
  EXPECT_FALSE(fs::exists(bad));
}

TEST(Security, AnAuthorisedClientDrivesTheTool) {
  const fs::path stats = fs::temp_directory_path() / ("stroma_sec_ok_" + std::to_string(getpid()) + ".json");
  Process server = secure_server(131, stats);
  Process tool({STROMA_BINARY, "tool", "--security", security_dir().string(), "--identity", "tool", "--name", "probe",
                "--script", kPress, "--duration", "2", "--domain", "131", "--wait", "20", "--no-realtime"});
  EXPECT_EQ(tool.wait_exit(60), 0) << "the authorised client got no feedback";
  server.signal(SIGTERM);
  ASSERT_EQ(server.wait_exit(20), 0);
  const auto j = nlohmann::json::parse(read_file(stats));
  EXPECT_GT(j["tool_commands"]["accepted"].get<int>() + j["tool_commands"]["clamped"].get<int>(), 500);
  EXPECT_NE(j["dds"]["config"].get<std::string>().find("DDS Security as 'server'"), std::string::npos);
  fs::remove(stats);
}

TEST(Security, UnauthenticatedAndUnpermittedClientsCommandNothing) {
  const fs::path stats = fs::temp_directory_path() / ("stroma_sec_deny_" + std::to_string(getpid()) + ".json");
  Process server = secure_server(132, stats);
  // No identity: never matched, so it finds no server to command.
  Process plain({STROMA_BINARY, "tool", "--name", "probe", "--script", kPress, "--duration", "1", "--domain", "132",
                 "--wait", "5", "--no-realtime"});
  EXPECT_EQ(plain.wait_exit(60), 1);
  // Authenticated, permitted to command 'scalpel' only: its writer for 'probe' is refused.
  Process intruder({STROMA_BINARY, "tool", "--security", security_dir().string(), "--identity", "intruder", "--name",
                    "probe", "--script", kPress, "--duration", "1", "--domain", "132", "--wait", "5",
                    "--no-realtime"});
  EXPECT_EQ(intruder.wait_exit(60), 2);
  server.signal(SIGTERM);
  ASSERT_EQ(server.wait_exit(20), 0);
  const auto j = nlohmann::json::parse(read_file(stats));
  EXPECT_EQ(j["tool_commands"]["received"].get<int>(), 0) << "a command reached the protected server";
  fs::remove(stats);
}

namespace {

/// Samples of TissueState, ToolFeedback and SimStatus a plain (unauthenticated) participant of
/// this process receives on `domain` within `seconds`.
int plain_samples(int domain, double seconds) {
  const dds_entity_t pp = stroma::create_participant(domain, "").participant;
  const dds_entity_t t_state = dds_create_topic(pp, &stroma_TissueState_desc, "stroma_TissueState", nullptr, nullptr);
  const dds_entity_t t_fb = dds_create_topic(pp, &stroma_ToolFeedback_desc, "stroma_ToolFeedback", nullptr, nullptr);
  const dds_entity_t t_status = dds_create_topic(pp, &stroma_SimStatus_desc, "stroma_SimStatus", nullptr, nullptr);
  const dds_entity_t readers[] = {dds_create_reader(pp, t_state, nullptr, nullptr),
                                  dds_create_reader(pp, t_fb, nullptr, nullptr),
                                  dds_create_reader(pp, t_status, nullptr, nullptr)};
  int n = 0;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    for (dds_entity_t r : readers) {
      void* samples[8] = {nullptr};
      dds_sample_info_t infos[8];
      const dds_return_t k = dds_take(r, samples, infos, 8, 8);
      for (dds_return_t i = 0; i < k; ++i) n += infos[i].valid_data;
      if (k > 0) dds_return_loan(r, samples, k);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  dds_delete(pp);
  return n;
}

}  // namespace

TEST(Security, APlainParticipantCannotReadStateFeedbackOrStatus) {
  // An open server first: the same readers do receive there (the check can fail).
  {
    Process open_server({STROMA_BINARY, "serve", kLiver, "--domain", "133", "--realtime", "off", "--duration", "60"});
    Process tool({STROMA_BINARY, "tool", "--name", "probe", "--script", kPress, "--duration", "4", "--domain", "133",
                  "--no-realtime"});
    EXPECT_GT(plain_samples(133, 3.0), 0);
    open_server.signal(SIGTERM);
    open_server.wait_exit(20);
  }
  const fs::path stats = fs::temp_directory_path() / ("stroma_sec_read_" + std::to_string(getpid()) + ".json");
  Process server = secure_server(134, stats);
  Process tool({STROMA_BINARY, "tool", "--security", security_dir().string(), "--identity", "tool", "--name", "probe",
                "--script", kPress, "--duration", "6", "--domain", "134", "--wait", "20", "--no-realtime"});
  std::this_thread::sleep_for(std::chrono::seconds(2));  // the authorised client is being served
  EXPECT_EQ(plain_samples(134, 3.0), 0) << "a plain participant read the protected domain";
  EXPECT_EQ(tool.wait_exit(60), 0);
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(20), 0);
  fs::remove(stats);
}

#ifdef STROMA_TEST_RENDER
TEST(Security, TheRendererWorksWithItsOwnIdentity) {
  const fs::path stats = fs::temp_directory_path() / ("stroma_sec_render_" + std::to_string(getpid()) + ".json");
  const fs::path out = fs::temp_directory_path() / ("stroma_sec_frames_" + std::to_string(getpid()));
  fs::remove_all(out);
  Process server = secure_server(135, stats);
  Process renderer({STROMA_BINARY, "render", "--security", security_dir().string(), "--domain", "135", "--out",
                    out.string(), "--frames", "5", "--fps", "10", "--width", "160", "--height", "120", "--msaa", "0",
                    "--no-video", "--wait", "30"});
  EXPECT_EQ(renderer.wait_exit(90), 0);
  for (int i = 0; i < 5; ++i) EXPECT_TRUE(fs::exists(out / fmt::format("frame_{:06d}.png", i))) << i;
  server.signal(SIGTERM);
  EXPECT_EQ(server.wait_exit(20), 0);
  fs::remove_all(out);
  fs::remove(stats);
}
#endif
