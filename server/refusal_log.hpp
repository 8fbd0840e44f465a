#pragma once
/// \file refusal_log.hpp
/// Refused inputs in the log without flooding it: a client that sends 1,000 bad poses a second
/// gets one line a second, each saying how many were refused since the last (the exact counts
/// are in `serve --stats` and SimStatus). Refusals that change a state (a CRTK FAULT) are logged
/// by their owner, always.
///
/// Not thread-safe: one instance per input thread (the server's input thread owns them).

#include <cstdint>
#include <string>
#include <utility>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "tissue/clock.hpp"

namespace stroma {

class RefusalLog {
 public:
  /// `interval_ns`: at most one line per interval (the first refusal is logged at once).
  explicit RefusalLog(int64_t interval_ns = 1000000000) : interval_ns_(interval_ns) {}
  ~RefusalLog() {
    if (pending_ > 0) spdlog::warn("{} more input(s) refused since the last message (counts: serve --stats)", pending_);
  }
  RefusalLog(const RefusalLog&) = delete;
  RefusalLog& operator=(const RefusalLog&) = delete;

  /// One refusal; logs `fmt` (with the number held back since the last line) when the interval
  /// has passed.
  template <typename... Args>
  void refused(fmt::format_string<Args...> fmt, Args&&... args) {
    const int64_t now = steady_now_ns();
    if (logged_ > 0 && now - last_ns_ < interval_ns_) {
      ++pending_;
      return;
    }
    const std::string what = fmt::format(fmt, std::forward<Args>(args)...);
    if (pending_ > 0)
      spdlog::warn("{} ({} more refused since the last message; counts: serve --stats)", what, pending_);
    else
      spdlog::warn("{}", what);
    last_ns_ = now;
    pending_ = 0;
    ++logged_;
  }

  uint64_t logged() const { return logged_; }

 private:
  int64_t interval_ns_;
  int64_t last_ns_ = 0;
  uint64_t pending_ = 0, logged_ = 0;
};

}  // namespace stroma
