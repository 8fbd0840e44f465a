#include "tissue/cholesky_refresh.hpp"

#include <pthread.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>

#include "tissue/clock.hpp"

namespace stroma {

CholeskyRefresher::CholeskyRefresher(const BsrPattern& pattern, int32_t num_nodes)
    : spare_(std::make_unique<CholmodSolver>(pattern)),
      vals_(9 * static_cast<size_t>(pattern.nnzb()), 0.0),
      rot_(9 * static_cast<size_t>(num_nodes), 0.0) {
  spare_->use_float_solves();  // its factors precondition (tissue/warped_preconditioner.hpp)
  worker_ = std::thread([this] { run(); });
}

CholeskyRefresher::~CholeskyRefresher() {
  // A factorisation under way is let finish; then the worker is told to stop, whatever else
  // it was waiting for.
  int s = state_.load(std::memory_order_acquire);
  for (;;) {
    if (s == kRequested) {
      state_.wait(kRequested, std::memory_order_acquire);
      s = state_.load(std::memory_order_acquire);
    } else if (state_.compare_exchange_weak(s, kStop, std::memory_order_acq_rel)) {
      break;
    }
  }
  state_.notify_all();
  worker_.join();
}

bool CholeskyRefresher::offer(std::vector<double>& vals, const double* node_rot, double key) {
  if (state_.load(std::memory_order_acquire) != kIdle || vals.size() != vals_.size()) return false;
  vals.swap(vals_);
  std::copy(node_rot, node_rot + rot_.size(), rot_.begin());
  key_ = key;
  state_.store(kRequested, std::memory_order_release);
  state_.notify_one();
  return true;
}

bool CholeskyRefresher::take(std::unique_ptr<CholmodSolver>& factor, std::vector<double>& node_rot, double& key,
                             bool wait) {
  if (!factor || node_rot.size() != rot_.size()) return false;
  int s = state_.load(std::memory_order_acquire);
  if (wait)
    while (s == kRequested) {
      state_.wait(kRequested, std::memory_order_acquire);
      s = state_.load(std::memory_order_acquire);
    }
  if (s == kDone) {
    factor.swap(spare_);
    node_rot.swap(rot_);
    key = key_;
    ++refreshes_;
    factor_ns_total_ += worker_ns_;
    factor_ns_max_ = std::max(factor_ns_max_, worker_ns_);
  } else if (s == kFailed) {
    ++failures_;
  } else {
    return false;
  }
  state_.store(kIdle, std::memory_order_release);
  return s == kDone;
}

void CholeskyRefresher::discard() {
  int s = state_.load(std::memory_order_acquire);
  while (s == kRequested) {
    state_.wait(kRequested, std::memory_order_acquire);
    s = state_.load(std::memory_order_acquire);
  }
  if (s == kDone || s == kFailed) state_.store(kIdle, std::memory_order_release);
}

bool CholeskyRefresher::drop_if_finished() {
  const int s = state_.load(std::memory_order_acquire);
  if (s == kRequested) return false;
  if (s == kDone || s == kFailed) state_.store(kIdle, std::memory_order_release);
  return true;
}

void CholeskyRefresher::run() {
  pthread_setname_np(pthread_self(), "chol-refresh");
  // Below the renderer and the tool client in the demo: a late factor costs CG iterations, a
  // starved renderer costs frames.
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 10);
  for (;;) {
    state_.wait(kIdle, std::memory_order_acquire);  // until a request (or stop)
    const int s = state_.load(std::memory_order_acquire);
    if (s == kStop) return;
    if (s == kRequested) {
      const int64_t t0 = steady_now_ns();
      const bool ok = spare_->factor(vals_.data());
      worker_ns_ = steady_now_ns() - t0;  // published with the state below
      state_.store(ok ? kDone : kFailed, std::memory_order_release);
      state_.notify_all();
    } else {
      state_.wait(s, std::memory_order_acquire);  // a result not yet taken
    }
  }
}

}  // namespace stroma
