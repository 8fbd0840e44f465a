#include "tissue/warped_preconditioner.hpp"

#include <algorithm>

#include "tissue/constraints.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/mat3.hpp"

namespace stroma {

WarpedPreconditioner::WarpedPreconditioner(const FemModel& model) : m_(model) {
  const size_t n3 = 3 * static_cast<size_t>(m_.num_nodes);
  node_rot_.assign(9 * static_cast<size_t>(m_.num_nodes), 0.0);
  for (int32_t i = 0; i < m_.num_nodes; ++i) node_rot_[9 * i] = node_rot_[9 * i + 4] = node_rot_[9 * i + 8] = 1.0;
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
  elastic_pass(m_, p);
  if (h_mass >= 0) add_mass_diagonal(m_, A0.data(), h_mass, m_.mass.data());
  project_constraints(m_, A0.data(), 1.0, false);
  if (!factor_) factor_ = std::make_unique<CholmodSolver>(m_.pattern);
  factor_->factor(A0.data());
  key_[0] = h_mass;
  key_[1] = k_beta;
  key_[2] = k_const;
}

void WarpedPreconditioner::update_rotations(const double* rot) {
  for (int32_t i = 0; i < m_.num_nodes; ++i) {
    double* R = node_rot_.data() + 9 * i;
    const bool has_element = m_.node_element_ptr[i + 1] > m_.node_element_ptr[i];
    if (!has_element || m_.constrained[i] == 7) {
      std::fill(R, R + 9, 0.0);
      R[0] = R[4] = R[8] = 1.0;
    } else {
      const int32_t e = m_.node_element[m_.node_element_ptr[i]];
      std::copy(rot + 9 * e, rot + 9 * e + 9, R);
    }
  }
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
