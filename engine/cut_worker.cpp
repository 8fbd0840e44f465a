#include "engine/cut_worker.hpp"

#include <algorithm>
#include <exception>

#include "tissue/clock.hpp"

namespace stroma {

CutWorker::CutWorker(size_t edges) : snapshot_(edges, kEdgeUncut) { thread_ = std::thread([this] { loop(); }); }

CutWorker::~CutWorker() {
  // Wait for a build in progress to finish, then stop (the destructor is not on the tick path).
  for (;;) {
    int p = phase_.load(std::memory_order_acquire);
    if (p == kPosted || p == kRelease) {
      phase_.wait(p, std::memory_order_acquire);
      continue;
    }
    if (phase_.compare_exchange_strong(p, kStop, std::memory_order_acq_rel)) break;
  }
  phase_.notify_one();
  thread_.join();
}

void CutWorker::loop() {
  for (;;) {
    int p = phase_.load(std::memory_order_acquire);
    while (p == kIdle || p == kDone) {
      phase_.wait(p, std::memory_order_acquire);
      p = phase_.load(std::memory_order_acquire);
    }
    if (p == kStop) return;
    if (p == kPosted) {
      build_failed_ = false;
      try {
        build_ = build_cut(*base_, snapshot_);
      } catch (const std::exception&) {
        build_ = CutBuild{};
        build_failed_ = true;
      }
      phase_.store(kDone, std::memory_order_release);
      phase_.notify_one();
    } else if (p == kRelease) {  // the physics thread is done with the build: free it here
      build_ = CutBuild{};
      base_.reset();
      phase_.store(kIdle, std::memory_order_release);
      phase_.notify_one();
    }
  }
}

bool CutWorker::service(std::shared_ptr<const Model>& m, std::unique_ptr<TickWorkspace>& w, State& s, int cut_edges,
                        int64_t tick) {
  pending_ += cut_edges;
  bool swapped = false;
  if (phase_.load(std::memory_order_acquire) == kDone) {
    if (build_failed_) {
      ++stats_.failed;
    } else if (!build_.changed) {
      ++stats_.unchanged;
    } else if (base_.get() == m.get()) {  // not stale (a reset may have replaced the model)
      const int64_t t0 = steady_now_ns();
      swapped = apply_cut(build_, m, w, s);  // the old model, workspace and state go into build_
      const int64_t dt = steady_now_ns() - t0;
      if (swapped) {
        ++stats_.swapped;
        stats_.swap_ns_last = dt;
        stats_.swap_ns_max = std::max(stats_.swap_ns_max, dt);
        stats_.lag_ticks_max = std::max(stats_.lag_ticks_max, tick - posted_tick_);
      }
    }
    stats_.build_ms_last = build_.build_ms;
    stats_.build_ms_max = std::max(stats_.build_ms_max, build_.build_ms);
    phase_.store(kRelease, std::memory_order_release);  // the worker frees what is left
    phase_.notify_one();
  }
  if (pending_ > 0 && phase_.load(std::memory_order_acquire) == kIdle) {
    std::copy(s.edge_cut.begin(), s.edge_cut.end(), snapshot_.begin());
    base_ = m;  // a reference count, no allocation
    posted_tick_ = tick;
    pending_ = 0;
    ++stats_.posted;
    phase_.store(kPosted, std::memory_order_release);
    phase_.notify_one();
  }
  return swapped;
}

}  // namespace stroma
