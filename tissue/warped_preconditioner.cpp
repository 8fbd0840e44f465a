#include "tissue/warped_preconditioner.hpp"

#include <algorithm>
#include <atomic>

#include "tissue/clock.hpp"
#include "tissue/constraints.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/mat3.hpp"

namespace stroma {

namespace {
void set_identities(std::vector<double>& r) {
  std::fill(r.begin(), r.end(), 0.0);
  for (size_t i = 0; i + 8 < r.size(); i += 9) r[i] = r[i + 4] = r[i + 8] = 1.0;
}

}  // namespace

uint64_t new_refresh_id() {
  static std::atomic<uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}

WarpedPreconditioner::WarpedPreconditioner(const FemModel& model) : m_(model) {
  const size_t n3 = 3 * static_cast<size_t>(m_.num_nodes);
  for (auto* r : {&node_abs_, &factor_rot_, &node_rot_}) {
    r->assign(3 * n3, 0.0);
    set_identities(*r);
  }
  a_.assign(n3, 0.0);
  b_.assign(n3, 0.0);
  op_.apply = &WarpedPreconditioner::apply;
  op_.context = this;
}

void WarpedPreconditioner::factor(double h_mass, double k_beta, double k_const) {
  if (rest_ && key_[0] == h_mass && key_[1] == k_beta && key_[2] == k_const) return;
  std::vector<double> A0(9 * static_cast<size_t>(m_.pattern.nnzb()), 0.0);
  ElasticPass p;
  p.x = m_.rest.data();
  p.kvals = A0.data();
  p.k_beta = k_beta;
  p.k_const = k_const;
  // Matrix-free locking-free bodies: the factor is of the plain elements with the full material
  // (a one-ring SPD matrix near the smoothed one; the pattern has no room for the node domains).
  p.unsmoothed = m_.smoothing.matrix_free;
  elastic_pass(m_, p);
  if (h_mass >= 0) add_mass_diagonal(m_, A0.data(), h_mass, m_.mass.data());
  project_constraints(m_, A0.data(), 1.0, false);
  if (!rest_) {
    rest_ = std::make_unique<CholmodSolver>(m_.pattern);
    rest_->use_float_solves();  // a preconditioner: half the memory traffic per application
  }
  rest_->factor(A0.data());
  ++rest_factorizations_;
  key_[0] = h_mass;
  key_[1] = k_beta;
  key_[2] = k_const;
  active_ = rest_.get();
  refreshed_id_ = 0;
  set_identities(factor_rot_);  // assembled at rest
}

void WarpedPreconditioner::update_rotations(const double* rot) {
  for (int32_t i = 0; i < m_.num_nodes; ++i) {
    double* R = node_abs_.data() + 9 * i;
    const bool has_element = m_.node_element_ptr[i + 1] > m_.node_element_ptr[i];
    if (!has_element || m_.constrained[i] == 7) {
      std::fill(R, R + 9, 0.0);
      R[0] = R[4] = R[8] = 1.0;
    } else {
      const int32_t e = m_.node_element[m_.node_element_ptr[i]];
      std::copy(rot + 9 * e, rot + 9 * e + 9, R);
    }
    m3::mul_nt(R, factor_rot_.data() + 9 * i, node_rot_.data() + 9 * i);
  }
}

void WarpedPreconditioner::enable_refresh(bool deterministic) {
  deterministic_ = deterministic;
  if (!refresh_) {
    refresh_ = std::make_unique<CholeskyRefresher>(m_.pattern, m_.num_nodes);
    refreshed_ = std::make_unique<CholmodSolver>(m_.pattern);  // the slot refreshes swap into
    refreshed_->use_float_solves();
    offer_.assign(9 * static_cast<size_t>(m_.pattern.nnzb()), 0.0);
  }
}

bool WarpedPreconditioner::hand_over(std::vector<double>& system, const double* node_rot, double key, uint64_t id,
                                     bool copy) {
  if (copy) {
    std::copy(system.begin(), system.end(), offer_.begin());
    if (!refresh_->offer(offer_, node_rot, key)) return false;
  } else if (!refresh_->offer(system, node_rot, key)) {
    return false;
  }
  job_id_ = id;
  return true;
}

void WarpedPreconditioner::adopt(SolverHistory& h, bool wait) {
  double key = 0;
  const bool ok = refresh_->take(refreshed_, factor_rot_, key, wait);
  if (!ok && refresh_->pending()) return;  // not finished yet (real time)
  job_id_ = 0;
  if (!ok) {  // not positive definite: dropped, the factor in use stays
    h.pending_id = 0;
    return;
  }
  active_ = refreshed_.get();
  refreshed_id_ = h.pending_id;
  h.factor_id = h.pending_id;
  h.factor_key = key;
  h.factor_matrix.swap(h.pending_matrix);  // (empty in real time: nothing to keep)
  h.factor_rot.swap(h.pending_rot);
  h.pending_id = 0;
  ++refreshes_;
}

void WarpedPreconditioner::sync(SolverHistory& h, std::vector<double>& carrier) {
  // The factor in use. factor_rot_ holds the rotations of the factor in use, so refreshed_id_
  // names refreshed_ only while it is in use with its own rotations: going back to the rest
  // factor forgets it (a state naming it again remakes it).
  if (h.factor_id == 0) {
    if (active_ != rest_.get()) {
      active_ = rest_.get();
      refreshed_id_ = 0;
      set_identities(factor_rot_);
    }
  } else if (h.factor_id != refreshed_id_) {
    // Real time keeps no systems in the state (a copied history has nothing to remake from) and
    // never waits for the worker: the rest factor until the next refresh.
    if (!deterministic_ || h.factor_matrix.size() != offer_.size() || !refreshed_) {
      h.factor_id = 0;
      active_ = rest_.get();
      refreshed_id_ = 0;
      set_identities(factor_rot_);
    } else {
      // A restored history: remake its factor from the system it keeps (the same arithmetic
      // as the worker's, so the same factor bit for bit).
      if (refresh_->pending()) {  // (its result belongs to another history)
        refresh_->discard();
        job_id_ = 0;
      }
      refreshed_id_ = 0;  // refreshed_ is overwritten: it names no refresh unless this succeeds
      if (refreshed_->factor(h.factor_matrix.data())) {
        refreshed_id_ = h.factor_id;
        active_ = refreshed_.get();
        std::copy(h.factor_rot.begin(), h.factor_rot.end(), factor_rot_.begin());
        ++remade_;
      } else {
        h.factor_id = 0;
        active_ = rest_.get();
        set_identities(factor_rot_);
      }
    }
  } else {
    active_ = refreshed_.get();
  }
  // The refresh being made.
  if (orphan_job_ && refresh_->drop_if_finished()) orphan_job_ = false;
  if (h.pending_id != job_id_) {
    if (!deterministic_) {
      // Real time (a reset, a restored state): the worker's job belongs to no history now. It
      // is dropped when it finishes; the physics thread never waits for it.
      if ((job_id_ != 0 || refresh_->pending()) && !refresh_->drop_if_finished()) orphan_job_ = true;
      job_id_ = 0;
      h.pending_id = 0;  // (a real-time history keeps no system to hand over again)
      return;
    }
    if (job_id_ != 0 || refresh_->pending()) refresh_->discard();
    orphan_job_ = false;
    job_id_ = 0;
    if (h.pending_id != 0) {
      if (h.pending_matrix.size() != carrier.size() || !deterministic_) {
        h.pending_id = 0;  // nothing to hand over again
      } else {
        std::copy(h.pending_matrix.begin(), h.pending_matrix.end(), carrier.begin());
        if (!hand_over(carrier, h.pending_rot.data(), h.pending_key, h.pending_id, false)) h.pending_id = 0;
      }
    }
  }
}

void WarpedPreconditioner::begin_step(std::vector<double>& last_system, double h_last, double h_now, SolverHistory& h) {
  last_wait_ns_ = 0;
  if (!refresh_) return;
  sync(h, last_system);
  // The schedule counts full steps (a sub-step's h differs), from the state alone: a stepper
  // that has not stepped yet (a fresh one given a restored state) counts as the original did.
  if (h_now != key_[0]) return;
  ++h.steps_since_offer;
  if (deterministic_) {
    // The factor handed over `lag` steps ago is swapped in now, whatever the worker's speed.
    if (h.pending_id != 0 && h.steps_since_offer >= h.lag) {
      const int64_t t0 = steady_now_ns();
      adopt(h, true);
      last_wait_ns_ = steady_now_ns() - t0;
    }
    return;  // this step's own system is handed over at end_assembly()
  }
  if (h.pending_id != 0) adopt(h, false);  // real time: as soon as it is ready
  if (h_last != key_[0]) return;  // no step yet, or a sub-step's system: nothing to hand over
  // Due every period, or now when the factor was found not to fit (a demand) and the worker is
  // free. A demand made while a refresh is under way is met by that refresh.
  if (h.pending_id != 0) {
    h.demand = false;
    return;
  }
  if (h.steps_since_offer < h.period && !h.demand) return;
  const uint64_t id = new_refresh_id();
  if (hand_over(last_system, node_abs_.data(), h_last, id, false)) {
    h.pending_id = id;
    h.pending_key = h_last;
    h.steps_since_offer = 0;
    h.demand = false;
  }
}

void WarpedPreconditioner::end_assembly(const std::vector<double>& system, double h_step, SolverHistory& h) {
  if (!refresh_ || !deterministic_ || h_step != key_[0]) return;
  if (h.pending_id != 0) {
    h.demand = false;  // met by the refresh under way
    return;
  }
  if (h.steps_since_offer < h.period && !h.demand) return;
  if (h.pending_matrix.size() != system.size() || h.pending_rot.size() != node_abs_.size()) return;  // not sized
  const uint64_t id = new_refresh_id();
  std::copy(system.begin(), system.end(), h.pending_matrix.begin());  // the state keeps it
  std::copy(node_abs_.begin(), node_abs_.end(), h.pending_rot.begin());
  std::vector<double>& copy = h.pending_matrix;  // (hand_over copies it into offer_)
  if (hand_over(copy, node_abs_.data(), h_step, id, true)) {
    h.pending_id = id;
    h.pending_key = h_step;
    // Swapped in at the start of the step a period from now, when the next one goes over: a
    // refresh every `period` steps, each factor `period` steps old when it comes in.
    h.lag = h.period;
    h.steps_since_offer = 0;
    h.demand = false;
  }
}

void WarpedPreconditioner::apply(void* self, const double* r, double* z) {
  auto* w = static_cast<WarpedPreconditioner*>(self);
  const int32_t n = w->m_.num_nodes;
  const double* R = w->node_rot_.data();
  for (int32_t i = 0; i < n; ++i) m3::mulv_t(R + 9 * i, r + 3 * i, w->a_.data() + 3 * i);
  const_cast<CholmodSolver*>(w->active_)->solve(w->a_.data(), w->b_.data());
  for (int32_t i = 0; i < n; ++i) m3::mulv(R + 9 * i, w->b_.data() + 3 * i, z + 3 * i);
}

}  // namespace stroma
