#pragma once
/// \file stage_timer.hpp
/// Times a block of the tick into a stage of its report (RAII). Adds, so a stage run several
/// times in one tick (a retried step) reports its total.

#include <cstdint>

#include "engine/tick_types.hpp"
#include "tissue/clock.hpp"

namespace stroma {

/// Adds the wall time of its lifetime to stage `s` of report `r` and marks the stage as run.
class StageTimer {
 public:
  StageTimer(TickReport& r, Stage s) : r_(r), s_(static_cast<int>(s)), t0_(steady_now_ns()) {}
  ~StageTimer() {
    r_.stage_ns[s_] += steady_now_ns() - t0_;
    r_.stage_ran[s_] = true;
  }
  StageTimer(const StageTimer&) = delete;
  StageTimer& operator=(const StageTimer&) = delete;

 private:
  TickReport& r_;
  int s_;
  int64_t t0_;
};

}  // namespace stroma
