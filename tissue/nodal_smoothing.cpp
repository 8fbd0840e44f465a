#include "tissue/nodal_smoothing.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "tissue/cg_solver.hpp"
#include "tissue/fem_forces.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/mat3.hpp"
#include "tissue/material.hpp"
#include "tissue/rotation.hpp"

namespace stroma {

namespace {

/// The four shape gradients of element e (rows of g are ∇N1..∇N3; ∇N0 = −Σ).
inline void element_gradients(const ElementParams& ep, double (&G)[4][3]) {
  for (int k = 0; k < 3; ++k) {
    G[1][k] = ep.g[k];
    G[2][k] = ep.g[3 + k];
    G[3][k] = ep.g[6 + k];
    G[0][k] = -(G[1][k] + G[2][k] + G[3][k]);
  }
}

/// G = Σ_j u_j ⊗ g_j over patch entries j0..j1 (row-major G[3i+k] = Σ u_j[i] g_j[k]).
inline void patch_gradient(const NodalSmoothing& s, int32_t j0, int32_t j1, const double* u, double* G) {
  std::fill(G, G + 9, 0.0);
  for (int32_t j = j0; j < j1; ++j) {
    const double* uj = u + 3 * s.patch_node[j];
    const double* gj = s.grad.data() + 3 * j;
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) G[3 * i + k] += uj[i] * gj[k];
  }
}

/// out_j += scale·P·g_j for every patch entry.
inline void patch_scatter(const NodalSmoothing& s, int32_t j0, int32_t j1, const double* P, double scale, double* out) {
  for (int32_t j = j0; j < j1; ++j) {
    double f[3];
    m3::mulv(P, s.grad.data() + 3 * j, f);
    double* o = out + 3 * s.patch_node[j];
    for (int i = 0; i < 3; ++i) o[i] += scale * f[i];
  }
}

}  // namespace

void build_nodal_smoothing(FemModel& m) {
  NodalSmoothing& s = m.smoothing;
  const bool matrix_free = s.matrix_free;  // chosen by the caller before
  s = NodalSmoothing{};
  s.matrix_free = matrix_free;
  s.ptr.push_back(0);
  s.pair_ptr.push_back(0);
  std::vector<int32_t> patch;
  std::vector<double> g;
  for (size_t ri = 0; ri < m.ranges.size(); ++ri) {
    const ElementRange& r = m.ranges[ri];
    if (!r.smoothed || r.fixed) continue;
    const BodyRange* body = nullptr;
    for (const BodyRange& b : m.bodies)
      if (b.element_begin == r.begin) body = &b;
    if (body == nullptr) throw std::logic_error("nodal smoothing: a smoothed range without its body");
    const double share = r.element_share;
    for (int32_t a = body->node_begin; a < body->node_end; ++a) {
      const int32_t e0 = m.node_element_ptr[a], e1 = m.node_element_ptr[a + 1];
      if (e0 == e1) continue;  // an unused node (a fixed node's domain still acts on its neighbours)
      patch.clear();
      double va = 0, lam = 0, mu = 0, beta = 0;
      for (int32_t k = e0; k < e1; ++k) {
        const ElementParams& ep = m.elements[m.node_element[k]];
        for (int32_t n : ep.node) patch.push_back(n);
        const double w = ep.volume / 4.0;
        va += w;
        lam += w * ep.lambda;
        mu += w * ep.mu;
        beta += w * ep.beta;
      }
      std::sort(patch.begin(), patch.end());
      patch.erase(std::unique(patch.begin(), patch.end()), patch.end());
      if (patch.size() > static_cast<size_t>(kMaxPatch))
        throw std::invalid_argument("locking_free: node " + std::to_string(a - body->node_begin) + " of body '" +
                                    body->name + "' has " + std::to_string(patch.size() - 1) +
                                    " neighbours; node smoothing supports up to " + std::to_string(kMaxPatch - 1) +
                                    " (a degenerate mesh?)");
      g.assign(3 * patch.size(), 0.0);
      for (int32_t k = e0; k < e1; ++k) {
        const ElementParams& ep = m.elements[m.node_element[k]];
        double G[4][3];
        element_gradients(ep, G);
        const double w = ep.volume / 4.0 / va;
        for (int i = 0; i < 4; ++i) {
          const auto at = std::lower_bound(patch.begin(), patch.end(), ep.node[i]) - patch.begin();
          for (int c = 0; c < 3; ++c) g[3 * at + c] += w * G[i][c];
        }
      }
      lam /= va;
      mu /= va;
      beta /= va;
      s.centre.push_back(a);
      s.patch_node.insert(s.patch_node.end(), patch.begin(), patch.end());
      s.grad.insert(s.grad.end(), g.begin(), g.end());
      s.ptr.push_back(static_cast<int32_t>(s.patch_node.size()));
      const int32_t n = static_cast<int32_t>(patch.size());
      s.pair_ptr.push_back(s.pair_ptr.back() + n * (n + 1) / 2);
      s.volume.push_back(va);
      s.mu.push_back((1.0 - share) * mu);
      s.lambda.push_back(lam + (2.0 / 3.0) * share * mu);
      s.beta.push_back(beta);
      s.linear.push_back(r.kernel == ElementKernel::Linear ? 1 : 0);
    }
  }
  if (!s.matrix_free) s.pair_slot.assign(s.pair_ptr.back(), -1);
}

void assign_smoothing_slots(FemModel& m) {
  NodalSmoothing& s = m.smoothing;
  if (s.matrix_free) return;
  for (int32_t d = 0; d < s.domains(); ++d) {
    int32_t q = s.pair_ptr[d];
    for (int32_t a = s.ptr[d]; a < s.ptr[d + 1]; ++a)
      for (int32_t b = a; b < s.ptr[d + 1]; ++b) {
        const int32_t slot = m.pattern.find(s.patch_node[a], s.patch_node[b]);
        if (slot < 0) throw std::logic_error("nodal smoothing: a patch pair is missing from the BSR pattern");
        s.pair_slot[q++] = slot;
      }
  }
}

double nodal_smoothing_pass(const FemModel& m, const ElasticPass& p) {
  const NodalSmoothing& s = m.smoothing;
  double energy = 0.0;
  double r[3 * kMaxPatch];  // rotated gradients R·g of the current domain
  for (int32_t d = 0; d < s.domains(); ++d) {
    const int32_t j0 = s.ptr[d], j1 = s.ptr[d + 1];
    const double* g = s.grad.data();
    double lambda = s.lambda[d], mu = s.mu[d];
    if (p.damage) {  // the patch's volume-weighted intactness
      const int32_t a = s.centre[d];
      double keep = 0, w = 0;
      for (int32_t k = m.node_element_ptr[a]; k < m.node_element_ptr[a + 1]; ++k) {
        const int32_t e = m.node_element[k];
        keep += m.elements[e].volume * (1.0 - static_cast<double>(p.damage[e]));
        w += m.elements[e].volume;
      }
      keep /= w;
      lambda *= keep;
      mu *= keep;
    }
    double F[9];
    patch_gradient(s, j0, j1, p.x, F);
    double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    if (!s.linear[d]) polar_rotation(F, R);
    const double V = s.volume[d];
    // ε = sym(RᵀF) − I, P = R·σ(ε); energy V(μ ε:ε + λ/2 tr²ε).
    double P[9], e[9];
    rotated_stress(R, F, lambda, mu, 1.0, P, e);
    double ee = 0;
    for (int k = 0; k < 9; ++k) ee += e[k] * e[k];
    const double tr = e[0] + e[4] + e[8];
    energy += V * (mu * ee + 0.5 * lambda * tr * tr);
    if (p.force) patch_scatter(s, j0, j1, P, -V, p.force);
    if (p.kv) {
      double L[9], Pv[9];
      patch_gradient(s, j0, j1, p.v, L);
      rotated_stress(R, L, lambda, mu, 0.0, Pv, nullptr);
      patch_scatter(s, j0, j1, Pv, V * (p.kv_beta * s.beta[d] + p.kv_const), p.kv);
    }
    if (!p.kvals) continue;
    const double scale = V * (p.k_beta * s.beta[d] + p.k_const);
    if (s.matrix_free) {
      if (p.nodal_system) p.nodal_system->record(d, R, scale * lambda, scale * mu);
    } else {
      const int32_t n = j1 - j0;
      for (int32_t a = 0; a < n; ++a) m3::mulv(R, g + 3 * (j0 + a), r + 3 * a);
      const double sl = scale * lambda, sm = scale * mu;
      const int32_t* slot = s.pair_slot.data() + s.pair_ptr[d];
      for (int32_t a = 0; a < n; ++a) {
        const double* ra = r + 3 * a;
        const double* ga = g + 3 * (j0 + a);
        for (int32_t b = a; b < n; ++b) {
          const double* rb = r + 3 * b;
          const double* gb = g + 3 * (j0 + b);
          // block (a, b) = V(λ r_a r_bᵀ + μ r_b r_aᵀ + μ (g_a·g_b) I); a ≤ b in node order.
          double* S = p.kvals + 9 * static_cast<size_t>(*slot++);
          const double gg = sm * (ga[0] * gb[0] + ga[1] * gb[1] + ga[2] * gb[2]);
          for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k) S[3 * i + k] += sl * ra[i] * rb[k] + sm * rb[i] * ra[k];
          S[0] += gg;
          S[4] += gg;
          S[8] += gg;
        }
      }
    }
  }
  return energy;
}

// ---------------------------------------------------------------------------------------------
// NodalSystem

NodalSystem::NodalSystem(const FemModel& m) : m_(m), op_(std::make_unique<ExtraOperator>()) {
  const size_t d = static_cast<size_t>(m.smoothing.domains());
  rot_.assign(9 * d, 0.0);
  lambda_.assign(d, 0.0);
  mu_.assign(d, 0.0);
  diag_.assign(9 * static_cast<size_t>(m.num_nodes), 0.0);
  op_->apply = &NodalSystem::apply_fn;
  op_->context = this;
  op_->diag = diag_.data();
}

NodalSystem::~NodalSystem() = default;

const ExtraOperator* NodalSystem::op() const { return op_.get(); }

void NodalSystem::apply_fn(void* self, const double* x, double* y) { static_cast<const NodalSystem*>(self)->apply(x, y); }

void NodalSystem::begin() {
  std::fill(diag_.begin(), diag_.end(), 0.0);
  std::fill(lambda_.begin(), lambda_.end(), 0.0);
  std::fill(mu_.begin(), mu_.end(), 0.0);
}

void NodalSystem::record(int32_t d, const double* R, double lambda, double mu) {
  const NodalSmoothing& s = m_.smoothing;
  for (int k = 0; k < 9; ++k) rot_[9 * d + k] = R[k];
  lambda_[d] = lambda;
  mu_[d] = mu;
  // Diagonal blocks V(λ r rᵀ + μ r rᵀ + μ|g|² I), r = R·g (V·scale already in λ, μ).
  for (int32_t j = s.ptr[d]; j < s.ptr[d + 1]; ++j) {
    const double* g = s.grad.data() + 3 * j;
    double r[3];
    m3::mulv(R, g, r);
    double* D = diag_.data() + 9 * s.patch_node[j];
    const double gg = mu * (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) D[3 * a + b] += (lambda + mu) * r[a] * r[b];
    D[0] += gg;
    D[4] += gg;
    D[8] += gg;
  }
}

void NodalSystem::finish() {
  for (int32_t i : m_.constrained_nodes) {
    const uint8_t c = m_.constrained[i];
    double* D = diag_.data() + 9 * i;
    for (int a = 0; a < 3; ++a)
      if (c & (1u << a))
        for (int b = 0; b < 3; ++b) D[3 * a + b] = D[3 * b + a] = 0.0;
  }
}

void NodalSystem::apply(const double* x, double* y) const {
  const NodalSmoothing& s = m_.smoothing;
  const int32_t* nodes = s.patch_node.data();
  const uint8_t* fixed = m_.constrained.data();
  for (int32_t d = 0; d < s.domains(); ++d) {
    const double lambda = lambda_[d], mu = mu_[d];
    if (lambda == 0.0 && mu == 0.0) continue;  // not recorded (a damaged-through patch)
    const int32_t j0 = s.ptr[d], j1 = s.ptr[d + 1];
    const double* g = s.grad.data() + 3 * j0;
    // L = Σ x_j ⊗ g_j over the free DOFs (a constrained DOF's column is zero).
    double L[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (int32_t j = j0; j < j1; ++j, g += 3) {
      const int32_t n = nodes[j];
      double xv[3] = {x[3 * n], x[3 * n + 1], x[3 * n + 2]};
      if (fixed[n])
        for (int a = 0; a < 3; ++a)
          if (fixed[n] & (1u << a)) xv[a] = 0.0;
      for (int a = 0; a < 3; ++a)
        for (int k = 0; k < 3; ++k) L[3 * a + k] += xv[a] * g[k];
    }
    double P[9];
    rotated_stress(rot_.data() + 9 * d, L, lambda, mu, 0.0, P, nullptr);
    g = s.grad.data() + 3 * j0;
    for (int32_t j = j0; j < j1; ++j, g += 3) {
      const int32_t n = nodes[j];
      double f[3];
      m3::mulv(P, g, f);
      if (fixed[n])
        for (int a = 0; a < 3; ++a)
          if (fixed[n] & (1u << a)) f[a] = 0.0;
      y[3 * n] += f[0];
      y[3 * n + 1] += f[1];
      y[3 * n + 2] += f[2];
    }
  }
}

}  // namespace stroma
