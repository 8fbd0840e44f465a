#pragma once
/// \file rod.hpp
/// A rod — a suture thread — as a chain of nodes of the FEM node space (issue 43; the design is
/// docs/ARCHITECTURE.md, "Bodies of more than one kind"). Its nodes are tissue-like nodes: they
/// live in TissueState::x and v, are fixed, damped, snapshotted and published as every node is;
/// its mass is lumped on them (ρ·A·ℓ/2 from each segment). Its energy is
///
///   E = Σ_segments ½·k_s·(|x_{i+1} − x_i| − ℓ)²  +  Σ_interior ½·k_b·|x_{i−1} − 2·x_i + x_{i+1}|²
///
/// with k_s = E·A/ℓ (stretching: an axial spring per segment) and k_b = E·I/ℓ³ (bending: the
/// quadratic bending energy of a discrete inextensible curve, Bergou, Wardetzky, Harmon, Zorin &
/// Grinspun 2006, "A quadratic bending model for inextensible surfaces", in its 1-D form). For
/// equal segments of length ℓ turning by θ at a node, |x_{i−1} − 2x_i + x_{i+1}| = 2ℓ·sin(θ/2),
/// so the bending term is ½·E·I·θ²/ℓ (the integral of ½·E·I·κ² over the node's ℓ) to O(θ⁴):
/// exact as the segments shorten. Its Hessian is constant — precomputed pattern slots, no
/// rotation to track, no energy gain from linearising it in the implicit step — and the rest
/// shape is straight (a suture has no memory of its spool worth modelling at these forces).
/// Twist is not modelled: a round, isotropic thread's twist is quasi-static and decouples from
/// its centreline when its rest shape is straight (Bergou et al. 2008, "Discrete elastic rods"),
/// and a suture's torsional stiffness is not a published parameter.
///
/// Invariants (rod_check in debug builds): node_end − node_begin ≥ 3 (two segments or more),
/// consecutive node indices; segment_length > 0; stretch_stiffness > 0; bend_stiffness ≥ 0;
/// beta ≥ 0; its slots are 3 per segment and 6 per interior node from slot_begin in
/// FemModel::rod_slots.

#include <cmath>
#include <cstdint>
#include <string>

namespace stroma {

/// One rod's slice of the FEM arrays and its constants.
struct RodRange {
  std::string name;
  int32_t node_begin = 0, node_end = 0;  ///< global node indices [begin, end), in order along the rod
  double segment_length = 0;             ///< rest length ℓ of every segment (m)
  double stretch_stiffness = 0;          ///< k_s = E·A/ℓ (N/m)
  double bend_stiffness = 0;             ///< k_b = E·I/ℓ³ (N/m)
  double beta = 0;                       ///< Rayleigh stiffness damping (s)
  double diameter = 0;                   ///< m (for output: the stiffnesses carry it)
  double friction = 0;                   ///< Coulomb coefficient where it passes through tissue (punctures) and in contact
  /// Pa/m: the pressure its contact with the tissue's surface makes per metre of penetration
  /// (engine/thread_contact.hpp; on the projected area diameter × arc length). ≥ 0 (0: none).
  double contact_stiffness = 0;
  /// Its pattern slots in FemModel::rod_slots from here: per segment (i, i+1) the blocks
  /// (i, i), (i, i+1), (i+1, i+1); then per interior node i the blocks of (i−1, i, i+1):
  /// (i−1, i−1), (i−1, i), (i−1, i+1), (i, i), (i, i+1), (i+1, i+1).
  int32_t slot_begin = 0;

  int32_t nodes() const { return node_end - node_begin; }
  int32_t segments() const { return nodes() - 1; }
};

/// A rod's node tied to a material point of the tissue (an anchor knot; docs/THREAD.md): a
/// zero-length spring of energy ½·k·|x_node − Σ_a w_a x_tissue[a]|², whose Hessian is the
/// constant k·(c cᵀ ⊗ I) with c = (1, −w_0, −w_1, −w_2, −w_3) — like the rods' terms, assembled
/// into precomputed pattern slots (the five nodes are one pattern group), nothing linearised.
/// Invariants (model_check): node is a rod's node; tissue[] are tissue nodes (before the rods');
/// w ≥ 0 summing to 1; stiffness > 0; beta ≥ 0; its 15 slots (the upper triangle of the
/// 5×5 block pairs in the order (0,0), (0,1) … (0,4), (1,1) … (4,4) of (node, tissue[0..3]))
/// are in FemModel::rod_slots from slot_begin.
struct RodAnchor {
  int32_t node = 0;
  int32_t tissue[4] = {0, 0, 0, 0};
  double w[4] = {1, 0, 0, 0};
  double stiffness = 0;  ///< k (N/m)
  double beta = 0;       ///< Rayleigh stiffness damping (s): the rod's
  int32_t slot_begin = 0;
};

/// Where a rod passes through the tissue (a puncture the needle made; engine/thread_attach.hpp):
/// a material point of a tetrahedron and the rod's point tied to it, at σ along the rod in node
/// units from its first node (segment ⌊σ⌋, fraction σ − ⌊σ⌋). Tied by a spring stiff across the
/// rod and, along it, stuck until the Coulomb limit μ·|normal force| — past it the rod slides
/// (σ moves); while it slides, each step's σ starts ahead by the thread's travel at its last
/// relative speed (`slip`), so a steady pull meets the friction limit, not that plus the spring
/// dragged a step's travel — and a thread that stops predicts no travel.
/// Invariants: w ≥ 0, Σw = 1, node are a tetrahedron's; 0 ≤ sigma ≤ the rod's segments;
/// stiffness > 0. No padding (copied and hashed as bytes).
struct RodPuncture {
  double w[4] = {0, 0, 0, 0};
  double sigma = 0;
  double stiffness = 0;  ///< N/m: the tissue body's needle-track spring (track_stiffness × spacing)
  double slip = 0;       ///< σ the next step starts ahead by (the last one's travel; 0: stuck)
  int32_t node[4] = {0, 0, 0, 0};
  int32_t rod = 0;   ///< index into FemModel::rods
  int32_t body = 0;  ///< the tissue body it is in
};
static_assert(sizeof(RodPuncture) == 80, "RodPuncture has padding");

/// The slots of one anchor: the upper triangle of its 5×5 node pairs.
inline constexpr int kRodAnchorSlots = 15;

/// A solid round rod of diameter d and Young's modulus E: its axial rigidity E·A (N, A = π d²/4)
/// and flexural rigidity E·I (N·m², I = π d⁴/64). A thread's `bending_stiffness` (a braid's E·I)
/// is at most the solid's (the loader's check).
inline double rod_axial_rigidity(double young_modulus, double diameter) {
  const double pi = 3.14159265358979323846;
  return young_modulus * pi * diameter * diameter / 4.0;
}
inline double rod_solid_flexural_rigidity(double young_modulus, double diameter) {
  const double pi = 3.14159265358979323846;
  return young_modulus * pi * std::pow(diameter, 4) / 64.0;
}

/// The flexural rigidity a thread bends with: its `bending_stiffness` (a braid's E·I) when given
/// (> 0), else the solid rod's.
inline double rod_flexural_rigidity(double young_modulus, double diameter, double bending_stiffness) {
  return bending_stiffness > 0 ? bending_stiffness : rod_solid_flexural_rigidity(young_modulus, diameter);
}

/// The stiffnesses of a rod's segments of length ℓ: stretching k_s = E·A/ℓ (the solid's E·A),
/// bending k_b = E·I/ℓ³ for the flexural rigidity E·I passed in (rod_flexural_rigidity's).
inline double rod_stretch_stiffness(double young_modulus, double diameter, double segment_length) {
  return rod_axial_rigidity(young_modulus, diameter) / segment_length;
}
inline double rod_bend_stiffness(double flexural_rigidity, double segment_length) {
  return flexural_rigidity / std::pow(segment_length, 3);
}

}  // namespace stroma
