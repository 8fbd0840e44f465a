// engine/session_log: recorded server sessions round-trip exactly; interrupted logs are refused.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "runtime/session_log.hpp"
#include "tests/test_scenarios.hpp"
#include "tissue/input_error.hpp"

using namespace stroma;

using test_scenarios::write_temp;

TEST(SessionLog, RoundTripsExactlyAndRejectsInterruptedLogs) {
  SessionEvent a;
  a.kind = SessionEvent::Tool;
  a.tick = 12;
  a.input.tool = 1;
  a.input.seq = 99;
  a.input.client_time_ns = 123456789;
  a.input.pose.position = {0.1, 1.0 / 3.0, -2e-17};
  a.input.pose.orientation = {std::sqrt(0.5), 0, std::sqrt(0.5), 0};
  a.input.pose.jaw = 0.7;
  a.input.pose.buttons = 5;
  SessionEvent b;
  b.kind = SessionEvent::Step;
  b.tick = 12;
  b.steps = 7;
  SessionEvent cutoff;  // tick 12 ran out of its budget at its 37th deadline check
  cutoff.kind = SessionEvent::Deadline;
  cutoff.tick = 12;
  cutoff.deadline_check = 37;
  SessionEvent end;
  end.kind = SessionEvent::End;
  end.tick = 40;
  const std::string path =
      write_temp("stroma_session.log", std::string(kSessionLogHeader) + format_session_event(a) + format_session_event(b) +
                                           format_session_event(cutoff) + format_session_event(end));
  auto ev = read_session_log(path, 2);
  ASSERT_EQ(ev.size(), 4u);
  EXPECT_EQ(ev[2].kind, SessionEvent::Deadline);
  EXPECT_EQ(ev[2].deadline_check, 37);
  ev.erase(ev.begin() + 2);
  EXPECT_EQ(ev[0].input.pose.position, a.input.pose.position);  // bit-exact doubles
  EXPECT_EQ(ev[0].input.pose.orientation, a.input.pose.orientation);
  EXPECT_EQ(ev[0].input.seq, 99u);
  EXPECT_EQ(ev[0].input.pose.buttons, 5u);
  EXPECT_EQ(ev[1].steps, 7u);
  EXPECT_EQ(ev[2].tick, 40);
  const std::string cut = write_temp("stroma_session_cut.log", std::string(kSessionLogHeader) + format_session_event(a));
  EXPECT_THROW(read_session_log(cut, 2), InputError);
}


namespace {

/// The InputError a log with `body` (after the header) raises against `tools` tools.
InputError log_error(const std::string& body, int tools = 1) {
  const std::string path = write_temp("stroma_session_bad.log", std::string(kSessionLogHeader) + body);
  try {
    read_session_log(path, tools);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no error for: " << body;
  return InputError("", 0, "", "");
}

const char* const kGoodTool = "3,tool,0,1,5,0.1,0.2,0.3,1,0,0,0,0.5,0,0\n";

}  // namespace

// A replay indexes the scenario's tools with the logged index: replaying against a scenario
// with fewer tools crashed (SIGSEGV, heap corruption). Every out-of-range index is refused at
// load, naming the line and the field.
TEST(SessionLog, ToolIndexOutsideTheScenarioIsALoadError) {
  for (const char* idx : {"1", "-1", "1000"}) {
    const InputError e = log_error(std::string(kGoodTool) + "4,tool," + idx + ",2,6,0.1,0.2,0.3,1,0,0,0,0.5,0,0\n9,end,,,,,,,,,,,,,0\n");
    EXPECT_EQ(e.line(), 4) << idx;  // header lines 1-2, first tool line 3
    EXPECT_EQ(e.field(), "tool") << idx;
    EXPECT_NE(e.message().find("1 tool"), std::string::npos) << e.what();
  }
  // The same index is fine against a scenario with enough tools.
  const std::string ok = write_temp("stroma_session_ok.log", std::string(kSessionLogHeader) +
                                                                 "4,tool,1,2,6,0.1,0.2,0.3,1,0,0,0,0.5,0,0\n9,end,,,,,,,,,,,,,0\n");
  EXPECT_EQ(read_session_log(ok, 2).size(), 2u);
}

TEST(SessionLog, MalformedValuesNameTheirField) {
  struct Case {
    std::string line, field;
  };
  const Case cases[] = {
      {"3,tool,0,1,5,nan,0.2,0.3,1,0,0,0,0.5,0,0", "x"},
      {"3,tool,0,1,5,0.1,inf,0.3,1,0,0,0,0.5,0,0", "y"},
      {"3,tool,0,1,5,0.1,0.2,0.3,nan,0,0,0,0.5,0,0", "qw"},
      {"3,tool,0,1,5,0.1,0.2,0.3,0.5,0,0,0,0.5,0,0", "qw,qx,qy,qz"},
      {"3,tool,0,1,5,0.1,0.2,0.3,1,0,0,0,zero,0,0", "jaw"},
      {"3,tool,0,-1x,5,0.1,0.2,0.3,1,0,0,0,0.5,0,0", "seq"},
      {"3,tool,0,1,5,0.1,0.2,0.3,1,0,0,0,0.5,-2,0", "buttons"},
      {"x3,pause,,,,,,,,,,,,,", "tick"},
      {"3,step,,,,,,,,,,,,,many", "steps"},
      {"3,teleport,,,,,,,,,,,,,", "event"},
  };
  for (const Case& c : cases) {
    const InputError e = log_error(c.line + "\n9,end,,,,,,,,,,,,,0\n");
    EXPECT_EQ(e.line(), 3) << c.line;
    EXPECT_EQ(e.field(), c.field) << e.what();
  }
  // Quotes are capped and escaped: a 100,000-character value is not echoed back whole.
  const InputError long_value = log_error("3,tool,0,1,5," + std::string(100000, '7') + "x,0,0,1,0,0,0,0,0,0\n9,end,,,,,,,,,,,,,0\n");
  EXPECT_EQ(long_value.field(), "x");
  EXPECT_LT(std::string(long_value.what()).size(), 300u) << long_value.what();
  const InputError binary = log_error(std::string("3,tool,0,1,5,\x01\x02,0,0,1,0,0,0,0,0,0\n9,end,,,,,,,,,,,,,0\n"));
  EXPECT_NE(std::string(binary.what()).find("\\x01\\x02"), std::string::npos) << binary.what();
}

TEST(SessionLog, WindowsLineEndingsAreRead) {
  const std::string path =
      write_temp("stroma_session_crlf.log", "# stroma session log v2\r\n3,tool,0,1,5,0.1,0.2,0.3,1,0,0,0,0.5,0,0\r\n9,end,,,,,,,,,,,,,0\r\n");
  const auto ev = read_session_log(path, 1);
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_EQ(ev[0].input.pose.position[2], 0.3);
}

// A server killed outright (SIGKILL) leaves no 'end' line, and maybe half a line: the log replays
// to its last checkpoint (mark), events at or after it dropped; without a mark it is an error.
// A server that compiled with --converge says so in its log's comments, so a replay compiles
// the same way; the line counts only among the header comments.
TEST(SessionLog, ItSaysWhetherTheServerCompiledWithConverge) {
  SessionEvent end;
  end.kind = SessionEvent::End;
  end.tick = 3;
  const std::string plain = std::string(kSessionLogHeader) + "# scenario: s.yaml\n" + format_session_event(end);
  const std::string conv = std::string(kSessionLogHeader) + "# scenario: s.yaml\n" + kSessionLogConvergeLine +
                           "\n" + format_session_event(end);
  EXPECT_FALSE(session_log_converged(write_temp("stroma_session_plain.log", plain)));
  EXPECT_TRUE(session_log_converged(write_temp("stroma_session_conv.log", conv)));
  EXPECT_FALSE(session_log_converged(write_temp("stroma_session_late.log",
                                                plain + kSessionLogConvergeLine + "\n")));
  EXPECT_THROW(session_log_converged("/nonexistent/stroma.log"), InputError);
}

TEST(SessionLog, AKilledServersLogEndsAtItsLastCheckpoint) {
  const std::string body = std::string(kSessionLogHeader) +
                           "3,tool,0,1,5,0.1,0.2,0.3,1,0,0,0,0.5,0,0\n"
                           "10,mark,,,,,,,,,,,,,0\n"
                           "12,tool,0,2,6,0.1,0.2,0.4,1,0,0,0,0.5,0,0\n"
                           "20,tool,0,3,7,0.1,0.2,0.5,1,0,0,0,0.5,0,0\n"
                           "20,mark,,,,,,,,,,,,,0\n"
                           "20,tool,0,4,8,0.1,0.2,0.6,1,0,0,0,0.5,0,0\n"
                           "25,tool,0,5,9,0.1,0.2";  // the write the kill cut short
  bool interrupted = false;
  const auto ev = read_session_log(write_temp("stroma_killed.log", body), 1, &interrupted);
  EXPECT_TRUE(interrupted);
  ASSERT_EQ(ev.size(), 3u);  // tool@3, tool@12, end@20 (the tool events at tick 20 would act in tick 21)
  EXPECT_EQ(ev[1].input.seq, 2u);
  EXPECT_EQ(ev[2].kind, SessionEvent::End);
  EXPECT_EQ(ev[2].tick, 20);
  // A closed log is read whole, marks dropped, and not flagged.
  const auto closed = read_session_log(
      write_temp("stroma_closed.log", std::string(kSessionLogHeader) + "10,mark,,,,,,,,,,,,,0\n12,tool,0,2,6,0.1,0.2,0.4,1,0,0,0,0.5,0,0\n"
                                                                       "30,end,,,,,,,,,,,,,0\n"),
      1, &interrupted);
  EXPECT_FALSE(interrupted);
  ASSERT_EQ(closed.size(), 2u);
  EXPECT_EQ(closed[1].tick, 30);
  // Killed before its first checkpoint: nothing to replay, said so.
  try {
    read_session_log(write_temp("stroma_killed_early.log", std::string(kSessionLogHeader) + "3,tool,0,1,5,0.1,0.2,0.3,1,0,0,0,0.5,0,0\n"), 1);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no 'mark' checkpoint"), std::string::npos) << e.what();
  }
  // A malformed line with its newline is still an error, killed or not.
  EXPECT_THROW(read_session_log(write_temp("stroma_bad_mid.log", std::string(kSessionLogHeader) + "10,mark,,,,,,,,,,,,,0\n12,tool,0,2\n20,mark,,,,,,,,,,,,,0\n"), 1),
               InputError);
}
