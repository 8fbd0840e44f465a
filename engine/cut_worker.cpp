#include "engine/cut_worker.hpp"

#include <algorithm>
#include <exception>

#include "tissue/clock.hpp"

namespace stroma {

CutWorker::CutWorker(std::shared_ptr<const Model> original, size_t edges, CutModelRegistry* registry)
    : original_(std::move(original)), registry_(registry), snapshot_(edges, kEdgeUncut) {
  thread_ = std::thread([this] { loop(); });
}

CutWorker::~CutWorker() {
  // Wait for a build in progress to finish, then stop (the destructor is not on the tick path).
  for (;;) {
    int p = phase_.load(std::memory_order_acquire);
    if (p == kPosted || p == kRelease) {
      std::this_thread::yield();
      continue;
    }
    if (phase_.compare_exchange_strong(p, kStop, std::memory_order_acq_rel)) break;
  }
  ring();
  thread_.join();
}

void CutWorker::loop() {
  uint32_t seen = 0;
  for (;;) {
    // One wait for every kind of request: the doorbell rings after each.
    if (spare_state_.load(std::memory_order_acquire) == kSpareMaking) {
      spare_ = std::make_unique<TickWorkspace>(*original_);
      spare_->stepper().set_realtime(true);
      spare_state_.store(kSpareReady, std::memory_order_release);
    }
    if (spare_state_.load(std::memory_order_acquire) == kRetired) {
      retired_work_.reset();  // the cut model's workspace and model, freed here
      retired_model_.reset();
      spare_state_.store(kSpareMaking, std::memory_order_release);
      continue;  // make the next spare
    }
    const int p = phase_.load(std::memory_order_acquire);
    if (p == kStop) return;
    if (p == kPosted) {
      build_failed_ = false;
      try {
        build_ = build_cut(*base_, snapshot_);
        if (build_.workspace) build_.workspace->stepper().set_realtime(true);
        if (registry_ && build_.changed && build_.model) registry_->add(build_.model);
      } catch (const std::exception&) {
        build_ = CutBuild{};
        build_failed_ = true;
      }
      phase_.store(kDone, std::memory_order_release);
      continue;
    }
    if (p == kRelease) {  // the physics thread is done with the build: free it here
      build_ = CutBuild{};
      base_.reset();
      phase_.store(kIdle, std::memory_order_release);
      continue;
    }
    doorbell_.wait(seen, std::memory_order_acquire);
    seen = doorbell_.load(std::memory_order_acquire);
  }
}

bool CutWorker::reset(const std::shared_ptr<const Model>& original, std::shared_ptr<const Model>& m,
                      std::unique_ptr<TickWorkspace>& w) {
  pending_ = 0;
  ++generation_;  // a build in flight is stale now, whatever model it refines
  if (m.get() == original.get()) return true;  // nothing cut: the state's reset is the whole reset
  if (spare_state_.load(std::memory_order_acquire) != kSpareReady) return false;
  std::swap(w, spare_);        // the spare becomes the workspace, the cut one goes to be freed
  retired_work_ = std::move(spare_);
  retired_model_ = std::move(m);
  m = original;                // a reference count, no allocation
  spare_state_.store(kRetired, std::memory_order_release);
  ring();
  return true;
}

bool CutWorker::service(std::shared_ptr<const Model>& m, std::unique_ptr<TickWorkspace>& w, State& s, int cut_edges,
                        int64_t tick) {
  pending_ += cut_edges;
  bool swapped = false;
  if (phase_.load(std::memory_order_acquire) == kDone) {
    const bool stale = posted_generation_ != generation_ || base_.get() != m.get();
    if (stale) {
      // refines a model no longer current (a Reset since): released unused
    } else if (build_failed_) {
      ++stats_.failed;
      pending_ += 1;  // try again at the next tick (the cuts are still in the state)
    } else if (!build_.changed) {
      ++stats_.unchanged;
    } else {
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
    ring();
  }
  if (pending_ > 0 && phase_.load(std::memory_order_acquire) == kIdle) {
    std::copy(s.edge_cut.begin(), s.edge_cut.end(), snapshot_.begin());
    base_ = m;  // a reference count, no allocation
    posted_tick_ = tick;
    posted_generation_ = generation_;
    pending_ = 0;
    ++stats_.posted;
    phase_.store(kPosted, std::memory_order_release);
    ring();
  }
  return swapped;
}

}  // namespace stroma
