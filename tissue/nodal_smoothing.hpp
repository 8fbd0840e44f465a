#pragma once
/// \file nodal_smoothing.hpp
/// Locking-free near-incompressible tetrahedra (`material.locking_free`): node-based strain
/// smoothing (selective NS-FEM) and element patches (F-bar-patch), one domain machinery.
///
/// Linear tetrahedra lock at ν → 0.5: one volume constraint per element, ~5 elements per node,
/// only 3 DOFs per node. Here the strain is instead measured on a smoothing domain around each
/// node: the node's patch (the elements around it), each element counting with a quarter of its
/// volume. Its deformation gradient is the patch average
///   F_a = Σ_e (V_e/4)/V_a · F_e = Σ_j x_j ⊗ g_aj,   V_a = Σ_e V_e/4,
/// with g_aj the averaged shape gradients. One volume constraint per node, not per element:
/// no locking. The domain is a corotational element with as many nodes as its patch: polar
/// R_a of F_a, ε_a = sym(R_aᵀF_a) − I, stress σ = λ_a tr(ε) I + 2μ_a ε, energy V_a(μ_a ε:ε +
/// λ_a/2 tr²ε), forces f_j = −V_a R_a σ g_aj, tangent blocks V_a(λ r_j r_kᵀ + μ r_k r_jᵀ +
/// μ (g_aj·g_ak) I) with r = R_a g — symmetric positive semi-definite, as the element's.
///
/// Smoothing the deviatoric part as well is what removes locking's bending stiffness, but pure
/// NS-FEM has spurious low-energy modes (its free-free spectrum collapses into a cluster at the
/// bottom; docs/TISSUE.md). So a share s (`stabilisation`, default 0.1) of the deviatoric
/// stiffness stays on the elements: the element kernel runs with (μ, λ) → (s·μ, −⅔·s·μ), a
/// purely deviatoric element energy s·μ|dev ε|², and each node domain carries the rest,
/// μ_a = (1 − s)·μ̄, λ_a = λ̄ + ⅔·s·μ̄ (so the bulk modulus κ = λ + ⅔μ is entirely nodal), with
/// μ̄, λ̄ (and the Rayleigh β) the patch's volume-weighted averages (regions mix at their
/// interface). Total: exactly the material's μ and κ, split across the two.
///
/// Element patches (`element_patches`, F-bar-patch in its small-strain corotational form): the
/// domains are instead disjoint patches of at least k elements (partition_element_patches),
/// each element counted whole (weight V_e), carrying only the bulk: the elements keep all of
/// the deviatoric stiffness (element_share = 1) and a share b of the bulk modulus
/// (ElementRange::element_bulk_share, default 0.02), the patch the rest. One volume
/// constraint per patch: with k ≥ 12–16 about one per node or fewer, so no locking; a patch
/// couples only its own nodes (one node's star and what joined it), so the assembled pattern
/// grows far less than node smoothing's two-ring and the warped factor of the whole system
/// stays cheap. The share b stops a patch's elements from collapsing one into another while
/// the patch keeps its volume (without it, soft beams gained energy through inverted
/// elements in the stability suite; docs/STABILITY.md). Element patches are always assembled.
///
/// Two ways to put the domains' tangent into the implicit system (NodalSmoothing::matrix_free):
///  - assembled: a domain couples every pair of its patch's nodes, so the BSR pattern grows to
///    the two-ring (~4× the blocks) and every solver takes the matrix as it is. Needed by
///    CHOLMOD (linear_solver: cholmod);
///  - matrix-free (linear_solver: cg): the pattern stays the elements' one-ring and CG applies
///    the domains as an extra operator (NodalSystem): per domain a gradient, a rotation and a
///    scatter, ~20 flops per patch node, where the assembled two-ring stores ~90 blocks. Jacobi
///    preconditioners add the domains' diagonal blocks; the warped Cholesky factor is built from
///    the plain (unsmoothed) element matrix, a nearby SPD one-ring matrix (docs/PERFORMANCE.md).

#include <cstdint>
#include <memory>
#include <vector>

namespace stroma {

struct FemModel;
struct ElasticPass;
struct ExtraOperator;

/// The smoothing domains (node domains or element patches) of all smoothed bodies, in CSR form.
/// Invariants: `ptr`/`pair_ptr` have domains()+1 entries; domain d's patch is entries
/// ptr[d] .. ptr[d+1] of `patch_node` (ascending global node ids, the centre node among them)
/// and `grad` (3 per entry; Σ of a domain's gradients = 0, Σ_j X_j ⊗ g_j = I at rest); its
/// upper pairs (a ≤ b in patch order) are pair_ptr[d] .. pair_ptr[d+1] of `pair_slot`, row by
/// row: (0,0), (0,1) … (0,n−1), (1,1) …, each the slot of block (node a, node b), a ≤ b.
/// volume > 0; mu ≥ 0; lambda + ⅔mu ≥ 0.
struct NodalSmoothing {
  std::vector<int32_t> centre;      ///< the domain's node (an element patch: its first element's first node)
  std::vector<int32_t> ptr;         ///< CSR offsets into patch_node / grad
  std::vector<int32_t> patch_node;  ///< global node ids of each patch, ascending
  std::vector<double> grad;         ///< 3 per patch entry: smoothed shape gradient (1/m)
  std::vector<int32_t> pair_ptr;    ///< CSR offsets into pair_slot
  std::vector<int32_t> pair_slot;   ///< BSR slot of each upper pair
  std::vector<int32_t> element_ptr; ///< CSR offsets into element
  std::vector<int32_t> element;     ///< each domain's elements (a node's star, or its patch)
  std::vector<double> volume;       ///< V_a (m³)
  std::vector<double> lambda, mu;   ///< the domain's Lamé parameters (after the element share)
  std::vector<double> beta;         ///< Rayleigh stiffness coefficient
  std::vector<uint8_t> linear;      ///< 1: a linear body (R = I), 0: corotational (polar R)
  /// The domains' tangent is applied by NodalSystem, not assembled: the pattern is the
  /// elements' only and pair_slot is empty.
  bool matrix_free = false;
  int32_t domains() const { return static_cast<int32_t>(centre.size()); }
  bool empty() const { return centre.empty(); }
};

/// Largest patch a node may have (its neighbours and itself); a larger one is a load error
/// (a degenerate mesh). The pass keeps its rotated gradients on the stack.
inline constexpr int kMaxPatch = 256;

/// Disjoint patches of at least k elements covering elements [element_begin, element_end) of
/// one body (nodes [node_begin, node_end)), for `element_patches`: greedy over the nodes in
/// order (a node's not yet taken elements become a patch when there are k or more), then each
/// element left over joins the neighbouring patch it shares most nodes with (the smallest among
/// equals), sweeping until none is left. Returns each element's patch id (0 .. patches − 1).
/// Needs m.node_element*. Deterministic.
std::vector<int32_t> partition_element_patches(const FemModel& m, int32_t element_begin, int32_t element_end,
                                               int32_t node_begin, int32_t node_end, int k);

/// Builds the node domains of every range with `smoothed` set (not fixed), from the elements
/// and node → element lists of `m` (set before). Returns, per domain, its patch as a node group
/// for the BSR pattern; pair_slot is filled later by assign_smoothing_slots(). Throws
/// std::invalid_argument for a patch over kMaxPatch nodes.
void build_nodal_smoothing(FemModel& m);

/// Fills NodalSmoothing::pair_slot from m.pattern (which must contain every patch pair).
/// Nothing when matrix-free.
void assign_smoothing_slots(FemModel& m);

/// The node domains' part of an implicit system, matrix-free (NodalSmoothing::matrix_free):
/// what the element pass records instead of assembling, and its product. Sized once; no
/// allocation afterwards. Invariant after the pass and finish(): apply() adds A_n·x with A_n the
/// domains' tangent scaled as the pass was asked (k_beta·β + k_const), with the rows and
/// columns of constrained DOFs zero; diag() holds A_n's 3×3 diagonal blocks (9 per node), with
/// the same rows and columns zero.
class NodalSystem {
 public:
  explicit NodalSystem(const FemModel& m);
  ~NodalSystem();
  /// Start of an assembly (the pass then records each domain).
  void begin();
  /// Records domain d: rotation R (row-major) and its scaled Lamé pair V·scale·(λ, μ); adds its
  /// diagonal blocks.
  void record(int32_t d, const double* R, double lambda, double mu);
  /// After the pass: zeroes the constrained rows and columns of the diagonal blocks.
  void finish();
  /// y += A_n·x.
  void apply(const double* x, double* y) const;
  const double* diag() const { return diag_.data(); }
  /// A function-pointer view for CgSolver (valid while this object lives).
  const ExtraOperator* op() const;

 private:
  static void apply_fn(void* self, const double* x, double* y);
  /// Domains per block of the product's batched stress (rot_ is stored [block][entry][lane]).
  static constexpr int kLanes = 8;
  /// Four doubles in one register (AVX), for the product's branch-free path.
  typedef double v4 __attribute__((vector_size(32)));
  const FemModel& m_;
  std::vector<double> rot_, lambda_, mu_, diag_;
  std::vector<int32_t> off_;     ///< per patch entry: 3 × its node
  std::vector<double> g4_;       ///< per patch entry: its gradient in 4 lanes (the 4th 0)
  std::vector<double> mask4_;    ///< per patch entry: 1 per free DOF, 0 per constrained (4 lanes)
  std::vector<uint8_t> masked_;  ///< per domain: its patch holds a constrained DOF
  std::unique_ptr<ExtraOperator> op_;
};

/// Adds the node domains' energy, forces, K·v and tangent blocks as ElasticPass asks (the same
/// outputs and scalings as the element pass: kv by kv_beta·β + kv_const, blocks by
/// k_beta·β + k_const; damage scales each domain by its patch's volume-weighted (1 − d)).
/// Returns the domains' energy. Visco-elastic state is not read (load refuses the combination).
double nodal_smoothing_pass(const FemModel& m, const ElasticPass& p);

}  // namespace stroma
