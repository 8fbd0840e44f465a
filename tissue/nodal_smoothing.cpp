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

/// Appends one domain over the elements `els`, element e weighing wt (m³: V_e/4 in a node
/// domain, V_e in an element patch): its patch, averaged gradients, volume and materials.
void add_domain(NodalSmoothing& s, const FemModel& m, const BodyRange& body, const ElementRange& r, int32_t centre,
                const std::vector<int32_t>& els, const std::vector<double>& wt, std::vector<int32_t>& patch,
                std::vector<double>& g) {
  patch.clear();
  double va = 0, lam = 0, mu = 0, beta = 0;
  for (size_t k = 0; k < els.size(); ++k) {
    const ElementParams& ep = m.elements[els[k]];
    for (int32_t n : ep.node) patch.push_back(n);
    va += wt[k];
    lam += wt[k] * ep.lambda;
    mu += wt[k] * ep.mu;
    beta += wt[k] * ep.beta;
  }
  std::sort(patch.begin(), patch.end());
  patch.erase(std::unique(patch.begin(), patch.end()), patch.end());
  if (patch.size() > static_cast<size_t>(kMaxPatch))
    throw std::invalid_argument("locking_free: " +
                                (r.patch_elements > 0 ? "a patch at node " : std::string("node ")) +
                                std::to_string(centre - body.node_begin) + " of body '" + body.name + "' has " +
                                std::to_string(patch.size() - 1) + " neighbours; smoothing supports up to " +
                                std::to_string(kMaxPatch - 1) + " (a degenerate mesh?)");
  g.assign(3 * patch.size(), 0.0);
  for (size_t k = 0; k < els.size(); ++k) {
    const ElementParams& ep = m.elements[els[k]];
    double G[4][3];
    element_gradients(ep, G);
    const double w = wt[k] / va;
    for (int i = 0; i < 4; ++i) {
      const auto at = std::lower_bound(patch.begin(), patch.end(), ep.node[i]) - patch.begin();
      for (int c = 0; c < 3; ++c) g[3 * at + c] += w * G[i][c];
    }
  }
  lam /= va;
  mu /= va;
  beta /= va;
  const double share = r.element_share;
  s.centre.push_back(centre);
  s.patch_node.insert(s.patch_node.end(), patch.begin(), patch.end());
  s.grad.insert(s.grad.end(), g.begin(), g.end());
  s.ptr.push_back(static_cast<int32_t>(s.patch_node.size()));
  s.element.insert(s.element.end(), els.begin(), els.end());
  s.element_ptr.push_back(static_cast<int32_t>(s.element.size()));
  const int32_t n = static_cast<int32_t>(patch.size());
  s.pair_ptr.push_back(s.pair_ptr.back() + n * (n + 1) / 2);
  s.volume.push_back(va);
  s.mu.push_back((1.0 - share) * mu);
  // The domain carries (1 − share)·μ̄ of the shear and (1 − bulk share)·κ̄ of the bulk.
  s.lambda.push_back((1.0 - r.element_bulk_share) * (lam + (2.0 / 3.0) * mu) - (2.0 / 3.0) * (1.0 - share) * mu);
  s.beta.push_back(beta);
  s.linear.push_back(r.kernel == ElementKernel::Linear ? 1 : 0);
}

}  // namespace

std::vector<int32_t> partition_element_patches(const FemModel& m, int32_t element_begin, int32_t element_end,
                                               int32_t node_begin, int32_t node_end, int k) {
  const int32_t ne = element_end - element_begin;
  std::vector<int32_t> patch(ne, -1), size;
  std::vector<int32_t> free_els;
  for (int32_t a = node_begin; a < node_end; ++a) {  // greedy: a node's untaken elements
    free_els.clear();
    for (int32_t q = m.node_element_ptr[a]; q < m.node_element_ptr[a + 1]; ++q) {
      const int32_t e = m.node_element[q];
      if (e >= element_begin && e < element_end && patch[e - element_begin] < 0) free_els.push_back(e);
    }
    if (static_cast<int>(free_els.size()) < k) continue;
    for (int32_t e : free_els) patch[e - element_begin] = static_cast<int32_t>(size.size());
    size.push_back(static_cast<int32_t>(free_els.size()));
  }
  // The leftovers join a neighbouring patch: the one they share most nodes with (a face
  // before an edge before a node), the smallest among equals; sweeps until none is left. A
  // component no patch reached starts its own.
  for (bool left = true; left;) {
    left = false;
    bool progress = false;
    for (int32_t le = 0; le < ne; ++le) {
      if (patch[le] >= 0) continue;
      const ElementParams& ep = m.elements[element_begin + le];
      int32_t best = -1, best_shared = 0;
      for (int32_t n : ep.node)
        for (int32_t q = m.node_element_ptr[n]; q < m.node_element_ptr[n + 1]; ++q) {
          const int32_t f = m.node_element[q];
          if (f < element_begin || f >= element_end || patch[f - element_begin] < 0) continue;
          int32_t shared = 0;
          for (int32_t a : ep.node)
            for (int32_t b : m.elements[f].node) shared += a == b;
          const int32_t p = patch[f - element_begin];
          if (best < 0 || shared > best_shared || (shared == best_shared && size[p] < size[best]))
            best = p, best_shared = shared;
        }
      if (best < 0) {
        left = true;
        continue;
      }
      patch[le] = best;
      ++size[best];
      progress = true;
    }
    if (left && !progress)
      for (int32_t le = 0; le < ne; ++le)
        if (patch[le] < 0) {
          patch[le] = static_cast<int32_t>(size.size());
          size.push_back(1);
          break;
        }
  }
  return patch;
}

void build_nodal_smoothing(FemModel& m) {
  NodalSmoothing& s = m.smoothing;
  const bool matrix_free = s.matrix_free;  // chosen by the caller before
  s = NodalSmoothing{};
  s.matrix_free = matrix_free;
  s.ptr.push_back(0);
  s.pair_ptr.push_back(0);
  s.element_ptr.push_back(0);
  std::vector<int32_t> patch, els;
  std::vector<double> g, wt;
  for (size_t ri = 0; ri < m.ranges.size(); ++ri) {
    const ElementRange& r = m.ranges[ri];
    if (!r.smoothed || r.fixed) continue;
    const BodyRange* body = nullptr;
    for (const BodyRange& b : m.bodies)
      if (b.element_begin == r.begin) body = &b;
    if (body == nullptr) throw std::logic_error("nodal smoothing: a smoothed range without its body");
    if (r.patch_elements > 0) {  // F-bar-patch: disjoint element patches, each element whole
      const std::vector<int32_t> pid =
          partition_element_patches(m, r.begin, r.end, body->node_begin, body->node_end, r.patch_elements);
      const int32_t np = pid.empty() ? 0 : *std::max_element(pid.begin(), pid.end()) + 1;
      std::vector<std::vector<int32_t>> members(np);
      for (int32_t le = 0; le < r.end - r.begin; ++le) members[pid[le]].push_back(r.begin + le);
      for (const std::vector<int32_t>& p : members) {
        wt.clear();
        for (int32_t e : p) wt.push_back(m.elements[e].volume);
        add_domain(s, m, *body, r, m.elements[p[0]].node[0], p, wt, patch, g);
      }
      continue;
    }
    for (int32_t a = body->node_begin; a < body->node_end; ++a) {
      const int32_t e0 = m.node_element_ptr[a], e1 = m.node_element_ptr[a + 1];
      if (e0 == e1) continue;  // an unused node (a fixed node's domain still acts on its neighbours)
      els.assign(m.node_element.begin() + e0, m.node_element.begin() + e1);
      wt.clear();
      for (int32_t e : els) wt.push_back(m.elements[e].volume / 4.0);
      add_domain(s, m, *body, r, a, els, wt, patch, g);
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
  // The domains' polar rotations, kBatch at a time through the branch-free batched SVD (as the
  // element pass does: one at a time it cost as much as the rest of the domain's work).
  constexpr int kBatch = 8;
  double Fb[9][kBatch], Rb[9][kBatch];
  for (int32_t d = 0; d < s.domains(); ++d) {
    const int32_t j0 = s.ptr[d], j1 = s.ptr[d + 1];
    const int lane = d % kBatch;
    if (lane == 0) {
      const int32_t n = std::min<int32_t>(kBatch, s.domains() - d);
      for (int b = 0; b < kBatch; ++b) {
        double Fd[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};  // (lanes past the end: the identity)
        if (b < n) patch_gradient(s, s.ptr[d + b], s.ptr[d + b + 1], p.x, Fd);
        for (int k = 0; k < 9; ++k) Fb[k][b] = Fd[k];
      }
      polar_rotation_batch<kBatch>(Fb, Rb);
    }
    const double* g = s.grad.data();
    double lambda = s.lambda[d], mu = s.mu[d];
    if (p.damage) {  // the patch's volume-weighted intactness
      double keep = 0, w = 0;
      for (int32_t k = s.element_ptr[d]; k < s.element_ptr[d + 1]; ++k) {
        const int32_t e = s.element[k];
        keep += m.elements[e].volume * (1.0 - static_cast<double>(p.damage[e]));
        w += m.elements[e].volume;
      }
      keep /= w;
      lambda *= keep;
      mu *= keep;
    }
    double F[9], R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (int k = 0; k < 9; ++k) F[k] = Fb[k][lane];
    if (!s.linear[d])
      for (int k = 0; k < 9; ++k) R[k] = Rb[k][lane];
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
      if (mu == 0.0) {  // bulk only (element patches, or s = 1): block (a, b) = Vλ r_a r_bᵀ
        for (int32_t a = 0; a < n; ++a) {
          double ra[3];
          for (int i = 0; i < 3; ++i) ra[i] = sl * r[3 * a + i];
          for (int32_t b = a; b < n; ++b) {
            const double* rb = r + 3 * b;
            double* S = p.kvals + 9 * static_cast<size_t>(*slot++);
            for (int i = 0; i < 3; ++i)
              for (int k = 0; k < 3; ++k) S[3 * i + k] += ra[i] * rb[k];
          }
        }
        continue;
      }
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
  rot_.assign(9 * (d + kLanes), 0.0);  // [block of kLanes domains][entry][lane]
  lambda_.assign(d + kLanes, 0.0);  // (padded: the product's last block reads whole blocks)
  mu_.assign(d + kLanes, 0.0);
  diag_.assign(9 * static_cast<size_t>(m.num_nodes), 0.0);
  // The product's packed form: each patch entry's DOF offset, its gradient and its free-DOF
  // mask (1 free, 0 constrained) in four lanes, and which domains touch a constrained DOF.
  const size_t entries = m.smoothing.patch_node.size();
  off_.resize(entries);
  g4_.assign(4 * entries, 0.0);
  mask4_.assign(4 * entries, 0.0);
  for (size_t j = 0; j < entries; ++j) {
    const int32_t n = m.smoothing.patch_node[j];
    off_[j] = 3 * n;
    for (int k = 0; k < 3; ++k) {
      g4_[4 * j + k] = m.smoothing.grad[3 * j + k];
      mask4_[4 * j + k] = (m.constrained[n] & (1u << k)) ? 0.0 : 1.0;
    }
  }
  masked_.assign(d, 0);
  for (size_t k = 0; k < d; ++k)
    for (int32_t j = m.smoothing.ptr[k]; j < m.smoothing.ptr[k + 1]; ++j)
      if (m.constrained[m.smoothing.patch_node[j]]) masked_[k] = 1;
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
  for (int k = 0; k < 9; ++k) rot_[9 * kLanes * (d / kLanes) + kLanes * k + d % kLanes] = R[k];
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
  const int32_t* off = off_.data();
  const double* g4 = g4_.data();
  const double* mask4 = mask4_.data();
  const int32_t D = s.domains();
  // kLanes domains at a time: gather each one's L = Σ x_j ⊗ g_j, then their stresses
  // P = R·σ(sym(RᵀL)) together across the lanes (vectorised: done one domain at a time the
  // 3×3 products were a third of the product's cost), then scatter y_j += P·g_j.
  for (int32_t d0 = 0; d0 < D; d0 += kLanes) {
    const int n = std::min<int32_t>(kLanes, D - d0);
    alignas(64) double Lb[9][kLanes] = {}, Pb[9][kLanes];
    for (int lane = 0; lane < n; ++lane) {
      const int32_t d = d0 + lane;
      const int32_t j0 = s.ptr[d], j1 = s.ptr[d + 1];
      const bool masked = masked_[d];
      // Four lanes per gradient (the fourth 0), two entries at a time into separate sums (the
      // loop is bound by the additions' latency). A constrained DOF's column is zero: masked.
      v4 A0 = {0, 0, 0, 0}, A1 = A0, A2 = A0, B0 = A0, B1 = A0, B2 = A0;
      auto entry = [&](int32_t k, v4& L0, v4& L1, v4& L2) {
        v4 g;
        __builtin_memcpy(&g, g4 + 4 * static_cast<size_t>(k), sizeof g);
        const double* xn = x + off[k];
        double x0 = xn[0], x1 = xn[1], x2 = xn[2];
        if (masked) {
          const double* mk = mask4 + 4 * static_cast<size_t>(k);
          x0 *= mk[0], x1 *= mk[1], x2 *= mk[2];
        }
        L0 += x0 * g;
        L1 += x1 * g;
        L2 += x2 * g;
      };
      int32_t j = j0;
      for (; j + 1 < j1; j += 2) {
        entry(j, A0, A1, A2);
        entry(j + 1, B0, B1, B2);
      }
      if (j < j1) entry(j, A0, A1, A2);
      A0 += B0, A1 += B1, A2 += B2;
      for (int k = 0; k < 3; ++k) {
        Lb[k][lane] = A0[k];
        Lb[3 + k][lane] = A1[k];
        Lb[6 + k][lane] = A2[k];
      }
    }
    // (A domain not recorded — a damaged-through patch — has λ = μ = 0: P = 0.)
    const double* R = rot_.data() + 9 * static_cast<size_t>(d0);  // this block's [entry][lane]
    const double* lam = lambda_.data() + d0;
    const double* mu = mu_.data() + d0;
#pragma omp simd
    for (int lane = 0; lane < kLanes; ++lane) {
      double S[9];  // RᵀL
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          S[3 * a + b] = R[(0 + a) * kLanes + lane] * Lb[b][lane] + R[(3 + a) * kLanes + lane] * Lb[3 + b][lane] +
                         R[(6 + a) * kLanes + lane] * Lb[6 + b][lane];
      const double tr = lam[lane] * (S[0] + S[4] + S[8]);
      double sig[9];
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) sig[3 * a + b] = mu[lane] * (S[3 * a + b] + S[3 * b + a]);
      sig[0] += tr, sig[4] += tr, sig[8] += tr;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          Pb[3 * a + b][lane] = R[(3 * a + 0) * kLanes + lane] * sig[b] + R[(3 * a + 1) * kLanes + lane] * sig[3 + b] +
                                R[(3 * a + 2) * kLanes + lane] * sig[6 + b];
    }
    for (int lane = 0; lane < n; ++lane) {
      const int32_t d = d0 + lane;
      const bool masked = masked_[d];
      // y_j += P·g_j (a constrained DOF's row is zero: masked out).
      const v4 c0 = {Pb[0][lane], Pb[3][lane], Pb[6][lane], 0}, c1 = {Pb[1][lane], Pb[4][lane], Pb[7][lane], 0},
               c2 = {Pb[2][lane], Pb[5][lane], Pb[8][lane], 0};
      for (int32_t j = s.ptr[d]; j < s.ptr[d + 1]; ++j) {
        const double* g = g4 + 4 * static_cast<size_t>(j);
        v4 f = c0 * g[0] + c1 * g[1] + c2 * g[2];
        if (masked) {
          v4 mk;
          __builtin_memcpy(&mk, mask4 + 4 * static_cast<size_t>(j), sizeof mk);
          f *= mk;
        }
        double* yn = y + off[j];
        yn[0] += f[0];
        yn[1] += f[1];
        yn[2] += f[2];
      }
    }
  }
}

}  // namespace stroma
