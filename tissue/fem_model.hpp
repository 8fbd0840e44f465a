#pragma once
/// \file fem_model.hpp
/// The compiled, immutable finite-element model of all deformable bodies: rest geometry,
/// per-element shape gradients and Lamé parameters, lumped masses, constraints, constant
/// external forces, the fixed BSR sparsity pattern and element→slot scatter maps.
/// Built once (fem_build.hpp); read-only afterwards, shared by every thread.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "tissue/bsr_matrix.hpp"
#include "tissue/fibre.hpp"
#include "tissue/nodal_smoothing.hpp"
#include "tissue/viscoelastic.hpp"
#include "tissue/options.hpp"
#include "tissue/rod.hpp"
#include "tissue/tet_mesh.hpp"

namespace stroma {

/// What one linear tetrahedron needs each tick (120 bytes, contiguous). Invariants: the four
/// nodes are distinct and positively oriented at rest (volume > 0); lambda, mu ≥ 0 (valid E, ν);
/// beta ≥ 0.
struct ElementParams {
  std::array<int32_t, 4> node;  ///< global node indices
  double g[9];      ///< rows: gradients of shape functions N1, N2, N3 (∇N0 = −Σ); = Dm⁻¹
  double volume;    ///< rest volume (> 0)
  double lambda;    ///< Lamé λ
  double mu;        ///< Lamé μ
  double beta;      ///< Rayleigh stiffness coefficient of its body
};

/// How a contiguous range of elements is computed (one body; one kernel, no per-element branch).
enum class ElementKernel : uint8_t { Linear, CorotationalPolar, CorotationalQR, StableNeoHookean, StVenantKirchhoff };

/// A contiguous range of elements sharing one kernel (one body).
struct ElementRange {
  int32_t begin = 0;
  int32_t end = 0;
  ElementKernel kernel = ElementKernel::CorotationalPolar;
  /// Every node of the body is fixed: a rigid obstacle (e.g. a table for body contact). The
  /// elastic pass skips it — its forces and stiffness would only land on fixed DOFs, and it
  /// stays at rest with zero energy — so a fixed body costs nothing per tick.
  bool fixed = false;
  /// Its elements carry fibres (FemModel::fibres): a hyperelastic kernel adds their term.
  bool fibres = false;
  /// Visco-elastic (viscoelastic.hpp): index into FemModel::visco, −1 for none. Its elements'
  /// internal variables start at visco_q_begin (terms × 6 per element) and visco_s0_begin (6 per
  /// element) of TissueState::visco_q / visco_s0.
  int32_t visco = -1;
  int64_t visco_q_begin = 0, visco_s0_begin = 0;
  /// Locking-free (nodal_smoothing.hpp): the elements keep only `element_share` of the
  /// deviatoric stiffness — the kernel runs with (μ, λ) → (share·μ, −⅔·share·μ) — and the node
  /// domains of FemModel::smoothing carry the rest and all of the bulk. Linear and corotational
  /// kernels only.
  bool smoothed = false;
  double element_share = 1.0;
  /// 0: the domains are node domains; ≥ 2: disjoint patches of at least this many elements.
  int32_t patch_elements = 0;
  /// The share of the bulk modulus κ kept on each element (the kernel's λ gains
  /// element_bulk_share·κ, the domains carry the rest); 0 for node domains. It keeps single
  /// elements of a patch from collapsing while the patch keeps its volume (docs/TISSUE.md).
  double element_bulk_share = 0.0;
};

/// One body's slice of the global arrays.
struct BodyRange {
  std::string name;
  double density = 0;                          ///< kg/m³ (a cut model re-lumps its masses with it)
  int32_t node_begin = 0, node_end = 0;        ///< global node indices [begin, end)
  int32_t element_begin = 0, element_end = 0;  ///< global element indices
  std::vector<Tri> boundary;                   ///< surface triangles, global node indices
};

/// The whole compiled FEM system.
/// Invariants: every array indexed by node has num_nodes entries (rest, f_ext: 3·num_nodes);
/// elements, slots and (QR only) rest_frame are parallel; ranges and bodies cover the elements
/// in order without overlap; constrained nodes (mask 7) have zero rows and columns in every
/// projected matrix; a node used by no tetrahedron and no rod is fully constrained and massless.
struct FemModel {
  int32_t num_nodes = 0;
  std::vector<double> rest;                 ///< 3n rest positions
  std::vector<ElementParams> elements;
  std::vector<ElementRange> ranges;         ///< kernels by range, covering all elements
  std::vector<std::array<double, 9>> rest_frame;  ///< per element, QR rotation only (else empty)
  std::vector<double> mass;                 ///< lumped mass per node (kg); 0 for unused nodes
  /// Per element its density (kg/m³) when some body has regions of their own density; empty:
  /// each element has its body's (BodyRange::density). element_density() reads either.
  std::vector<double> element_density;
  /// Per element its fibres (fibre.hpp) when some body is fibre-reinforced; empty otherwise.
  /// Elements of ranges without `fibres` are never read (k1 = 0 there).
  std::vector<FibreParams> fibres;
  /// Prony series of the visco-elastic ranges (ElementRange::visco), and the sizes of the
  /// state's internal-variable arrays (0: no visco-elastic body).
  std::vector<PronySeries> visco;
  int64_t visco_q_size = 0, visco_s0_size = 0;
  /// Node domains of the locking-free bodies (nodal_smoothing.hpp); empty: none. The pattern
  /// then couples every pair of nodes of each domain's patch (the two-ring).
  NodalSmoothing smoothing;
  std::vector<double> inv_mass;             ///< 1/mass (0 for nodes without mass)
  std::vector<double> alpha;                ///< Rayleigh mass coefficient per node
  /// Per node, bit k set: DOF k (x, y, z) is fixed. 7: the node does not move (fixed or
  /// unused by any tetrahedron).
  std::vector<uint8_t> constrained;
  std::vector<int32_t> constrained_nodes;   ///< nodes with any constrained DOF
  std::vector<double> f_ext;                ///< 3n constant external force (gravity + loads)
  Vec3 gravity{0, 0, 0};                    ///< m/s², included in f_ext as mass·g
  BsrPattern pattern;
  std::vector<ElementSlots> slots;          ///< per element
  /// Off-diagonal blocks (slot, row node, column node) touching a constrained DOF.
  std::vector<std::array<int32_t, 3>> constrained_offdiag;
  std::vector<BodyRange> bodies;
  /// Rods (suture threads, rod.hpp): chains of nodes after the bodies' nodes, with their slots
  /// (rod_slots: per rod from its slot_begin). Not in `bodies`: they have no tetrahedra, surface
  /// or elements, and the element pass adds their energy after the elements'.
  std::vector<RodRange> rods;
  /// Rods' nodes tied to material points of the tissue (anchor knots, rod.hpp); their slots
  /// follow the rods' in rod_slots.
  std::vector<RodAnchor> rod_anchors;
  std::vector<int32_t> rod_slots;
  /// Elements around each node (CSR): node i's are node_element[node_element_ptr[i] ..
  /// node_element_ptr[i + 1]), in increasing order. Damage (mass removal at rupture) and the
  /// warped preconditioner (a rotation per node) read them.
  std::vector<int32_t> node_element_ptr, node_element;
  /// Some element has Rayleigh stiffness damping (β > 0): the symplectic step and the Newton
  /// residual need a K·v pass only then.
  bool any_stiffness_damping = false;

  /// Number of degrees of freedom (3 per node, constrained included).
  int32_t dofs() const { return 3 * num_nodes; }
};

/// Element e's density: its own (regions) or its body's `b`.
inline double element_density(const FemModel& m, int32_t e, const BodyRange& b) {
  return m.element_density.empty() ? b.density : m.element_density[e];
}

/// Adds the implicit step's mass term (1 + h·α_i)·m_i to each node's diagonal block of the BSR
/// values A. `mass`: the lumped masses to use (the model's, or the current ones after damage).
inline void add_mass_diagonal(const FemModel& m, double* A, double h, const double* mass) {
  for (int32_t i = 0; i < m.num_nodes; ++i) {
    double* D = A + 9 * m.pattern.diag[i];
    const double md = (1.0 + h * m.alpha[i]) * mass[i];
    D[0] += md;
    D[4] += md;
    D[8] += md;
  }
}

}  // namespace stroma
