#pragma once
/// \file model.hpp
/// The compiled, immutable scenario model (as MuJoCo's mjModel): the constants the tick reads,
/// typed and resolved, and the few its outputs read (name, probes, body_tets, a cut model's
/// edge state and serial) — in two parts: the scenario's constants (ModelConstants), which a
/// topology change keeps, and the part that follows the mesh's topology (ModelTopology), which
/// each cut builds anew. Built once by compile_scenario() (compiled_scenario.hpp),
/// shared read-only by every thread. The scenario text, log notes, headless tool scripts and
/// visual surfaces live beside it in CompiledScenario: the tick never reads them.

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "collision/body_contact.hpp"
#include "engine/damage_model.hpp"
#include "haptics/tool.hpp"
#include "rigid/needle_track.hpp"
#include "rigid/rigid_body.hpp"
#include "tissue/barycentric.hpp"
#include "tissue/cut_topology.hpp"
#include "tissue/fem_model.hpp"
#include "tissue/time_stepper.hpp"

namespace stroma {

/// A compiled probe: a material point embedded in one tetrahedron (global node indices).
struct ProbeModel {
  std::string name;
  int body = 0;
  BarycentricPoint where;  ///< node indices are global (DOFs of the copy holding it, once cut)
};

struct CutSupport;  // engine/cut_compile.hpp

/// What the cuts of a model's topology made (zero on an uncut model).
struct CutStats {
  int32_t elements_split = 0;   ///< tetrahedra of the uncut mesh in more than one copy
  int32_t edges_cut = 0;        ///< edges of the uncut mesh the blade crossed
  int32_t nodes_created = 0;    ///< DOFs beyond the uncut mesh's nodes (virtual nodes)
  int32_t faces_created = 0;    ///< surface triangles on cut faces (both lips)
  double cut_area = 0;          ///< m²: the wound's area (one lip's rest area)
};

/// The part of a compiled model that a topology change keeps: the scenario's constants — the
/// step's settings, the tools, the damage models, which stages the scene needs. A cut model
/// takes them whole from the model it refines (engine/cut_compile.cpp: one assignment).
///
/// Invariants (established by compile_scenario, relied on by the tick):
///  - `tools` are resolved: a tool with a shape has contact_stiffness > 0, a grasping tool has
///    grasp_stiffness > 0; workspace_min ≤ workspace_max. Their order is the scenario's and the
///    index of a ToolInput.
///  - `has_contact` ⇔ some tool has a shape, the scenario has `body_contact`, rigid bodies or
///    threads.
///  - `has_damage` ⇔ some body_damage[b] or region_damage[r] is enabled.
///  - `max_step_displacement` > 0: half the rest bounding-box diagonal of the whole scene (a cut
///    moves no rest position, so it is the cut models' too).
struct ModelConstants {
  std::string name;                ///< the scenario's name (logs, outputs, published scene)
  StepperSettings stepper;         ///< integrator and solver settings (Newton count resolved)
  double time_step = 0.001;        ///< s: the tick (and haptic) period
  /// Multirate (solver.fem_every): the tissue is stepped every fem_every ticks by fem_step =
  /// fem_every·time_step; the ticks render tools from the last step's haptic model. 1: every tick.
  int fem_every = 1;
  double fem_step = 0.001;         ///< s: the tissue's step (= time_step when fem_every is 1)
  bool haptic_secant = false;   ///< solver.haptic_model: secant (true) or hold (false, the default)
  /// solver.on_cg_cap: a tick whose CG hits its cap is redone in sub-steps (true, the default)
  /// or kept (false).
  bool substep_on_cg_cap = true;
  /// solver.time_budget: wall time one tick may take (s); 0: none (headless default). The
  /// real-time loop passes its own deadline (the period minus a margin, or this if smaller).
  double time_budget = 0;
  /// Largest node displacement one step (or sub-step) may make before it counts as diverged
  /// (half the scene's rest bounding-box diagonal).
  double max_step_displacement = 0;
  std::vector<ToolSpec> tools;            ///< resolved (see the invariants), in scenario order
  /// Rigid bodies (issue 42), in scenario order: the index of State::rigid. Free bodies are
  /// stepped after the tissue in the integrate stage (rigid/rigid_motion.hpp); they touch
  /// nothing yet.
  std::vector<RigidBodyModel> rigid_bodies;
  /// Per FEM body, how needles meet it (its material's `needle:`; rigid/needle_track.hpp).
  /// Sized to the bodies when some rigid body is a needle, else empty.
  std::vector<NeedleTissue> needle_tissue;
  bool has_needles = false;  ///< some rigid body is a needle (the track's springs and update run)
  std::vector<DamageModel> body_damage;    ///< per body (enabled = false: no damage model)
  /// Damage models of regions that have their own (`regions: [{…, damage: …}]`); which element
  /// follows which is the topology part's (ModelTopology::element_region_damage).
  std::vector<DamageModel> region_damage;
  bool has_damage = false;                ///< some body has a damage model: damage stage runs
  /// Some tool has a shape, or the scenario has body contact, rigid bodies or threads: the
  /// collide stage and BVH exist.
  bool has_contact = false;
  // Cutting (docs/CUTTING.md). A scenario with a cutting tool compiles its uncut model with
  // `cutting` set; each topology change compiles a new Model (engine/cut_compile.hpp) that the
  // runner swaps in at a tick boundary (engine/cut_swap.hpp).
  std::shared_ptr<const CutSupport> cutting;  ///< null: no tool cuts (no edge state, no scan)
};

/// The part of a compiled model that follows the mesh's topology — the FEM system and its
/// pattern, everything indexed by element, node or surface face, the collision surface, body
/// contact, probes — and which topology it is. compile_scenario builds the uncut one; each cut
/// builds a new one whole (compile_cut_model).
///
/// Invariants:
///  - `fem` is a valid FemModel (see its invariants); every index below is into its arrays.
///  - the collision arrays (triangles, slots, edges, face_elem) are parallel and non-empty only
///    when ModelConstants::has_contact.
///  - element_node_mass is sized to the elements when has_damage (empty otherwise),
///    element_face_ptr to the elements + 1 when has_contact; element_region_damage is empty or
///    sized to the elements.
/// Punctures a scene's threads may go through at once (two per bite: eight stitches).
inline constexpr int32_t kThreadPunctures = 16;

struct ModelTopology {
  FemModel fem;                    ///< all bodies in one system
  std::vector<ProbeModel> probes;
  /// Per element the region damage model it follows: an index into region_damage, or −1 for its
  /// body's. Empty: every element follows its body's. damage_of() reads either.
  std::vector<int32_t> element_region_damage;
  std::vector<double> element_node_mass;  ///< ρV/4 of each element (damage: removed at rupture)
  std::optional<BodyContactModel> body_contact;  ///< scenario `body_contact:` (none: not computed)
  /// All bodies' surfaces (outward), over surface points: the DOFs, then collision_embedded
  /// (collision/contact_surface.hpp). An uncut model has no embedded points.
  std::vector<std::array<int32_t, 3>> collision_triangles;
  std::vector<CutVertex> collision_embedded;  ///< points on element copies' edges (cut surfaces)
  /// Per embedded point, the DOF its contact forces act on: its copy edge's material end
  /// (collision/contact_surface.hpp, triangle_dofs, says why).
  std::vector<int32_t> collision_embedded_dof;
  std::vector<SurfaceTriangleDofs> collision_dofs;  ///< how each triangle acts on the DOFs (slots)
  std::vector<double> collision_edge;  ///< longest rest edge of each collision triangle
  std::vector<uint8_t> collision_cut_face;  ///< per triangle 1: a cut face (empty when uncut)
  /// The elements on either side of each collision face (−1: none). Faces of bodies without a
  /// damage model are their boundary ({−1, −1}: always active); bodies with one get every tet
  /// face, active when exactly one side is intact (a tear exposes the inner faces).
  std::vector<std::array<int32_t, 2>> collision_face_elem;
  /// The collision faces of element e (those a change of its damage level can open or close):
  /// element_face[element_face_ptr[e] .. element_face_ptr[e + 1]). An uncut tetrahedron lists its
  /// faces; a copy of a cut one, its part of the cut surface and of the faces it shares.
  std::vector<int32_t> element_face_ptr, element_face;
  std::vector<std::vector<Tet>> body_tets;  ///< per body, global node indices (for output)
  /// Needles (ModelConstants::has_needles; else empty): each element's face neighbours
  /// (tissue/tet_walk.hpp: 4 per element, −1 on the boundary) and an element of each node —
  /// where a needle's walks start.
  std::vector<int32_t> tet_neighbours, node_tet;
  /// Needles in a cut model: where each element copy's material lies (tissue/tet_walk.hpp's
  /// WalkMesh: planes element_planes[element_plane_begin[e] .. [e + 1]), none for a whole
  /// tetrahedron), so a walk ends at the cut. Empty for an uncut model or without needles.
  std::vector<int32_t> element_plane_begin;
  std::vector<std::array<double, 4>> element_planes;
  /// Needles in a cut model: each element copy's next twin (WalkMesh::next_twin: the copies of
  /// one tetrahedron in a cycle). Empty when element_plane_begin is.
  std::vector<int32_t> element_next_twin;
  /// The tissue's positions at t = 0 where they are not its rest positions (a body with
  /// `prestretch`, docs/TISSUE.md: its mesh, the rest shape shrunk from it); empty: at rest.
  /// A cut model's is empty (a state is carried onto it, never started on it).
  std::vector<double> initial_x;
  /// Needles: per collision triangle, the element it is a face of (where a puncture's walk starts).
  std::vector<int32_t> collision_tri_elem;
  /// Threads' ends tied to needles' tails (docs/THREAD.md): each tick a spring of `stiffness`
  /// between the rod's node and the body's point x_c + R·arm (arm in the body frame), in the
  /// step with the body's rows (collide stage; engine/thread_attach.hpp).
  /// Invariants: node is a rod's node; body indexes rigid_bodies; stiffness > 0.
  struct ThreadTie {
    int32_t node = 0;
    int32_t body = 0;
    Vec3 arm{0, 0, 0};
    double stiffness = 0;
  };
  std::vector<ThreadTie> thread_ties;
  /// Most punctures threads go through at once (State::punctures' size): kThreadPunctures when
  /// a thread is tied to a needle, else 0.
  int32_t puncture_capacity = 0;

  std::shared_ptr<const CutTopology> topology;  ///< this model's topology (the uncut one's too)
  int32_t topology_version = 0;  ///< 0: uncut; +1 per swapped-in cut model
  /// Per edge of the uncut mesh, the two DOFs whose positions the blade tests it at (the edge's
  /// nodes when uncut; a copy holding the edge as material once cut).
  std::vector<std::array<int32_t, 2>> cut_edge_dofs;
  CutStats cut_stats;
  /// A cut model: the per-edge cut state it was built from (its topology's input; the publisher
  /// re-maps visual surfaces with it). Empty on an uncut model.
  std::vector<double> cut_edge_state;
  /// A cut model's serial, unique in the process (0: a scenario's uncut model). A state frame
  /// names the model whose layout it has by this (CutModelRegistry), since topology versions
  /// start again after a Reset.
  uint64_t cut_serial = 0;
};

/// The compiled scenario model: the constants a topology change keeps and the part it replaces.
/// Fields are read as one (m.tools, m.fem); constants() and topology_part() name the halves.
/// Invariants: those of both parts, and between them — `has_contact` ⇔ the collision arrays
/// are non-empty; `has_damage` ⇔ element_node_mass is sized; body_damage has one entry per
/// fem.bodies; element_region_damage indexes region_damage (engine/model_check.hpp checks
/// them after every compile and cut compile in checked builds).
struct Model : ModelConstants, ModelTopology {
  ModelConstants& constants() { return *this; }
  const ModelConstants& constants() const { return *this; }
  ModelTopology& topology_part() { return *this; }
  const ModelTopology& topology_part() const { return *this; }
};

/// The damage model element e of body b follows (its region's, or its body's).
inline const DamageModel& damage_of(const Model& m, size_t b, int32_t e) {
  if (m.element_region_damage.empty() || m.element_region_damage[e] < 0) return m.body_damage[b];
  return m.region_damage[m.element_region_damage[e]];
}

/// Whether any element of body b has a damage model (its faces inside can tear).
inline bool body_can_tear(const Model& m, size_t b) {
  if (b < m.body_damage.size() && m.body_damage[b].enabled) return true;
  if (m.element_region_damage.empty()) return false;
  for (int32_t e = m.fem.bodies[b].element_begin; e < m.fem.bodies[b].element_end; ++e)
    if (m.element_region_damage[e] >= 0 && m.region_damage[m.element_region_damage[e]].enabled) return true;
  return false;
}


}  // namespace stroma
