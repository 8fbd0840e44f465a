#include "tissue/warped_preconditioner.hpp"

#include <algorithm>

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
  if (factor_ && key_[0] == h_mass && key_[1] == k_beta && key_[2] == k_const) return;
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
  if (!factor_) {
    factor_ = std::make_unique<CholmodSolver>(m_.pattern);
    factor_->use_float_solves();  // a preconditioner: half the memory traffic per application
  }
  factor_->factor(A0.data());
  ++rest_factorizations_;
  key_[0] = h_mass;
  key_[1] = k_beta;
  key_[2] = k_const;
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

void WarpedPreconditioner::enable_refresh(int period, bool deterministic) {
  period_ = std::max(1, period);
  lag_ = period_;
  deterministic_ = deterministic;
  if (!refresh_) refresh_ = std::make_unique<CholeskyRefresher>(m_.pattern, m_.num_nodes);
}

void WarpedPreconditioner::adopt(bool wait) {
  double key = 0;
  if (!refresh_->take(factor_, factor_rot_, key, wait)) return;
  key_[0] = key_[1] = key;
  key_[2] = key * key;
  ++refreshes_;
}

void WarpedPreconditioner::begin_step(std::vector<double>& last_system, double h_last) {
  last_wait_ns_ = 0;
  if (!refresh_ || h_last <= 0 || h_last != key_[0]) return;
  ++steps_since_offer_;
  // Deterministic: the factor handed over `lag` steps ago is swapped in now, whatever the
  // worker's speed. Real time: poll() swapped it in as soon as it was ready.
  if (deterministic_ && refresh_->pending() && steps_since_offer_ >= lag_) {
    const int64_t t0 = steady_now_ns();
    adopt(true);
    last_wait_ns_ = steady_now_ns() - t0;
  }
  // Due every period, or now when the factor was found not to fit (request_refresh()) and the
  // worker is free. A demand made while a refresh is under way is met by that refresh.
  if (refresh_->pending()) {
    demand_ = false;
    return;
  }
  if (steps_since_offer_ < period_ && !demand_) return;
  if (refresh_->offer(last_system, node_abs_.data(), h_last)) {
    steps_since_offer_ = 0;
    demand_ = false;
    lag_ = period_;  // swapped in this many steps from now (deterministic mode)
  }
}

void WarpedPreconditioner::poll() {
  if (refresh_ && !deterministic_) adopt(false);  // take() returns at once unless a factor is done
}

void WarpedPreconditioner::apply(void* self, const double* r, double* z) {
  auto* w = static_cast<WarpedPreconditioner*>(self);
  const int32_t n = w->m_.num_nodes;
  const double* R = w->node_rot_.data();
  for (int32_t i = 0; i < n; ++i) m3::mulv_t(R + 9 * i, r + 3 * i, w->a_.data() + 3 * i);
  w->factor_->solve(w->a_.data(), w->b_.data());
  for (int32_t i = 0; i < n; ++i) m3::mulv(R + 9 * i, w->b_.data() + 3 * i, z + 3 * i);
}

}  // namespace stroma
