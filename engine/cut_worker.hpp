#pragma once
/// \file cut_worker.hpp
/// Cut models for a real-time loop: built on a worker thread, swapped in by the physics thread
/// at a tick boundary, the old model released on the worker — the physics thread never waits,
/// locks or allocates for a cut (docs/ARCHITECTURE.md, "Cutting").
///
/// Hand-over through one atomic phase: Idle → (physics) Posted → (worker) Done → (physics)
/// Release → (worker) Idle. The physics thread owns the snapshot while Idle and the build while
/// Done; the worker owns both otherwise. Wake-ups are std::atomic::notify_one (a futex wake: no
/// lock on the physics thread).

#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

#include "engine/cut_swap.hpp"

namespace stroma {

class CutWorker {
 public:
  /// Statistics (physics thread's view; read after the loop or from the physics thread).
  struct Stats {
    uint64_t posted = 0;    ///< snapshots handed to the worker
    uint64_t swapped = 0;   ///< cut models swapped in
    uint64_t unchanged = 0; ///< builds whose cuts separated nothing new (nothing to swap)
    uint64_t failed = 0;    ///< builds that threw (counted; the current model stays)
    double build_ms_last = 0, build_ms_max = 0;
    int64_t swap_ns_last = 0, swap_ns_max = 0;
    int64_t lag_ticks_max = 0;  ///< ticks from a post to its swap
  };

  /// `edges`: the uncut mesh's edge count (the snapshot is sized once).
  explicit CutWorker(size_t edges);
  ~CutWorker();
  CutWorker(const CutWorker&) = delete;
  CutWorker& operator=(const CutWorker&) = delete;

  /// Physics thread, at a tick boundary (after tick `tick`, whose report cut `cut_edges`):
  /// swaps in a finished build (apply_cut), then, if the state holds cuts the model was not
  /// built from and the worker is idle, posts a snapshot of s.edge_cut. Returns true when a new
  /// model was swapped in (m, w and s then are the cut model's). Never waits, locks or
  /// allocates.
  bool service(std::shared_ptr<const Model>& m, std::unique_ptr<TickWorkspace>& w, State& s, int cut_edges,
               int64_t tick);

  /// Physics thread, after a reset to the uncut model: forgets the pending cuts (a build in
  /// flight is then stale: it refines a model no longer current, and is released unused).
  void reset() { pending_ = 0; }

  /// True when nothing is pending: no cuts since the last post and the worker idle (tests and
  /// benchmarks wait for the topology to settle with this).
  bool settled() const { return pending_ == 0 && phase_.load(std::memory_order_acquire) == kIdle; }
  const Stats& stats() const { return stats_; }

 private:
  enum Phase : int { kIdle, kPosted, kDone, kRelease, kStop };
  void loop();
  std::atomic<int> phase_{kIdle};
  std::vector<double> snapshot_;
  std::shared_ptr<const Model> base_;  ///< the model the posted snapshot refines
  CutBuild build_;
  bool build_failed_ = false;
  int64_t pending_ = 0;      ///< edges cut since the last post (physics thread)
  int64_t posted_tick_ = 0;  ///< physics thread
  Stats stats_;
  std::thread thread_;
};

}  // namespace stroma
