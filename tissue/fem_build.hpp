#pragma once
/// \file fem_build.hpp
/// Compiles prepared meshes, materials, constraints and loads into a FemModel.

#include <vector>

#include "tissue/fem_model.hpp"
#include "tissue/mesh_prepare.hpp"

namespace stroma {

/// Everything the FEM needs to know about one body, already validated.
/// A material for one element (a region's, overriding its body's).
struct ElementMaterial {
  double young_modulus = 0, poisson_ratio = 0, density = 0, rayleigh_stiffness = 0;
};

struct FemBodyInput {
  std::string name;
  const PreparedMesh* mesh = nullptr;   ///< node positions in metres
  ElementModel model = ElementModel::Corotational;
  RotationMethod rotation = RotationMethod::Polar;
  double young_modulus = 0, poisson_ratio = 0, density = 0;
  double rayleigh_mass = 0, rayleigh_stiffness = 0;
  /// Fixed DOFs: local (file-order) node index and axis mask (bit 0 x, 1 y, 2 z; 7 = all).
  std::vector<std::pair<int32_t, uint8_t>> fixed;
  std::vector<std::pair<int32_t, Vec3>> nodal_forces;  ///< local node, force (N)
  /// Per tetrahedron (file order) its own material, or empty: the body's for all. Regions of a
  /// heterogeneous body (a tumour in a liver) set it.
  std::vector<ElementMaterial> element_material;
  /// Per tetrahedron (file order) its fibres (fibre.hpp), or empty: no fibres in this body.
  /// Only the hyperelastic models (stable Neo-Hookean, St. Venant–Kirchhoff) take fibres.
  std::vector<FibreParams> element_fibres;
  /// Visco-elastic: the body's Prony series (terms = 0: elastic). Corotational polar only.
  PronySeries visco;
  /// Locking-free node smoothing (nodal_smoothing.hpp): the share of the deviatoric stiffness
  /// kept on the elements, in [0, 1]; negative: off (plain elements).
  double locking_free_share = -1;
  /// Locking-free: 0, node domains; ≥ 2, domains are disjoint patches of at least this many
  /// tetrahedra (element_patches, nodal_smoothing.hpp).
  int locking_free_patch = 0;
  /// Locking-free: the share of the bulk modulus kept on the elements, in [0, 1).
  double locking_free_bulk = 0;
  /// Mass lumping: false, each tetrahedron gives ρV/4 to each of its nodes; true, the body's
  /// mass Σ ρV is shared equally by the nodes its tetrahedra use (SOFA's UniformMass).
  bool uniform_mass = false;
};

/// A rod (a suture thread, rod.hpp), already validated: its nodes in order along it (at least
/// three), which are both its rest and its initial positions, with segments of equal rest length.
struct FemRodInput {
  std::string name;
  std::vector<Vec3> nodes;              ///< positions in metres, ≥ 3
  double segment_length = 0;            ///< rest length of every segment (m)
  double young_modulus = 0, diameter = 0, density = 0;
  double bending_stiffness = 0;  ///< N·m², E·I; 0: the solid rod's, E·π·d⁴/64
  double rayleigh_mass = 0, rayleigh_stiffness = 0;
  double friction = 0;  ///< Coulomb coefficient at punctures and in contact
  double contact_stiffness = 0;  ///< Pa/m against the tissue (engine/thread_contact.hpp)
  /// Fixed DOFs: local node index (0 = the first) and axis mask (7 = all).
  std::vector<std::pair<int32_t, uint8_t>> fixed;
  std::vector<std::pair<int32_t, Vec3>> nodal_forces;  ///< local node, force (N)
  /// Anchors (rod.hpp, RodAnchor): `node` local to the rod, `tissue` global node indices.
  std::vector<RodAnchor> anchors;
};

/// Builds the global model: bodies are concatenated (node and element offsets in order).
/// Lumped mass: each tetrahedron gives ρV/4 to each of its nodes (or, for a body with
/// uniform_mass, the body's mass is shared equally by its used nodes). Gravity enters f_ext as m·g.
/// `smoothing_matrix_free`: locking-free bodies' node domains are applied by NodalSystem
/// instead of assembled (nodal_smoothing.hpp; for CG solves — CHOLMOD needs the matrix).
/// Rods follow the bodies' nodes, in order: each node gets ρ·A·ℓ/2 from each of its segments.
FemModel build_fem_model(const std::vector<FemBodyInput>& bodies, const Vec3& gravity,
                         bool smoothing_matrix_free = false, const std::vector<FemRodInput>& rods = {});

/// The derived parts of a model whose nodes, elements, ranges, masses, constraints and loads are
/// set (`all_tets`: each element's nodes): inverse masses, the constrained-node list, the BSR
/// pattern with the element slots and constrained off-diagonal blocks, node → element lists,
/// and whether any element has stiffness damping. build_fem_model ends with it; a cut model
/// (cut_model.hpp) is finished by it too.
void finish_fem_model(FemModel& m, const std::vector<Tet>& all_tets);

}  // namespace stroma
