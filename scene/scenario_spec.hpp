#pragma once
/// \file scenario_spec.hpp
/// ScenarioSpec: the plain-data form of a scenario YAML file, after parsing and validation but
/// before compilation. Every field has the default a scenario gets when the key is absent.
/// Paths are already resolved (absolute or relative to the working directory), so the spec can
/// be compiled without knowing where the YAML file was.

#include <optional>
#include <string>
#include <vector>

#include "engine/damage_model.hpp"
#include "haptics/tool.hpp"
#include "tissue/options.hpp"
#include "tissue/tet_mesh.hpp"
#include "tissue/viscoelastic.hpp"

namespace stroma {

/// Where a value came from in the scenario file, for error messages raised after parsing
/// (for example when compile finds a box that selects no node).
struct SourceLocation {
  std::string file;  ///< scenario file path
  int line = 0;      ///< 1-based line, 0 if unknown
};


/// `solver.on_cg_cap:` what a tick whose CG stopped at its iteration cap does.
enum class CapPolicy {
  /// The default: `continue` where the energy guard applies (every model without QR-rotation
  /// bodies, implicit Euler), `substep` otherwise (resolved_cap_policy).
  Auto,
  Substep,  ///< redo the tick in sub-steps (2, 4, … 16; the last level keeps its capped solve)
  Continue  ///< keep the capped step; the energy guard takes out any energy it gained
};

/// `solver:` section.
struct SolverSpec {
  Integrator integrator = Integrator::ImplicitEuler;
  LinearSolverKind linear_solver = LinearSolverKind::CG;
  /// Empty: `auto` (the default) — the engine chooses at load from trial steps of the scene
  /// (tissue/solver_choice.hpp); a value: the scenario's choice, never overridden.
  std::optional<Preconditioner> preconditioner;
  int max_iterations = 200;       ///< CG iteration cap per solve (also Newton cap for static)
  double tolerance = 1.0e-6;      ///< CG relative residual ‖r‖/‖b‖
  WarmStart warm_start = WarmStart::Extrapolate;  ///< CG initial guess (off | previous | extrapolate)
  double static_tolerance = 1.0e-8;   ///< static: Newton stops when ‖residual‖ ≤ this·‖f_ext‖
  int static_max_newton = 50;     ///< static: Newton iteration cap
  /// `on_cg_cap:` (CapPolicy). `auto` (the default) keeps a capped step wherever the energy
  /// guard checks it (a capped iterate is stable: the guard takes out any energy it gained), so
  /// a stable capped step is never redone in sub-steps; sub-steps still run for steps that are
  /// unstable (non-finite, or a node moving more than max_step_displacement) and, for models with
  /// QR-rotation bodies (no guard), for capped steps. `substep` redoes every capped tick in 2,
  /// 4, … 16 sub-steps (better conditioned, up to 16× the cost: it un-inverts elements faster on
  /// inverted meshes, docs/STABILITY.md); `continue` keeps every capped step. Served ticks are
  /// budgeted either way: the ladder stops at the deadline.
  CapPolicy on_cg_cap = CapPolicy::Auto;
  /// Implicit Euler: Newton iterations per tick (1: the linearised step alone). More
  /// re-linearise at the iterate, with a backtracking line search on the step's incremental
  /// potential, until ‖residual‖ ≤ newton_tolerance × the step's scale: for large steps on
  /// soft, near-incompressible or badly shaped meshes, where one linearisation adds energy.
  /// 0 = `auto` (the default): kAutoNewtonLargeStep iterations when time_step > 1 ms, else 1
  /// (see resolved_newton_iterations; docs/STABILITY.md has the data behind the choice).
  int newton_iterations = 0;
  double newton_tolerance = 1.0e-3;
  /// Wall-time budget of one tick in seconds (0 = `none`, the default headless): the linear
  /// solve, Newton iterations, contact-release passes and the sub-step ladder all stop at it and
  /// the tick degrades stably (engine/step_with_recovery.hpp). `stroma serve` budgets every tick
  /// with the period minus --budget-margin-ms, or with this when it is smaller.
  double time_budget = 0;
  /// `preconditioner_refresh:` (warped_cholesky with implicit Euler): refresh the factor from a
  /// recent step's system on a worker thread every N steps, and sooner when a solve shows the
  /// factor no longer fits (TimeStepper::solve). -1 = `auto` (the default): every
  /// auto_refresh_period() steps (tissue/solver_costs.hpp: re-evaluated as the ticks go);
  /// 0 = `off` (the rest-pose factor).
  int preconditioner_refresh = -1;
  /// `stiffness_every: N` (implicit Euler): the elements' stiffness blocks are made every N
  /// steps and the steps between solve with them (StepperSettings::stiffness_every). 1 (the
  /// default): every step.
  int stiffness_every = 1;
  /// `fem_every: N` (multirate, issue 14 §7): the tissue is stepped every N ticks with a step of
  /// N·time_step; the ticks in between (the haptic rate, 1/time_step) render each tool's force
  /// from the last finished step's local model (engine/haptic_model.hpp). 1 (the default): every
  /// tick steps the tissue.
  int fem_every = 1;
  /// `haptic_model:` what the ticks between tissue steps render: `hold` (the default) — the
  /// last finished step's force; `secant` — that force plus the stiffness the last steps
  /// measured along the contact normal times the tool's motion since (engine/multirate.hpp).
  bool haptic_secant = false;
  SourceLocation fem_every_where;    ///< the `fem_every:` key (file only when absent)
  SourceLocation time_budget_where;  ///< the `time_budget:` key (file only when absent)
  SourceLocation where;             ///< the `solver:` section (file only when absent)
  SourceLocation integrator_where;  ///< the `integrator:` key (file only when absent)
};

/// `on_cg_cap: auto` resolved for a model: substep unless the energy guard checks capped steps
/// (implicit Euler on a model without QR-rotation bodies: `guard_applies`).
inline bool resolved_substep_on_cg_cap(CapPolicy p, Integrator integrator, bool guard_applies) {
  if (p != CapPolicy::Auto) return p == CapPolicy::Substep;
  return !(integrator == Integrator::ImplicitEuler && guard_applies);
}

/// Newton iterations `newton_iterations: auto` gives steps longer than 1 ms. In the stability
/// suite (docs/STABILITY.md) 4 iterations at 5–33 ms pass 48 cases the single linearised step
/// fails (its energy gains; stable-Neo-Hookean elements that could not un-invert) and fail 5 it
/// passes (corotational, initially inverted, ν = 0.49: 4–7 elements settle inverted); at ≤ 1 ms
/// they change 6 of 150 cases (4 fixed, 2 failed) for ~1.35× per tick: the 1 kHz loop keeps 1.
inline constexpr int kAutoNewtonLargeStep = 4;

/// The Newton iterations a solver section asks for at this time step (resolves `auto`).
inline int resolved_newton_iterations(int newton_iterations, double time_step) {
  if (newton_iterations > 0) return newton_iterations;
  return time_step > 1.0e-3 * (1 + 1e-9) ? kAutoNewtonLargeStep : 1;
}

/// `material.damage:` section (engine/damage_model.hpp): the compiled model's type, as parsed.
using DamageSpec = DamageModel;

/// `material:` section of a body.
/// `fibres:` of a material: one family of exponential (Holzapfel–Gasser–Ogden) fibres on a
/// hyperelastic matrix (tissue/fibre.hpp). Invariants: k1 > 0 (Pa); 0 ≤ k2 ≤ 1e3; `direction`
/// has unit length unless `from_mesh`.
struct FibreSpec {
  Vec3 direction{1, 0, 0};  ///< rest fibre direction (normalised on load)
  bool from_mesh = false;   ///< `direction: mesh`: each tetrahedron's from the mesh's cell data
  double k1 = 0;            ///< Pa
  double k2 = 0;            ///< dimensionless
  SourceLocation where;
};

/// `viscoelastic:` of a material (tissue/viscoelastic.hpp). A Prony series (the named models
/// are one-branch series) or Kelvin–Voigt (`kelvin_voigt`: stiffness damping β = τ).
/// Invariants: 1..8 terms, g ∈ [0, 1), τ > 0, Σ g < 1 — except `maxwell`: one term, g = 1.
struct ViscoSpec {
  std::string model;           ///< prony | standard_linear_solid | maxwell | kelvin_voigt
  PronySeries series;          ///< (prony, standard_linear_solid, maxwell)
  double kelvin_voigt_tau = 0; ///< s: η/E (kelvin_voigt)
  SourceLocation where;
};

/// `locking_free:` of a material (tissue/nodal_smoothing.hpp): node-based strain smoothing
/// (`node_smoothing`) or the volumetric strain averaged over disjoint element patches
/// (`element_patches`, F-bar-patch). Invariants: 0 ≤ stabilisation ≤ 1 (1 for element_patches:
/// the deviatoric part stays on the elements); patch_elements in [2, 64] for element_patches,
/// 0 for node_smoothing; 0 ≤ element_bulk < 1 (0 for node_smoothing).
/// element_patches' defaults (docs/TISSUE.md, "Candidates"): the least patch size, and the share
/// of the bulk modulus each element keeps.
inline constexpr int kDefaultPatchElements = 16;
inline constexpr double kDefaultElementBulk = 0.02;

struct LockingFreeSpec {
  std::string method = "node_smoothing";  ///< node_smoothing | element_patches
  double stabilisation = 0.1;  ///< share of the deviatoric stiffness kept on the elements
  SourceLocation where;
  int patch_elements = 0;      ///< element_patches: a patch's least number of tetrahedra
  double element_bulk = 0;     ///< element_patches: share of the bulk modulus kept on the elements

  /// element_patches at its defaults.
  static LockingFreeSpec element_patches() {
    LockingFreeSpec l;
    l.method = "element_patches";
    l.stabilisation = 1.0;
    l.patch_elements = kDefaultPatchElements;
    l.element_bulk = kDefaultElementBulk;
    return l;
  }
};

/// `needle:` of a material (rigid/needle_track.hpp): how needles puncture, cut and slide in this
/// tissue. Invariants: puncture_force, cutting_force > 0; 0 ≤ friction_kinetic ≤ friction_static;
/// track_stiffness, track_spacing ≥ 0 (0: automatic).
struct NeedleTissueSpec {
  double puncture_force = 0;    ///< N
  double cutting_force = 0;     ///< N
  double friction_static = 0;   ///< N/m of inserted length
  double friction_kinetic = 0;  ///< N/m
  double track_stiffness = 0;   ///< N/m per m (0: 100·E)
  double track_spacing = 0;     ///< m (0: half the body's mean surface edge)
  SourceLocation where;
};

struct MaterialSpec {
  ElementModel model = ElementModel::Corotational;
  RotationMethod rotation = RotationMethod::Polar;
  double young_modulus = 0;        ///< Pa, required, > 0
  double poisson_ratio = 0;        ///< required, in (-1, 0.5)
  double density = 0;              ///< kg/m^3, required, > 0
  double rayleigh_mass = 0;        ///< α in C = αM + βK, ≥ 0
  double rayleigh_stiffness = 0;   ///< β in C = αM + βK, ≥ 0
  DamageSpec damage;
  std::optional<FibreSpec> fibres;  ///< fibre reinforcement (hyperelastic models only)
  std::optional<ViscoSpec> viscoelastic;  ///< visco-elasticity (corotational, polar, for now)
  std::optional<LockingFreeSpec> locking_free;  ///< near-incompressibility without locking
  /// `mass_lumping`: false (`volume`, the default) ρV/4 per tetrahedron node; true (`uniform`)
  /// the body's mass ΣρV shared equally by its nodes (SOFA's UniformMass).
  bool uniform_mass = false;
  std::optional<NeedleTissueSpec> needle;  ///< needles puncture it (none: they only press it)
  SourceLocation where;
};

/// An axis-aligned box in rest coordinates (inclusive bounds).
struct BoxSpec {
  Vec3 min{0, 0, 0};
  Vec3 max{0, 0, 0};
};

/// `surface:` part of a node selection: the nodes of the boundary faces whose outward normal
/// lies within `max_angle_deg` of `normal` (for example the lower face an organ rests on:
/// normal [0, -1, 0]). Invariant: `normal` has unit length; 0 < max_angle_deg ≤ 180.
struct SurfaceSelectSpec {
  Vec3 normal{0, -1, 0};
  double max_angle_deg = 45;
};

/// Selection of nodes: a box (rest positions inside), a surface (boundary nodes facing a
/// direction), both (the nodes satisfying both), or an explicit 0-based node list (alone).
struct NodeSelection {
  std::optional<BoxSpec> box;
  std::optional<SurfaceSelectSpec> surface;
  std::vector<int> nodes;
  uint8_t axes = 7;  ///< `fixed:` only: constrained axes (bit 0 x, 1 y, 2 z), default all
  SourceLocation where;
};

/// `loads:` entry: a constant force applied to the selected nodes.
/// `force` is the total force, divided equally over the selected nodes, unless `per_node` is set.
struct NodalLoadSpec {
  NodeSelection select;
  Vec3 force{0, 0, 0};  ///< N
  bool per_node = false;
};

/// `visual:` of a body: a surface mesh (OBJ or STL), usually finer than the tetrahedra, that
/// follows them through a barycentric mapping and is what renderers draw.
struct VisualSpec {
  std::string mesh_path;      ///< resolved path
  SourceLocation where;       ///< where the mesh path is in the scenario file
  /// Largest distance of a visual vertex outside the tetrahedra (projected onto the nearest
  /// one); farther is an error. 0: automatic, 5 % of the body's bounding-box diagonal.
  double max_distance = 0;
};

/// One deformable body.
/// `regions:` entry of a body: the tetrahedra of one region of its mesh (a gmsh physical group,
/// chosen by name or tag) with their own material — what it gives replaces the body's, the rest
/// is the body's. Regions of one body must not overlap.
struct RegionSpec {
  std::string name;       ///< the mesh's region name (physical name), or empty: by tag
  int32_t tag = 0;        ///< the region tag (when chosen by number)
  std::optional<double> young_modulus, poisson_ratio, density, rayleigh_stiffness;
  std::optional<DamageSpec> damage;  ///< the region's own damage thresholds
  std::optional<FibreSpec> fibres;   ///< the region's fibres (replace the body's there)
  SourceLocation where;   ///< the entry
  SourceLocation region_where;  ///< its `region:` key
};

struct BodySpec {
  std::string name;
  std::string mesh_path;   ///< resolved path of the tetrahedral mesh file
  SourceLocation mesh_where;  ///< where `mesh:` is in the scenario file
  double scale = 1.0;      ///< multiplies node coordinates as read (unit conversion)
  Vec3 translate{0, 0, 0}; ///< added to the coordinates after scaling (placing a body)
  /// The mesh's stretch over the body's rest shape along x, y, z (docs/TISSUE.md, "Prestretch"):
  /// the mesh is the tissue as it is, under tension (> 1) or compression (< 1); its rest shape
  /// is the mesh shrunk by 1/s about the body's centroid. {1, 1, 1}: the mesh is at rest.
  Vec3 prestretch{1, 1, 1};
  MaterialSpec material;
  std::vector<NodeSelection> fixed;
  std::vector<NodalLoadSpec> loads;
  std::vector<RegionSpec> regions;   ///< materials of regions of the mesh (heterogeneous tissue)
  std::optional<VisualSpec> visual;  ///< scaled by `scale` like the tetrahedra
  SourceLocation where;
};

/// A point of a body whose displacement is reported (metrics, summary, checks).
struct ProbeSpec {
  std::string name;
  std::string body;
  Vec3 point{0, 0, 0};  ///< rest (material) coordinates
  SourceLocation where;
};

/// `tools:` entry: a tool with its limits (ToolSpec) and where it is in the file.
struct ToolEntry {
  ToolSpec spec;
  std::string script;  ///< trajectory file (YAML or CSV) driving it in headless runs; may be empty
  bool has_pose = false;  ///< `pose:` given (else the rest pose is the script's first keyframe)
  SourceLocation where;
};

/// `run:` section: how long a headless run lasts. Exactly one of duration/steps is used;
/// steps wins when both are given (the loader rejects giving both).
struct RunSpec {
  std::optional<double> duration;  ///< s of simulated time
  std::optional<long> steps;
};

/// `check:` section: tolerances for `stroma check` against a stored reference state.
struct CheckSpec {
  double max_error = 1.0e-9;   ///< m: largest nodal position difference allowed
  double mean_error = 1.0e-10; ///< m: mean nodal position difference allowed
};

/// What the tissue colour shows in rendered frames.
enum class ColorFieldSpec { None, Stress, Damage };

/// `render:` section: how renderers show the scenario (a renderer's options override it).
struct RenderSpec {
  bool has_camera = false;              ///< position/target given; else frame the bounding box
  Vec3 camera_position{0, 0, 0}, camera_target{0, 0, 0};
  std::optional<Vec3> camera_up;        ///< default: against gravity (or +y without gravity)
  Vec3 view_direction{0.35, -0.45, -1.0};  ///< automatic camera: looking along this
  double fov_deg = 35;                  ///< vertical field of view
  Vec3 light_direction{0, 0, 0};        ///< key light, world; zero: above-left of the camera
  Vec3 tissue_color{0.66, 0.26, 0.22};  ///< sRGB 0..1
  Vec3 background_color{0.20, 0.23, 0.28};
  ColorFieldSpec color_field = ColorFieldSpec::Damage;
  double color_min = 0, color_max = 0;  ///< max <= min: automatic
  bool wireframe = false;
  bool contacts = true;                 ///< contact markers
};

/// `body_contact:` section: frictionless penalty contact between different bodies (each
/// body's surface vertices against the other bodies' surface triangles). Absent: no body–body
/// contact and no cost.
struct BodyContactSpec {
  double stiffness = 0;  ///< Pa/m: pressure per metre of penetration; 0: automatic (10·E_max / mean surface edge)
  double max_depth = 0;  ///< m: deepest penetration resolved; 0: automatic, per body (¼ of its
                         ///< smallest extent)
  SourceLocation where;
};

/// `rigid_bodies:` entry (issue 42; docs/RIGID.md): a rigid body of a shape at a uniform
/// density, posed and moving, or fixed. Invariants after load: density > 0 and the shape's
/// dimensions > 0 (capsule length ≥ 0); the orientation a unit quaternion (w, x, y, z); a mesh
/// path resolved (its closedness is checked when compiled, where the file is read).
enum class RigidShapeKind { Sphere, Box, Capsule, Mesh, Needle };
struct RigidBodySpec {
  std::string name;
  RigidShapeKind shape = RigidShapeKind::Sphere;
  double radius = 0;         ///< sphere, capsule (m)
  double length = 0;         ///< capsule: its cylinder's length along the body's z (m)
  Vec3 size{0, 0, 0};        ///< box: full side lengths (m)
  std::string mesh_path;     ///< mesh: a closed surface (.obj .stl .off .ply), in the body's frame
  double mesh_scale = 1;     ///< mesh: multiplies its coordinates
  double wire_radius = 0;    ///< needle: its wire's radius (m); `length` straight, `radius` + `angle` curved
  double angle_deg = 0;      ///< needle: a curved one's arc (degrees; 135 is a 3/8 circle)
  double density = 0;        ///< kg/m³
  Vec3 position{0, 0, 0};    ///< where the shape's frame origin is, world (m)
  std::array<double, 4> orientation{1, 0, 0, 0};  ///< the shape's frame → world, unit (w, x, y, z)
  Vec3 velocity{0, 0, 0};          ///< of the centre of mass, world (m/s)
  Vec3 angular_velocity{0, 0, 0};  ///< world (rad/s)
  bool fixed = false;        ///< does not move (an obstacle, a table)
  /// Contact (rigid/rigid_contact.hpp): Pa/m (0: automatic, 100·E_max / the shape's smallest
  /// feature, as a tool's), Pa·s/m, and the Coulomb coefficient.
  double contact_stiffness = 0, contact_damping = 0, friction = 0.2;
  SourceLocation where;      ///< the entry
  SourceLocation shape_where;
};

/// `threads:` entry (issue 43; docs/THREAD.md): a suture thread, a rod of `segments` equal
/// segments (tissue/rod.hpp), straight from `start` along `direction` or along the polyline
/// `path` (its nodes at equal arc length on it). Invariants after load: segments ≥ 2; length,
/// diameter, young_modulus and density > 0; bending_stiffness 0 (the solid rod's) or in
/// (0, E·π·d⁴/64]; the bending over the stretching stiffness, EI/(EA·ℓ²), at least that of a
/// solid rod whose segments are kThreadMaxSegmentRatio diameters long; direction a unit vector;
/// a path's length within 1e-6 of `length`.
inline constexpr double kThreadMaxSegmentRatio = 100;
struct ThreadSpec {
  std::string name;
  double length = 0;         ///< m, unstretched
  int segments = 0;          ///< ≥ 2
  double diameter = 0;       ///< m
  double young_modulus = 0;  ///< Pa
  double density = 0;        ///< kg/m³
  /// N·m²: the thread's flexural rigidity E·I; 0: a solid (monofilament) rod's, E·π·d⁴/64. A
  /// braid bends by its filaments (they slide on each other): about the solid's × its fill
  /// fraction over its filament count (docs/THREAD.md, "The model").
  double bending_stiffness = 0;
  Vec3 start{0, 0, 0};       ///< the first node (world, m)
  Vec3 direction{1, 0, 0};   ///< unit: straight from start along it (when no path)
  std::vector<Vec3> path;    ///< ≥ 2 points, its length = `length`; empty: straight
  double rayleigh_mass = 0, rayleigh_stiffness = 0;
  double friction = 0.2;     ///< Coulomb coefficient on tissue (punctures, contact) and other bodies
  /// Pa/m: pressure on the tissue per metre of penetration (0: automatic, 10·E_max/diameter).
  double contact_stiffness = 0;
  bool fix_first = false, fix_last = false;  ///< `fixed: [first, last]`: those nodes do not move
  /// `attach:` entries: an end tied to a needle's tail (it follows the needle) or to the tissue
  /// body it lies in or on (an anchor knot). Invariants after load: each end at most once, never
  /// also fixed; the target names a needle (rigid body of shape needle) or a tissue body.
  struct Attach {
    bool last = false;      ///< the thread's last node (else its first)
    bool needle = false;    ///< to a needle's tail (else to a tissue body)
    std::string target;     ///< the needle's or the tissue body's name
    SourceLocation where;
  };
  std::vector<Attach> attach;
  /// No start, direction or path: the thread leaves its needle's tail straight backwards (only
  /// when its first end is attached to a needle).
  bool from_needle = false;
  SourceLocation where;
};

/// A whole scenario. Invariants after load_scenario(): time_step > 0; at least one body; names
/// of bodies, probes and tools unique; paths resolved; every SourceLocation names the line it
/// came from (0 when the key was absent).
struct ScenarioSpec {
  std::string name;
  std::string file;        ///< the scenario file it was read from
  double time_step = 0.001;
  Vec3 gravity{0, -9.81, 0};
  SolverSpec solver;
  std::vector<BodySpec> bodies;
  std::vector<ProbeSpec> probes;
  std::vector<ToolEntry> tools;
  std::vector<RigidBodySpec> rigid_bodies;
  std::vector<ThreadSpec> threads;
  std::optional<BodyContactSpec> body_contact;
  RunSpec run;
  CheckSpec check;
  RenderSpec render;
};

/// Reads and validates a scenario YAML file. Paths inside are resolved relative to the file.
/// Throws InputError with file, line and field on any problem: unknown key, wrong type,
/// missing required field, value out of range (ν ≥ 0.5, E ≤ 0, ...), duplicate names, probes
/// naming unknown bodies. Mesh files are not opened here (compile does that).
ScenarioSpec load_scenario(const std::string& path);

/// Same, from YAML text; `file` is used in messages and `base_dir` to resolve relative paths.
ScenarioSpec parse_scenario(const std::string& yaml_text, const std::string& file,
                            const std::string& base_dir);

}  // namespace stroma
