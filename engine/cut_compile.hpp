#pragma once
/// \file cut_compile.hpp
/// Compiling cut models: a scenario with a cutting tool keeps what every cut needs of its uncut
/// model (CutSupport), and each new topology becomes a whole new Model — FEM, collision surface
/// over the cut, body contact, probes, damage arrays — built off the physics thread
/// (docs/CUTTING.md, docs/ARCHITECTURE.md "Cutting").

#include <memory>
#include <vector>

#include "engine/model.hpp"
#include "tissue/cut_model.hpp"

namespace stroma {

/// What cutting keeps of a scenario's uncut model: every cut model is compiled from it.
/// Invariants: `uncut` is the scenario's FemModel; base and uncut_topology are of its mesh;
/// probes are the uncut model's.
struct CutSupport {
  FemModel uncut;
  CutBase base;
  std::shared_ptr<const CutTopology> uncut_topology;
  std::vector<ProbeModel> probes;
  /// Σ|e| / (2V) over the uncut mesh (1/m): how many edges a unit of cut area crosses on
  /// average (a plane of random orientation crosses an edge of length |e| with probability
  /// |e|/2 per unit of its offset). The cut area of one tick is estimated from the edges it
  /// cut: ΔA ≈ n / this (the exact area follows from the topology once it is rebuilt).
  double edges_per_area = 0;
  /// Some body can tear (a damage model and contact): cut topologies list their internal faces,
  /// which become collision faces that a rupture opens, as the uncut model's tet faces do.
  bool internal_faces = false;
  /// The uncut model's Model::element_region_damage (per tetrahedron; empty: none).
  std::vector<int32_t> element_region_damage;
};

/// Sets up cutting on a freshly compiled uncut model (compile_scenario calls it when a tool
/// cuts): m.cutting, m.topology (uncut), m.cut_edge_dofs.
void enable_cutting(Model& m);

/// The Model of `current`'s scenario cut to `topo` (built from edge_cut by build_cut_topology),
/// as version `version`: current's ModelConstants whole, and a ModelTopology built for `topo`.
/// Throws std::invalid_argument if the topology does not fit the scenario's mesh.
std::shared_ptr<Model> compile_cut_model(const Model& current, std::shared_ptr<const CutTopology> topo,
                                         const std::vector<double>& edge_cut, int32_t version);

}  // namespace stroma
