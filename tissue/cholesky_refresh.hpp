#pragma once
/// \file cholesky_refresh.hpp
/// Asynchronous preconditioning (Courtecuisse et al. 2010, SOFA's AsyncSparseLDLSolver): a
/// worker thread factors the system matrix of a recent step while the physics thread keeps
/// solving with the factor it has; the new factor is swapped in at a step boundary. The rest-pose
/// factor of the warped preconditioner degrades when the deformation itself (not only the
/// rotation) changes the tangent, and it never sees contact stiffness; a factor of a tangent a
/// few ticks old sees both.
///
/// The hand-off costs the physics thread no copy of the matrix and no wait: offer() swaps its
/// matrix buffer with the worker's input buffer (O(1)), take() swaps factor objects. Both are
/// refused (return false) while the worker is busy, so the caller keeps what it has.

#include <atomic>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

#include "tissue/bsr_matrix.hpp"
#include "tissue/cholmod_solver.hpp"

namespace stroma {

/// Invariants: exactly one thread owns each buffer at a time — the input buffers and the spare
/// factor belong to the worker from a successful offer() until the worker publishes its result,
/// and to the physics thread otherwise (the hand-over is the `state_` atomic, release/acquire).
/// The worker runs at a lower scheduling priority (nice +10) than the process's other threads.
class CholeskyRefresher {
 public:
  /// Runs the spare factor's symbolic analysis (allocates) and starts the worker thread.
  CholeskyRefresher(const BsrPattern& pattern, int32_t num_nodes);
  /// Stops the worker (an unfinished factorisation is completed first) and joins it.
  ~CholeskyRefresher();
  CholeskyRefresher(const CholeskyRefresher&) = delete;
  CholeskyRefresher& operator=(const CholeskyRefresher&) = delete;

  /// Physics thread. If the worker is idle: takes `vals` (a symmetric positive definite system
  /// in BSR values of `pattern`, 9·nnzb entries) by swapping it with the worker's input buffer
  /// (`vals` then holds stale values of the same size), copies `node_rot` (9 per node: the frame
  /// the matrix was assembled in), remembers `key`, and starts factoring. Returns false and
  /// changes nothing while the worker is busy or holds an untaken result.
  bool offer(std::vector<double>& vals, const double* node_rot, double key);
  /// Physics thread. If a factorisation has finished (or, with `wait`, once it finishes):
  /// swaps `factor` with the new factor and `node_rot` with its rotations, sets `key`, and
  /// returns true. A matrix CHOLMOD found not positive definite is dropped (failures()).
  /// Returns false when nothing new is ready; never blocks without `wait`. `factor` must hold a
  /// solver of the same pattern (it becomes the worker's next spare); with none, returns false.
  bool take(std::unique_ptr<CholmodSolver>& factor, std::vector<double>& node_rot, double& key, bool wait);
  /// True from a successful offer() until its result has been taken (or dropped).
  bool pending() const { return state_.load(std::memory_order_acquire) != kIdle; }
  /// Drops the job offered, waiting for its factorisation to end if it is under way (its
  /// result is not taken; the worker is idle again). For a history that no longer wants it
  /// (a restored state: WarpedPreconditioner::sync). Not for the real-time path.
  void discard();
  /// Physics thread, never blocks: drops a finished job's result (the worker is idle again) and
  /// returns true, or returns false while a factorisation is under way (call again later); true
  /// when nothing was pending. The real-time form of discard().
  bool drop_if_finished();

  int64_t refreshes() const { return refreshes_; }  ///< factors taken
  int64_t failures() const { return failures_; }     ///< matrices not positive definite
  /// The worker's time per factor taken (its factorisation and single-precision copy), summed
  /// and the longest (ns): what a refresh costs the second core.
  int64_t factor_ns_total() const { return factor_ns_total_; }
  int64_t factor_ns_max() const { return factor_ns_max_; }

 private:
  enum : int { kIdle = 0, kRequested = 1, kDone = 2, kFailed = 3, kStop = 4 };
  void run();
  std::unique_ptr<CholmodSolver> spare_;
  std::vector<double> vals_, rot_;
  double key_ = 0;
  std::atomic<int> state_{kIdle};
  int64_t refreshes_ = 0, failures_ = 0;
  int64_t worker_ns_ = 0;  ///< the last factorisation's time (written by the worker before its state)
  int64_t factor_ns_total_ = 0, factor_ns_max_ = 0;
  std::thread worker_;
};

}  // namespace stroma
