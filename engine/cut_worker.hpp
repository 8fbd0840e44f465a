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

#include "engine/cut_registry.hpp"
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
  /// `original`: the scenario's (uncut) model — the worker makes a spare workspace for it at
  /// once, for the first Reset. `edges`: the uncut mesh's edge count (the snapshot is sized once).
  /// `registry` (optional): every model built is registered there, on the worker thread, for
  /// the threads that read state frames of it.
  CutWorker(std::shared_ptr<const Model> original, size_t edges, CutModelRegistry* registry = nullptr);
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

  /// Physics thread, at a Reset: when `m` is a cut model, swaps the scenario's model (`original`)
  /// back in with the spare workspace made for it, and hands the cut model and its workspace to
  /// the worker to free (it then makes the next spare). Returns false, changing nothing, while
  /// the spare is not ready (a second Reset within a few ms of the first: the caller retries at
  /// the next tick). Forgets the pending cuts (a build in flight is then stale: it refines a
  /// model no longer current, and is released unused). Never waits, locks or allocates.
  bool reset(const std::shared_ptr<const Model>& original, std::shared_ptr<const Model>& m,
             std::unique_ptr<TickWorkspace>& w);

  /// True when nothing is pending: no cuts since the last post and the worker idle (tests and
  /// benchmarks wait for the topology to settle with this).
  bool settled() const { return pending_ == 0 && phase_.load(std::memory_order_acquire) == kIdle; }
  const Stats& stats() const { return stats_; }

 private:
  enum Phase : int { kIdle, kPosted, kDone, kRelease, kStop };
  /// The spare's hand-over: kSpareReady (the physics thread may take it) → kRetired (the
  /// physics thread left a cut model and workspace to free; the worker frees them and makes
  /// the next spare) → kSpareReady.
  enum Spare : int { kSpareMaking, kSpareReady, kRetired };
  void loop();
  std::atomic<int> phase_{kIdle};
  std::atomic<int> spare_state_{kSpareMaking};
  std::atomic<uint32_t> doorbell_{0};  ///< bumped on every request to the worker (its one wait)
  void ring() {
    doorbell_.fetch_add(1, std::memory_order_release);
    doorbell_.notify_one();
  }
  std::shared_ptr<const Model> original_;
  CutModelRegistry* registry_ = nullptr;
  std::unique_ptr<TickWorkspace> spare_;       ///< a workspace for original_ (kSpareReady)
  std::shared_ptr<const Model> retired_model_; ///< to free (kRetired)
  std::unique_ptr<TickWorkspace> retired_work_;
  std::vector<double> snapshot_;
  std::shared_ptr<const Model> base_;  ///< the model the posted snapshot refines
  CutBuild build_;
  bool build_failed_ = false;
  int64_t pending_ = 0;      ///< edges cut since the last post (physics thread)
  /// Bumped by every Reset; a build posted in an earlier generation is stale even if it refines
  /// the current model (the scenario's model is current again after a Reset).
  uint64_t generation_ = 0, posted_generation_ = 0;  ///< physics thread
  int64_t posted_tick_ = 0;  ///< physics thread
  Stats stats_;
  std::thread thread_;
};

}  // namespace stroma
