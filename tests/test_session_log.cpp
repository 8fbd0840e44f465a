// engine/session_log: recorded server sessions round-trip exactly; interrupted logs are refused.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "engine/session_log.hpp"
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
  auto ev = read_session_log(path);
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
  EXPECT_THROW(read_session_log(cut), InputError);
}

