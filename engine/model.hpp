#pragma once
/// \file model.hpp
/// The compiled, immutable scenario model (as MuJoCo's mjModel): everything that does not
/// change while the simulation runs. Built once by compile_model(); shared read-only.

#include <memory>
#include <string>
#include <optional>
#include <vector>

#include "engine/scenario_spec.hpp"
#include "collision/body_contact.hpp"
#include "engine/trajectory.hpp"
#include "tissue/barycentric.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/visual_mapping.hpp"
#include "tissue/time_stepper.hpp"

namespace stroma {

/// A compiled probe: a material point embedded in one tetrahedron (global node indices).
struct ProbeModel {
  std::string name;
  int body = 0;
  BarycentricPoint where;  ///< node indices are global
};

/// A compiled scenario.
/// A body's visual surface (scenario `visual:`): drawn instead of the tetrahedra's boundary,
/// following them through a fixed barycentric mapping (tissue/visual_mapping.hpp).
struct VisualModel {
  std::string source;                  ///< the mesh file
  std::vector<Vec3> rest;              ///< vertex rest positions (scaled like the body)
  std::vector<uint32_t> triangles;     ///< 3 per triangle, into `rest`
  VisualMapping mapping;               ///< vertex = Σ w · x(node), global node indices
};

struct Model {
  ScenarioSpec spec;               ///< the validated scenario it was compiled from
  FemModel fem;                    ///< all bodies in one system
  StepperSettings stepper;         ///< integrator and solver settings
  double time_step = 0.001;        ///< s
  std::vector<ProbeModel> probes;
  std::vector<ToolSpec> tools;            ///< the scenario's tools, in order
  std::vector<Trajectory> tool_scripts;   ///< per tool; empty keys when it has no script
  std::vector<DamageSpec> body_damage;    ///< per body (enabled = false: no damage model)
  bool has_damage = false;                ///< some body has a damage model: damage stage runs
  std::vector<double> element_node_mass;  ///< ρV/4 of each element (damage: removed at rupture)
  std::vector<int32_t> node_elem_ptr, node_elem;  ///< CSR: elements of each node (damage only)
  /// Some tool has a shape, or the scenario has body contact: the collide stage and BVH exist.
  bool has_contact = false;
  std::optional<BodyContactModel> body_contact;  ///< scenario `body_contact:` (none: not computed)
  std::vector<std::array<int32_t, 3>> collision_triangles;  ///< all bodies' surfaces (outward)
  std::vector<std::array<int32_t, 9>> collision_slots;      ///< BSR slots of each triangle's node pairs
  std::vector<double> collision_edge;  ///< longest rest edge of each collision triangle
  /// The elements on either side of each collision face (−1: none). Faces of bodies without a
  /// damage model are their boundary ({−1, −1}: always active); bodies with one get every tet
  /// face, active when exactly one side is intact (a tear exposes the inner faces).
  std::vector<std::array<int32_t, 2>> collision_face_elem;
  std::vector<std::array<int32_t, 4>> element_faces;  ///< collision face of each tet face (−1: none)
  // (contact sampling density: haptics/contact.hpp)
  /// Per body: its visual surface, or none (then renderers get the tetrahedra's boundary).
  std::vector<std::optional<VisualModel>> visuals;
  std::vector<std::vector<Tet>> body_tets;  ///< per body, global node indices (for output)
  std::vector<std::string> notes;  ///< load-time observations worth logging (reoriented, unused)
};

/// Loads every mesh, validates materials and selections against them, and compiles.
/// Throws InputError with the scenario file, line and field on any problem.
std::shared_ptr<const Model> compile_model(const ScenarioSpec& spec);

}  // namespace stroma
