#include "server/serve_record.hpp"

#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "runtime/session_log.hpp"

namespace stroma {

namespace {

/// Recorder thread: drains the physics loop's session events into the log file, and flushes it
/// to the kernel after every drain (every 10 ms): a server killed outright (SIGKILL, a crash)
/// leaves a log that replays to its last checkpoint, at most ~20 ms before the kill. Of the
/// checkpoints (a Mark every kRecordMarkTicks) only those followed by an event, and the last of a
/// drain, are written: the log grows with the session's events, not with its ticks.
/// A write that fails (a full disk, an I/O error) stops the recording there — said at once, with
/// the system's reason — while the server goes on; the queue is still drained, so physics never
/// notices.
void recorder_thread(PhysicsLoop& loop, std::FILE* f, RecordStatus& rs, const std::string& path) {
  SessionEvent e;
  SessionEvent mark;
  bool mark_pending = false;
  int64_t last_tick = 0;
  auto fail = [&] {
    if (rs.failed) return;
    rs.failed = true;
    rs.error = std::strerror(errno ? errno : EIO);
    rs.stopped_at_tick = last_tick;
    spdlog::error("--record: writing '{}' failed ({}): recording stopped at tick {}; the server goes on", path,
                  rs.error, last_tick);
  };
  auto write = [&](const SessionEvent& ev) {
    if (rs.failed) return;
    const std::string line = format_session_event(ev);
    errno = 0;
    if (std::fwrite(line.data(), 1, line.size(), f) != line.size()) return fail();
    ++rs.lines_written;
    last_tick = ev.tick;
  };
  auto drain = [&] {
    while (loop.record.pop(e)) {
      if (e.kind == SessionEvent::Mark) {
        mark = e;
        mark_pending = true;
        continue;
      }
      if (e.kind == SessionEvent::End && loop.stats().record_dropped > 0) continue;  // unreplayable
      if (mark_pending) write(mark);
      mark_pending = false;
      write(e);
    }
    if (mark_pending) write(mark);
    mark_pending = false;
    errno = 0;
    if (!rs.failed && std::fflush(f) != 0) fail();
  };
  while (!loop.finished.load()) {
    drain();
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  drain();
}

}  // namespace

SessionRecorder::SessionRecorder(const ServeOutputOptions& o, const std::string& scenario, bool converge)
    : path_(o.record_file), scenario_(scenario) {
  if (path_.empty()) return;
  f_ = std::fopen(path_.c_str(), "w");
  if (!f_) throw std::runtime_error(fmt::format("--record: cannot write '{}'", path_));
  std::fputs(kSessionLogHeader, f_);
  std::fprintf(f_, "# scenario: %s\n", scenario.c_str());
  if (converge) std::fprintf(f_, "%s\n", kSessionLogConvergeLine);
}

SessionRecorder::~SessionRecorder() {
  if (thread_.joinable()) thread_.join();
  if (f_) std::fclose(f_);
}

void SessionRecorder::start(PhysicsLoop& loop) {
  if (f_) thread_ = std::thread([this, &loop] { recorder_thread(loop, f_, rs_, path_); });
}

bool SessionRecorder::finish(const PhysicsLoop& loop) {
  if (thread_.joinable()) thread_.join();
  if (!f_) return true;
  errno = 0;
  const int closed = std::fclose(f_);
  f_ = nullptr;
  if (closed != 0 && !rs_.failed) {
    rs_.failed = true;
    rs_.error = std::strerror(errno ? errno : EIO);
    spdlog::error("--record: closing '{}' failed ({})", path_, rs_.error);
  }
  if (rs_.failed) {
    spdlog::error("--record: '{}' holds the session up to tick {} only ({})", path_, rs_.stopped_at_tick, rs_.error);
    return false;
  }
  if (loop.stats().record_dropped) {
    spdlog::error("--record: {} events lost (recorder fell behind); '{}' is incomplete and will not replay",
                  loop.stats().record_dropped, path_);
    return false;
  }
  spdlog::info("session recorded in {} (replay: stroma run {} --replay {})", path_, scenario_, path_);
  return true;
}

}  // namespace stroma
