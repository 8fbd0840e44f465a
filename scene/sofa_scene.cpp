#include "scene/sofa_scene.hpp"

#include <tinyxml2.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>

#include <fmt/format.h>

#include "io/mesh_io.hpp"
#include "tissue/input_error.hpp"
#include "tissue/mesh_prepare.hpp"

namespace stroma {

namespace {

namespace fs = std::filesystem;
using tinyxml2::XMLAttribute;
using tinyxml2::XMLElement;

// Components with no effect on what is simulated (scene loops, drawing, plugins, topology
// helpers): accepted with any attributes, and listed in the notes.
const std::set<std::string> kNoEffect = {
    "DefaultAnimationLoop", "DefaultVisualManagerLoop", "VisualStyle", "RequiredPlugin", "InteractiveCamera",
    "OglSceneFrame", "LightManager", "DirectionalLight", "PositionalLight", "SpotLight", "BackgroundSetting",
    "TetrahedronSetGeometryAlgorithms", "TetrahedronSetTopologyModifier", "TetrahedronSetTopologyAlgorithms"};
const std::set<std::string> kVolumeLoaders = {"MeshGmshLoader", "MeshVTKLoader"};
const std::set<std::string> kFem = {"TetrahedronFEMForceField", "TetrahedralCorotationalFEMForceField"};
const std::set<std::string> kMasses = {"UniformMass", "DiagonalMass", "MeshMatrixMass"};
const std::set<std::string> kFixed = {"FixedConstraint", "FixedProjectiveConstraint", "FixedPlaneProjectiveConstraint",
                                      "FixedPlaneConstraint"};
const std::set<std::string> kTopology = {"TetrahedronSetTopologyContainer", "MeshTopology"};
// SOFA's collision pipeline: what makes bodies and tools touch. Stroma's contact (tools against
// each body's boundary, a BVH and penalty springs: docs/TISSUE.md) is always on, so these carry
// no setting of Stroma's; accepted and listed in the notes (--explain).
const std::set<std::string> kCollisionPipeline = {
    "CollisionPipeline", "DefaultPipeline", "BruteForceBroadPhase", "BruteForceDetection", "BVHNarrowPhase",
    "DiscreteIntersection", "MinProximityIntersection", "NewProximityIntersection", "LocalMinDistance",
    "CollisionResponse", "DefaultContactManager", "DefaultCollisionGroupManager", "CollisionGroupManager"};
// Collision models: a body's collision surface. Stroma's is the body's boundary (its tetrahedra's
// outer faces) whatever the model's primitives (triangles, lines, points, spheres).
const std::set<std::string> kCollisionModels = {"TriangleCollisionModel", "LineCollisionModel", "PointCollisionModel",
                                                "SphereCollisionModel", "TTriangleModel", "TLineModel", "TPointModel"};
// Components outside the subset that SOFA users often write, with why they are not translated.
const std::map<std::string, std::string> kWhyNot = {
    {"RegularGridTopology", "a grid built at load is not translated: Stroma reads tetrahedral meshes from files (mesh "
                            "the box with gmsh, or a surface with `stroma mesh surface`)"},
    {"SparseGridTopology", "a grid built at load is not translated: Stroma reads tetrahedral meshes from files"},
    {"Hexa2TetraTopologicalMapping", "hexahedra split into tetrahedra at load are not translated: give the tetrahedral "
                                     "mesh as a file"},
    {"FreeMotionAnimationLoop", "constraint-based animation (Lagrange multipliers) is not modelled: Stroma's contact is "
                                "penalty-based"},
    {"GenericConstraintSolver", "constraint-based animation (Lagrange multipliers) is not modelled"},
    {"UncoupledConstraintCorrection", "constraint corrections belong to constraint-based animation, not modelled"},
    {"LinearSolverConstraintCorrection", "constraint corrections belong to constraint-based animation, not modelled"},
    {"SphereLoader", "spheres are read only as a body's collision model, in a collision child node of the body"}};
// Attributes every component may have that change nothing simulated.
const std::set<std::string> kGeneric = {"name", "printLog", "listening", "tags", "componentState", "bbox"};
// Node attributes that change nothing simulated: drawing, and `depend` (a no-op ordering hint).
const std::set<std::string> kNodeNoEffect = {"showBoundingTree", "depend", "activated"};
// Drawing-only attributes of the mechanical components.
const std::set<std::string> kDrawing = {"showObject", "showObjectScale", "showIndices", "showIndicesScale", "drawMode",
                                        "showColor", "showVectors", "drawSize", "drawBoxes", "drawTetrahedra",
                                        "showWireFrame"};

std::string join_names(const std::set<std::string>& s) {
  std::string out;
  for (const auto& n : s) out += (out.empty() ? "" : ", ") + n;
  return out;
}

/// A YAML double-quoted string (JSON escapes are YAML's).
std::string yaml_quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (static_cast<unsigned char>(c) < 0x20) {
      out += fmt::format("\\x{:02x}", static_cast<unsigned char>(c));
      continue;
    }
    out += c;
  }
  return out + "\"";
}

std::string num(double v) { return fmt::format("{}", v); }

class Translator {
 public:
  Translator(std::string file, std::string base_dir) : file_(std::move(file)), base_(std::move(base_dir)) {}

  SofaTranslation run(const std::string& xml) {
    tinyxml2::XMLDocument doc;
    if (doc.Parse(xml.data(), xml.size()) != tinyxml2::XML_SUCCESS)
      throw InputError(file_, doc.ErrorLineNum(), "", std::string("not well-formed XML: ") + doc.ErrorStr());
    const XMLElement* root = doc.RootElement();
    if (!root) throw InputError(file_, 0, "", "no root element: a SOFA scene is a <Node>");
    if (std::string(root->Name()) != "Node")
      fail(root, "", fmt::format("the root element is <{}>; a SOFA scene's root is a <Node>", root->Name()));
    allow(root, {"gravity", "dt", "showBoundingTree", "depend", "activated"});  // (bbox: generic)
    gravity_ = {0, -9.81, 0};
    if (root->Attribute("gravity")) {
      const auto g = numbers(root, "gravity");
      if (g.size() != 3) fail(root, "gravity", fmt::format("{} values; a gravity has 3 (x y z)", g.size()));
      gravity_ = {g[0], g[1], g[2]};
    } else {
      notes_.push_back(fmt::format("line {}: no gravity: SOFA's default (0, -9.81, 0)", root->GetLineNum()));
    }
    dt_ = 0.01;
    if (root->Attribute("dt")) {
      dt_ = number(root, "dt");
      if (!(dt_ > 0)) fail(root, "dt", "must be > 0");
    } else {
      notes_.push_back(fmt::format("line {}: no dt: SOFA's default 0.01 s", root->GetLineNum()));
    }
    Solvers top;
    top.gravity = gravity_;
    top.gravity_line = root->GetLineNum();
    attempt([&] { walk(root, top); });
    if (!errors_.empty()) throw combined_errors();
    if (bodies_.empty())
      fail(root, "", "no body: Stroma simulates nodes with a MechanicalObject, a tetrahedral FEM force field and a mass");
    // One gravity: the one every body's node has (a subtree's own gravity counts where a body is).
    for (const Body& b : bodies_)
      if (b.gravity != bodies_[0].gravity)
        attempt([&] {
          throw InputError(file_, b.line, fmt::format("Node[{}].gravity", b.name),
                           fmt::format("({} {} {}, from line {}) differs from body '{}''s ({} {} {}, from line {}): Stroma "
                                       "has one gravity for the scene",
                                       num(b.gravity[0]), num(b.gravity[1]), num(b.gravity[2]), b.gravity_line,
                                       bodies_[0].name, num(bodies_[0].gravity[0]), num(bodies_[0].gravity[1]),
                                       num(bodies_[0].gravity[2]), bodies_[0].gravity_line));
        });
    if (!errors_.empty()) throw combined_errors();
    if (bodies_[0].gravity != gravity_) {
      notes_.push_back(fmt::format("line {}: the bodies' gravity ({} {} {}) is their node's, not the root's ({} {} {})",
                                   bodies_[0].gravity_line, num(bodies_[0].gravity[0]), num(bodies_[0].gravity[1]),
                                   num(bodies_[0].gravity[2]), num(gravity_[0]), num(gravity_[1]), num(gravity_[2])));
      gravity_ = bodies_[0].gravity;
    }
    int colliding = 0;
    for (const Body& b : bodies_) colliding += b.collision_models > 0;
    if (colliding >= 2)
      fail(root, "", fmt::format("{} bodies have collision models: in SOFA they would collide with each other; the "
                                 "translation does not make bodies touch (Stroma's body_contact is frictionless "
                                 "penalty, not SOFA's response): remove the models, or write the scene in YAML with "
                                 "body_contact (docs/TISSUE.md)", colliding));
    return {emit(), notes_};
  }

 private:
  /// What a node inherits from its ancestors: its solvers, and its gravity (SOFA's context).
  struct Solvers {
    const XMLElement* ode = nullptr;
    const XMLElement* linear = nullptr;
    std::array<double, 3> gravity{0, 0, 0};
    int gravity_line = 0;  ///< the node whose gravity attribute set it
  };
  struct Body {
    std::string name, mesh, visual;
    int line = 0, mesh_line = 0;
    double scale = 1;
    std::array<double, 3> translate{0, 0, 0};
    std::string model, rotation;
    double young = 0, poisson = 0, density = 0, rayleigh_mass = 0, rayleigh_stiffness = 0;
    std::string mass_note;
    bool uniform_mass = false;
    std::vector<std::vector<int>> fixed_nodes;
    /// FixedPlaneProjectiveConstraint: nodes held along one axis only (0 x, 1 y, 2 z).
    std::vector<std::pair<std::vector<int>, int>> fixed_along;
    std::vector<std::array<double, 6>> fixed_boxes;
    std::vector<int> fixed_lines;
    int collision_models = 0;  ///< SOFA collision models on it (notes only: its boundary is the surface)
    /// The mesh as its loader read it (once: the mass and the volume use it again).
    std::shared_ptr<const TetMesh> tet;
    std::array<double, 3> gravity{0, 0, 0};  ///< the gravity of its node (inherited)
    int gravity_line = 0;
  };

  /// Every error of the scene, in the order found: a component's error stops that component (a
  /// body's, that body), not the scene, so one run reports them all.
  std::vector<InputError> errors_;

  template <class F>
  void attempt(F&& f) {
    try {
      f();
    } catch (const InputError& e) {
      errors_.push_back(e);
    }
  }

  /// One InputError for all of them: the first one's place, and each error on a line of its own.
  InputError combined_errors() const {
    const InputError& first = errors_.front();
    if (errors_.size() == 1) return first;
    std::string m = first.message();
    m += fmt::format("\n  ... and {} more error{} in this scene:", errors_.size() - 1, errors_.size() > 2 ? "s" : "");
    for (size_t k = 1; k < errors_.size(); ++k) m += "\n  " + std::string(errors_[k].what());
    return InputError(first.file(), first.line(), first.field(), m);
  }

  /// Each node's named components (filled as walk() reaches the node, before its subtree).
  std::map<const XMLElement*, std::map<std::string, const XMLElement*>> scopes_;

  [[noreturn]] void fail(const XMLElement* e, const std::string& attr, const std::string& what) const {
    std::string field = e->Name();
    if (const char* n = e->Attribute("name")) field += fmt::format("[{}]", n);
    if (!attr.empty()) field += "." + attr;
    throw InputError(file_, e->GetLineNum(), field, what);
  }

  /// Refuses every attribute of `e` outside `allowed` and the generic ones.
  void allow(const XMLElement* e, std::set<std::string> allowed, bool drawing = false) const {
    for (const XMLAttribute* a = e->FirstAttribute(); a; a = a->Next()) {
      const std::string n = a->Name();
      if (allowed.count(n) || kGeneric.count(n) || (drawing && kDrawing.count(n))) continue;
      for (const auto& g : kGeneric) allowed.insert(g);
      fail(e, n,
           fmt::format("attribute not supported by the importer (it would change the simulation in a way the "
                       "translation does not carry); supported here: {}",
                       join_names(allowed)));
    }
  }

  std::vector<double> numbers(const XMLElement* e, const char* attr) const {
    std::vector<double> out;
    const char* p = e->Attribute(attr);
    if (!p) return out;
    std::istringstream in(p);
    std::string tok;
    while (in >> tok) {
      errno = 0;
      char* end = nullptr;
      const double v = std::strtod(tok.c_str(), &end);
      if (end == tok.c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(v))
        fail(e, attr, fmt::format("'{}' is not a finite number", tok));
      out.push_back(v);
    }
    return out;
  }

  double number(const XMLElement* e, const char* attr) const {
    const auto v = numbers(e, attr);
    if (v.size() != 1)
      fail(e, attr, v.empty() ? "empty: one number expected"
                              : fmt::format("{} values; Stroma takes one value per body here", v.size()));
    return v[0];
  }

  bool boolean(const XMLElement* e, const char* attr, bool dflt) const {
    const char* p = e->Attribute(attr);
    if (!p) return dflt;
    const std::string s = p;
    if (s == "1" || s == "true" || s == "True") return true;
    if (s == "0" || s == "false" || s == "False") return false;
    fail(e, attr, fmt::format("'{}' is not a boolean (0, 1, false, true)", s));
  }

  /// "@name" or "@name.data" → name (the component in this node).
  std::string link_target(const XMLElement* e, const char* attr, const std::string& data = "") const {
    const std::string v = e->Attribute(attr);
    if (v.size() < 2 || v[0] != '@') fail(e, attr, fmt::format("'{}' is not a link (@name)", v));
    std::string t = v.substr(1);
    if (!data.empty()) {
      const std::string suffix = "." + data;
      if (t.size() > suffix.size() && t.compare(t.size() - suffix.size(), suffix.size(), suffix) == 0)
        t.resize(t.size() - suffix.size());
      else
        fail(e, attr, fmt::format("'{}': only a link to a loader's {} (@loader.{}) is supported", v, data, data));
    }
    return t;
  }

  std::string resolve_file(const XMLElement* e, const char* attr) const {
    const char* p = e->Attribute(attr);
    if (!p || !*p) fail(e, attr, "missing: the file to load");
    fs::path path(p);
    if (path.is_relative()) path = fs::path(base_) / path;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) fail(e, attr, fmt::format("'{}': no such file ({})", p, path.string()));
    return fs::absolute(path, ec).lexically_normal().string();
  }

  void walk(const XMLElement* node, Solvers solvers) {
    node_attributes(node, solvers);
    std::map<std::string, const XMLElement*> named;
    const XMLElement *mo = nullptr, *fem = nullptr, *mass = nullptr, *topology = nullptr;
    const XMLElement *own_ode = nullptr, *own_linear = nullptr;
    std::vector<const XMLElement*> fixed, loaders, children, collision_models;
    for (const XMLElement* e = node->FirstChildElement(); e; e = e->NextSiblingElement()) {
      if (const char* n = e->Attribute("name")) {
        if (named.count(n)) fail(e, "name", fmt::format("'{}' is already the name of a component of this node", n));
        named[n] = e;
      }
    }
    scopes_[node] = named;  // links from the subtree ("@../name") resolve here
    for (const XMLElement* e = node->FirstChildElement(); e; e = e->NextSiblingElement()) attempt([&] {
      const std::string kind = e->Name();
      auto one = [&](const XMLElement*& slot, const char* what) {
        if (slot) fail(e, "", fmt::format("a second {} in this node (line {}): one per node", what, slot->GetLineNum()));
        slot = e;
      };
      if (kind == "Node") children.push_back(e);
      else if (kNoEffect.count(kind)) notes_.push_back(fmt::format("line {}: {}: no effect on the simulation", e->GetLineNum(), kind));
      else if (kCollisionPipeline.count(kind))
        notes_.push_back(fmt::format("line {}: {}: SOFA's collision pipeline; Stroma's contact (tools against each "
                                     "body's boundary: BVH, penalty) is always on, this component's settings are not "
                                     "carried", e->GetLineNum(), kind));
      else if (kCollisionModels.count(kind)) collision_models.push_back(e);
      else if (kind == "EulerImplicitSolver") one(own_ode, "ODE solver");
      else if (kind == "CGLinearSolver" || kind == "SparseLDLSolver") one(own_linear, "linear solver");
      else if (kVolumeLoaders.count(kind) || kind == "MeshOBJLoader") loaders.push_back(e);
      else if (kTopology.count(kind)) one(topology, "topology");
      else if (kind == "MechanicalObject") one(mo, "MechanicalObject");
      else if (kFem.count(kind)) one(fem, "FEM force field");
      else if (kMasses.count(kind)) one(mass, "mass");
      else if (kFixed.count(kind)) fixed.push_back(e);
      else if (kind == "BoxROI" || kind == "OglModel" || kind == "BarycentricMapping") {
        // A BoxROI is read where a constraint links it; OglModel and BarycentricMapping belong
        // in a visual child node (an OglModel here is refused there: it needs a mapping).
        if (kind != "BoxROI")
          fail(e, "", "a visual surface goes in a child node of its body: MeshOBJLoader, OglModel and BarycentricMapping");
      } else {
        const auto why = kWhyNot.find(kind);
        fail(e, "",
             fmt::format("component not supported by the SOFA importer{}. Supported: Node, {}, {}, "
                         "MechanicalObject, {}, {}, EulerImplicitSolver, CGLinearSolver, SparseLDLSolver, {}, BoxROI, "
                         "MeshOBJLoader + OglModel + BarycentricMapping (a visual child node), and with no effect on "
                         "the simulation: {}",
                         why == kWhyNot.end() ? std::string() : ": " + why->second, join_names(kVolumeLoaders), join_names(kTopology), join_names(kFem), join_names(kMasses),
                         join_names(kFixed), join_names(kNoEffect)));
      }
    });
    // A node's solvers act on its whole subtree, wherever they stand among its children.
    if (own_ode) solvers.ode = own_ode;
    if (own_linear) solvers.linear = own_linear;
    if (mo) {
      attempt([&] { body(node, mo, fem, mass, topology, fixed, loaders, named, solvers, children, collision_models); });
    } else {
      for (const XMLElement* e : {fem, mass, topology})
        if (e) attempt([&] { fail(e, "", "no MechanicalObject in this node: it has nothing to act on"); });
      if (!collision_models.empty())
        attempt([&] {
          fail(collision_models[0], "", "a collision model of no body (no MechanicalObject in this node): an obstacle "
                                        "that is not a Stroma body is not translated");
        });
      if (!fixed.empty()) attempt([&] { fail(fixed[0], "", "no MechanicalObject in this node: it has nothing to act on"); });
      for (const XMLElement* c : children)
        attempt([&] {
          if (!is_visual_node(c)) walk(c, solvers);
          else fail(c, "", "a visual node (OglModel + BarycentricMapping) needs a body in its parent node");
        });
    }
  }

  /// A node's attributes: the root's gravity and dt (read in run()), a child's gravity (SOFA
  /// gives a subtree its own; it is inherited into `ctx`, and run() checks that every body has
  /// the same: Stroma has one), drawing and `depend`.
  void node_attributes(const XMLElement* node, Solvers& ctx) {
    const bool root = node->Parent() == node->GetDocument();
    std::set<std::string> ok = kNodeNoEffect;
    ok.insert("gravity");
    if (root) ok.insert("dt");
    allow(node, ok);
    if (!root && node->Attribute("gravity")) {
      const auto g = numbers(node, "gravity");
      if (g.size() != 3) fail(node, "gravity", fmt::format("{} values; a gravity has 3 (x y z)", g.size()));
      ctx.gravity = {g[0], g[1], g[2]};
      ctx.gravity_line = node->GetLineNum();
    }
    for (const char* a : {"showBoundingTree", "depend"})
      if (node->Attribute(a))
        notes_.push_back(fmt::format("line {}: Node {}: no effect on the simulation", node->GetLineNum(), a));
  }

  /// A child node that only holds a collision model of its parent's body (a loader, a
  /// MechanicalObject, the model, a mapping): SOFA's usual "Surf" node.
  static bool is_collision_node(const XMLElement* n) {
    bool model = false;
    for (const XMLElement* e = n->FirstChildElement(); e; e = e->NextSiblingElement()) {
      const std::string k = e->Name();
      if (kCollisionModels.count(k)) model = true;
      else if (k != "SphereLoader" && k != "MeshOBJLoader" && k != "MeshTopology" && k != "MechanicalObject" &&
               k != "BarycentricMapping" && k != "IdentityMapping" && k != "RequiredPlugin" && k != "Node")
        return false;
    }
    return model;
  }

  static bool is_visual_node(const XMLElement* n) {
    for (const XMLElement* e = n->FirstChildElement(); e; e = e->NextSiblingElement())
      if (std::string(e->Name()) == "OglModel") return true;
    return false;
  }

  /// The component a link names: "name" in `from`'s node (`named`), "../name" in its parent node,
  /// "../../name" in the grandparent (SOFA's relative paths), each as the scene declares it.
  const XMLElement* named_in(const std::map<std::string, const XMLElement*>& named, const XMLElement* from,
                             const char* attr, const std::string& target) const {
    std::string t = target;
    const std::map<std::string, const XMLElement*>* scope = &named;
    const tinyxml2::XMLNode* node = from->Parent();
    int up = 0;
    while (t.rfind("../", 0) == 0) {
      t = t.substr(3);
      ++up;
      node = node ? node->Parent() : nullptr;
      const auto* n = node ? node->ToElement() : nullptr;
      auto s = n ? scopes_.find(n) : scopes_.end();
      if (s == scopes_.end())
        fail(from, attr, fmt::format("links to '{}': there is no node {} level{} above", target, up, up > 1 ? "s" : ""));
      scope = &s->second;
    }
    auto it = scope->find(t);
    if (it == scope->end())
      fail(from, attr, fmt::format("links to '{}', which is no component of {}", target,
                                   up == 0 ? std::string("this node") : fmt::format("the node {} level{} up", up, up > 1 ? "s" : "")));
    return it->second;
  }

  void body(const XMLElement* node, const XMLElement* mo, const XMLElement* fem, const XMLElement* mass,
            const XMLElement* topology, const std::vector<const XMLElement*>& fixed,
            const std::vector<const XMLElement*>& loaders, const std::map<std::string, const XMLElement*>& named,
            const Solvers& solvers, const std::vector<const XMLElement*>& children,
            const std::vector<const XMLElement*>& collision_models) {
    Body b;
    b.line = node->GetLineNum();
    b.gravity = solvers.gravity;
    b.gravity_line = solvers.gravity_line;
    b.name = node->Attribute("name") ? node->Attribute("name") : fmt::format("body{}", bodies_.size());
    if (!fem) fail(mo, "", "no TetrahedronFEMForceField or TetrahedralCorotationalFEMForceField in this node: "
                           "Stroma simulates tetrahedral FEM bodies");
    if (!mass) fail(mo, "", "no mass (DiagonalMass, MeshMatrixMass or UniformMass) in this node");
    if (!solvers.ode) fail(mo, "", "no EulerImplicitSolver in this node or above: Stroma integrates with implicit Euler");

    // The MechanicalObject and the volume loader it takes its positions from.
    allow(mo, {"template", "src", "position", "translation", "dx", "dy", "dz", "scale", "scale3d", "sx", "sy", "sz",
               "rotation", "rx", "ry", "rz"},
          true);
    if (const char* t = mo->Attribute("template"); t && std::string(t) != "Vec3d" && std::string(t) != "Vec3")
      fail(mo, "template", fmt::format("'{}': only Vec3d (3D positions in double precision) bodies", t));
    std::string loader_name;
    if (mo->Attribute("src")) loader_name = link_target(mo, "src");
    else if (mo->Attribute("position")) loader_name = link_target(mo, "position", "position");
    else if (topology && topology->Attribute("src")) loader_name = link_target(topology, "src");
    else fail(mo, "src", "missing: link the volume mesh loader (src=\"@loader\")");
    const XMLElement* loader = named_in(named, mo, mo->Attribute("src") ? "src" : "position", loader_name);
    if (!kVolumeLoaders.count(loader->Name()))
      fail(mo, "src", fmt::format("'{}' is a {}; a body's positions come from a MeshGmshLoader or MeshVTKLoader",
                                  loader_name, loader->Name()));
    for (const XMLElement* l : loaders)
      if (l != loader && kVolumeLoaders.count(l->Name()))
        fail(l, "", "a second volume mesh loader in this body's node: one per body");
    volume_loader(loader, b);
    mechanical_object_transform(mo, b);
    if (topology) {
      allow(topology, {"src", "position", "tetrahedra", "template"});
      for (const char* a : {"src", "position", "tetrahedra"}) {
        if (!topology->Attribute(a)) continue;
        const std::string t = std::string(a) == "src" ? link_target(topology, a) : link_target(topology, a, a);
        if (t != loader_name)
          fail(topology, a, fmt::format("links '{}', not the body's loader '{}': the topology must be the mesh's", t,
                                        loader_name));
      }
    }

    attempt([&] {  // each part of a body is checked on its own: every error at once
      // Material.
      const std::string kind = fem->Name();
      allow(fem, kind == "TetrahedronFEMForceField"
                     ? std::set<std::string>{"template", "method", "youngModulus", "poissonRatio", "computeGlobalMatrix",
                                             "computeVonMisesStress", "showVonMisesStressPerElement", "showStressColorMap",
                                             "topology"}
                     : std::set<std::string>{"template", "method", "youngModulus", "poissonRatio", "computeGlobalMatrix",
                                             "fastMethod", "topology"},
            true);
      const std::string method = fem->Attribute("method") ? fem->Attribute("method") : "large";
      if (method == "large") b.model = "corotational", b.rotation = "qr";
      else if (method == "polar") b.model = "corotational", b.rotation = "polar";
      else if (method == "svd" && kind == "TetrahedronFEMForceField") {
        b.model = "corotational", b.rotation = "polar";
        notes_.push_back(fmt::format("line {}: method svd: Stroma's polar rotation (computed by SVD, inversion-safe)",
                                     fem->GetLineNum()));
      } else if (method == "small") b.model = "linear";
      else fail(fem, "method", fmt::format("'{}': supported are large, polar{}, small", method,
                                           kind == "TetrahedronFEMForceField" ? ", svd" : ""));
      if (!fem->Attribute("youngModulus")) fail(fem, "youngModulus", "missing (SOFA's default 5000 is rarely meant)");
      if (!fem->Attribute("poissonRatio")) fail(fem, "poissonRatio", "missing (SOFA's default 0.45 is rarely meant)");
      b.young = number(fem, "youngModulus");
      b.poisson = number(fem, "poissonRatio");
      if (!(b.young > 0)) fail(fem, "youngModulus", "must be > 0");
      if (!(b.poisson > -1 && b.poisson < 0.5)) fail(fem, "poissonRatio", "must be in (-1, 0.5)");

    });
    attempt([&] {
      // Damping from the ODE solver.
      const XMLElement* ode = solvers.ode;
      allow(ode, {"rayleighStiffness", "rayleighMass", "vdamping", "firstOrder", "trapezoidalScheme", "solveConstraint",
                  "computeResidual"});
      if (boolean(ode, "computeResidual", false))
        notes_.push_back(fmt::format("line {}: EulerImplicitSolver computeResidual: SOFA logs the residual after each "
                                     "solve; no effect on the simulation (Stroma reports its own: --stats)",
                                     ode->GetLineNum()));
      b.rayleigh_stiffness = ode->Attribute("rayleighStiffness") ? number(ode, "rayleighStiffness") : 0.0;
      b.rayleigh_mass = ode->Attribute("rayleighMass") ? number(ode, "rayleighMass") : 0.0;
      if (b.rayleigh_stiffness < 0) fail(ode, "rayleighStiffness", "must be >= 0");
      if (b.rayleigh_mass < 0) fail(ode, "rayleighMass", "must be >= 0");
      if (ode->Attribute("vdamping") && number(ode, "vdamping") != 0)
        fail(ode, "vdamping", "velocity damping is not modelled (use rayleighMass)");
      if (boolean(ode, "firstOrder", false)) fail(ode, "firstOrder", "first-order integration is not modelled");
      if (boolean(ode, "trapezoidalScheme", false)) fail(ode, "trapezoidalScheme", "only backward (implicit) Euler");
      if (boolean(ode, "solveConstraint", false)) fail(ode, "solveConstraint", "constraint solving is not modelled");

    });
    attempt([&] { mass_of(mass, b); });
    // SOFA lets a force field or a mass name its topology (topology="@name"): the node's own is
    // the only one a body has here.
    for (const XMLElement* e : {fem, mass})
      if (e && e->Attribute("topology"))
        attempt([&] {
          const std::string t = link_target(e, "topology");
          const XMLElement* target = named_in(named, e, "topology", t);
          if (target != topology)
            fail(e, "topology", fmt::format("links '{}', a {}, not this body's topology container{}", t, target->Name(),
                                            topology ? fmt::format(" (line {})", topology->GetLineNum()) : std::string()));
        });
    for (const XMLElement* f : fixed) attempt([&] { fixed_of(f, named, b); });
    for (const XMLElement* e : collision_models) collision_model(e, b);
    for (const XMLElement* c : children)
      attempt([&] {
        if (is_visual_node(c)) visual_node(c, mo, b);
        else if (is_collision_node(c)) collision_node(c, b);
        else walk(c, solvers);
      });
    if (!have_solver_) {
      body_solver_ = solvers;
      have_solver_ = true;
    } else if (!same_solver(body_solver_.ode, solvers.ode) || !same_solver(body_solver_.linear, solvers.linear)) {
      fail(mo, "", fmt::format("this body's solvers differ from those of the first body (line {}): Stroma steps "
                               "all bodies with one solver",
                               body_solver_.ode->GetLineNum()));
    }
    bodies_.push_back(std::move(b));
  }

  static bool same_solver(const XMLElement* a, const XMLElement* b) {
    if (a == b) return true;
    if (!a || !b || std::string(a->Name()) != b->Name()) return false;
    auto attrs = [](const XMLElement* e) {
      std::map<std::string, std::string> m;
      for (const XMLAttribute* x = e->FirstAttribute(); x; x = x->Next())
        if (std::string(x->Name()) != "name") m[x->Name()] = x->Value();
      return m;
    };
    return attrs(a) == attrs(b);
  }

  void volume_loader(const XMLElement* l, Body& b) {
    allow(l, {"filename", "scale", "scale3d", "translation", "rotation"});
    b.mesh = resolve_file(l, "filename");
    b.mesh_line = l->GetLineNum();
    // Read it here, so that a bad mesh file's error names the loader's line in the scene (not the
    // translated scenario's).
    try {
      b.tet = std::make_shared<const TetMesh>(load_tet_mesh(b.mesh));
    } catch (const InputError& e) {
      fail(l, "filename", std::string("the mesh cannot be read: ") + e.what());
    }
    if (l->Attribute("scale")) b.scale = number(l, "scale");
    if (l->Attribute("scale3d")) {
      const auto s = numbers(l, "scale3d");
      if (s.size() != 3 || s[0] != s[1] || s[1] != s[2])
        fail(l, "scale3d", "only a uniform scale (three equal values) is supported");
      if (l->Attribute("scale") && s[0] != 1.0 && b.scale != 1.0) fail(l, "scale3d", "give scale or scale3d, not both");
      if (s[0] != 1.0) b.scale = s[0];
    }
    if (!(b.scale > 0)) fail(l, l->Attribute("scale3d") ? "scale3d" : "scale", "must be > 0");
    if (l->Attribute("translation")) {
      const auto t = numbers(l, "translation");
      if (t.size() != 3) fail(l, "translation", fmt::format("{} values; a translation has 3", t.size()));
      b.translate = {t[0], t[1], t[2]};
    }
    if (l->Attribute("rotation")) {
      const auto r = numbers(l, "rotation");
      if (r.size() != 3) fail(l, "rotation", fmt::format("{} values; a rotation has 3", r.size()));
      if (r[0] != 0 || r[1] != 0 || r[2] != 0) fail(l, "rotation", "rotating a mesh at load is not supported");
    }
  }

  /// A 3-vector attribute of `e` given whole (`whole`: three numbers) or per axis (`axes`, each
  /// overriding its component), else `v`.
  std::array<double, 3> vector_or_axes(const XMLElement* e, const char* whole, const char* const axes[3],
                                       std::array<double, 3> v) const {
    if (e->Attribute(whole)) {
      const auto n = numbers(e, whole);
      if (n.size() != 3) fail(e, whole, fmt::format("{} values; a {} has 3", n.size(), whole));
      v = {n[0], n[1], n[2]};
    }
    for (int a = 0; a < 3; ++a)
      if (e->Attribute(axes[a])) v[size_t(a)] = number(e, axes[a]);
    return v;
  }

  /// SOFA's MechanicalObject moves its positions (and rest positions) at init: scale, then
  /// rotation, then translation (`translation` or the legacy dx/dy/dz, `scale`, `scale3d` or
  /// sx/sy/sz), after the loader's own. Composed into the body's scale and translation: a
  /// uniform scale and no rotation are carried, others refused.
  void mechanical_object_transform(const XMLElement* mo, Body& b) {
    static const char* const kS[3] = {"sx", "sy", "sz"}, *const kR[3] = {"rx", "ry", "rz"}, *const kD[3] = {"dx", "dy", "dz"};
    const double s = mo->Attribute("scale") ? number(mo, "scale") : 1.0;
    const std::array<double, 3> s3 = vector_or_axes(mo, "scale3d", kS, {s, s, s});
    if (s3[0] != s3[1] || s3[1] != s3[2])
      fail(mo, mo->Attribute("scale3d") ? "scale3d" : "sx", "only a uniform scale (three equal values) is supported");
    if (!(s3[0] > 0)) fail(mo, mo->Attribute("scale") ? "scale" : "scale3d", "must be > 0");
    const std::array<double, 3> r = vector_or_axes(mo, "rotation", kR, {0, 0, 0});
    if (r[0] != 0 || r[1] != 0 || r[2] != 0)
      fail(mo, mo->Attribute("rotation") ? "rotation" : "rx", "rotating the positions at init is not supported");
    const std::array<double, 3> t = vector_or_axes(mo, "translation", kD, {0, 0, 0});
    // x' = s_mo (s_l x + t_l) + t_mo
    b.scale *= s3[0];
    for (int a = 0; a < 3; ++a) b.translate[size_t(a)] = s3[0] * b.translate[size_t(a)] + t[size_t(a)];
    if (s3[0] != 1 || t != std::array<double, 3>{0, 0, 0})
      notes_.push_back(fmt::format("line {}: MechanicalObject's scale {} and translation ({} {} {}) composed with the "
                                   "loader's: scale {}, translate ({} {} {})",
                                   mo->GetLineNum(), num(s3[0]), num(t[0]), num(t[1]), num(t[2]), num(b.scale),
                                   num(b.translate[0]), num(b.translate[1]), num(b.translate[2])));
  }

  /// Mesh volume in the scene's units (after the loader's scale), for totalMass; `used` gets the
  /// number of nodes its tetrahedra use.
  double mesh_volume(const Body& b, const XMLElement* at, const char* attr, int* used = nullptr) const {
    if (!b.tet)
      fail(at, attr, b.mesh.empty() ? "the body has no mesh loader before it" : "the body's mesh could not be read (the loader's error)");
    const TetMesh& mesh = *b.tet;
    if (used) {
      std::vector<char> in(mesh.nodes.size(), 0);
      for (const Tet& t : mesh.tets)
        for (int32_t n : t) in[static_cast<size_t>(n)] = 1;
      *used = static_cast<int>(std::count(in.begin(), in.end(), 1));
    }
    double v = 0;
    for (const Tet& t : mesh.tets)
      v += std::abs(signed_volume(mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]], mesh.nodes[t[3]]));
    if (!(v > 0)) fail(at, attr, "the body's mesh has no volume");
    return v * b.scale * b.scale * b.scale;
  }

  void mass_of(const XMLElement* m, Body& b) {
    const std::string kind = m->Name();
    if (kind == "UniformMass") {
      // Every node the same mass: `mass_lumping: uniform` with the density that gives the total.
      allow(m, {"template", "totalMass", "vertexMass", "topology"}, true);
      if (m->Attribute("totalMass") && m->Attribute("vertexMass"))
        fail(m, "vertexMass", "give totalMass or vertexMass, not both");
      b.uniform_mass = true;
      int used = 0;
      const char* attr = m->Attribute("totalMass") ? "totalMass" : "vertexMass";
      const double volume = mesh_volume(b, m, attr, &used);
      double total = 0;
      if (m->Attribute("totalMass")) {
        total = number(m, "totalMass");
        if (!(total > 0)) fail(m, "totalMass", "must be > 0");
      } else {
        const double vm = m->Attribute("vertexMass") ? number(m, "vertexMass") : 1.0;
        if (!m->Attribute("vertexMass"))
          notes_.push_back(fmt::format("line {}: UniformMass without totalMass or vertexMass: SOFA's default vertexMass 1",
                                       m->GetLineNum()));
        if (!(vm > 0)) fail(m, "vertexMass", "must be > 0");
        total = vm * used;
      }
      b.density = total / volume;
      b.mass_note = fmt::format("UniformMass line {}: {} over {} nodes, each the same (mass_lumping: uniform)",
                                m->GetLineNum(), num(total), used);
      return;
    }
    allow(m, kind == "DiagonalMass" ? std::set<std::string>{"template", "massDensity", "totalMass", "topology"}
                                    : std::set<std::string>{"template", "massDensity", "totalMass", "lumping", "topology"},
          true);
    if (kind == "MeshMatrixMass" && !boolean(m, "lumping", false))
      fail(m, "lumping",
           "a consistent mass matrix (MeshMatrixMass's default): Stroma lumps masses. With lumping=\"true\" "
           "the row sums are exactly ρV/4 per tetrahedron node, which Stroma uses");
    const bool has_density = m->Attribute("massDensity") != nullptr, has_total = m->Attribute("totalMass") != nullptr;
    if (has_density && has_total) fail(m, "totalMass", "give massDensity or totalMass, not both");
    if (has_total) {
      const double total = number(m, "totalMass");
      if (!(total > 0)) fail(m, "totalMass", "must be > 0");
      b.density = total / mesh_volume(b, m, "totalMass");
      b.mass_note = fmt::format("{} line {}: totalMass {} over the mesh's volume, lumped ρV/4 per tetrahedron node",
                                kind, m->GetLineNum(), num(total));
    } else {
      b.density = has_density ? number(m, "massDensity") : 1.0;
      if (!has_density) notes_.push_back(fmt::format("line {}: {} without massDensity: SOFA's default 1", m->GetLineNum(), kind));
      if (!(b.density > 0)) fail(m, "massDensity", "must be > 0");
      b.mass_note = fmt::format("{} line {}: lumped ρV/4 per tetrahedron node", kind, m->GetLineNum());
    }
  }

  /// SOFA's FixedPlaneProjectiveConstraint: the nodes in the slab dmin < x·direction < dmax
  /// (rest positions, after the loader's and the MechanicalObject's transforms), or `indices`,
  /// lose their displacement along `direction` only — they slide in the plane. SOFA projects
  /// the matrix only for a direction along an axis, and so does the translation (Stroma's
  /// per-axis `fixed`); another direction is refused.
  void fixed_plane_of(const XMLElement* f, Body& b) {
    allow(f, {"template", "direction", "dmin", "dmax", "indices"}, true);
    if (!f->Attribute("direction")) fail(f, "direction", "missing: the normal of the plane the nodes slide in");
    const auto d = numbers(f, "direction");
    if (d.size() != 3) fail(f, "direction", fmt::format("{} values; a direction has 3", d.size()));
    int axis = -1;
    for (int a = 0; a < 3; ++a)
      if (d[size_t(a)] != 0) axis = axis == -1 ? a : 3;
    if (axis < 0 || axis > 2)
      fail(f, "direction", fmt::format("({} {} {}): only a direction along x, y or z (SOFA projects the matrix only for those)",
                                       num(d[0]), num(d[1]), num(d[2])));
    const double dmin = f->Attribute("dmin") ? number(f, "dmin") : 0.0, dmax = f->Attribute("dmax") ? number(f, "dmax") : 0.0;
    std::vector<int> nodes;
    if (dmin != dmax) {
      if (f->Attribute("indices")) fail(f, "indices", "give indices or a slab (dmin, dmax), not both");
      if (!b.tet) fail(f, "", "the body's mesh could not be read");
      for (size_t i = 0; i < b.tet->nodes.size(); ++i) {
        const double x = b.tet->nodes[i][size_t(axis)] * b.scale + b.translate[size_t(axis)];
        const double p = x * d[size_t(axis)];
        if (p > dmin && p < dmax) nodes.push_back(int(i));
      }
      if (nodes.empty())
        fail(f, "dmin", fmt::format("no node in the slab {} < x·direction < {}: nothing to constrain", num(dmin), num(dmax)));
    } else {
      if (!f->Attribute("indices")) fail(f, "indices", "missing: the nodes, or a slab (dmin < dmax)");
      for (double v : numbers(f, "indices")) {
        if (v < 0 || v != std::floor(v) || v > 2e9) fail(f, "indices", fmt::format("'{}' is not a 0-based node index", num(v)));
        nodes.push_back(static_cast<int>(v));
      }
    }
    b.fixed_lines.push_back(f->GetLineNum());
    b.fixed_along.emplace_back(std::move(nodes), axis);
  }

  void fixed_of(const XMLElement* f, const std::map<std::string, const XMLElement*>& named, Body& b) {
    if (std::string(f->Name()).rfind("FixedPlane", 0) == 0) return fixed_plane_of(f, b);
    allow(f, {"template", "indices", "fixAll"}, true);
    if (boolean(f, "fixAll", false)) fail(f, "fixAll", "fixing every node leaves nothing to simulate; not supported");
    const char* idx = f->Attribute("indices");
    if (!idx) fail(f, "indices", "missing: the nodes to fix (0-based indices, or @box.indices)");
    b.fixed_lines.push_back(f->GetLineNum());
    if (idx[0] == '@') {
      const std::string roi_name = link_target(f, "indices", "indices");
      const XMLElement* roi = named_in(named, f, "indices", roi_name);
      if (std::string(roi->Name()) != "BoxROI")
        fail(f, "indices", fmt::format("'{}' is a {}; indices can come from a BoxROI", roi_name, roi->Name()));
      allow(roi, {"template", "box"}, true);
      if (!roi->Attribute("box")) fail(roi, "box", "missing: xmin ymin zmin xmax ymax zmax");
      const auto v = numbers(roi, "box");
      if (v.empty() || v.size() % 6 != 0)
        fail(roi, "box", fmt::format("{} values; boxes are 6 each (xmin ymin zmin xmax ymax zmax)", v.size()));
      for (size_t k = 0; k < v.size(); k += 6) {
        for (int c = 0; c < 3; ++c)
          if (v[k + c] > v[k + 3 + c])
            fail(roi, "box", fmt::format("box {}: min {} > max {} along axis {}", k / 6, num(v[k + c]), num(v[k + 3 + c]), c));
        b.fixed_boxes.push_back({v[k], v[k + 1], v[k + 2], v[k + 3], v[k + 4], v[k + 5]});
      }
      return;
    }
    std::vector<int> nodes;
    for (double v : numbers(f, "indices")) {
      if (v < 0 || v != std::floor(v) || v > 2e9) fail(f, "indices", fmt::format("'{}' is not a 0-based node index", num(v)));
      nodes.push_back(static_cast<int>(v));
    }
    if (nodes.empty()) fail(f, "indices", "empty: no node to fix");
    b.fixed_nodes.push_back(std::move(nodes));
  }

  /// A collision model of body b: Stroma's collision surface is the body's boundary.
  void collision_model(const XMLElement* e, Body& b) {
    ++b.collision_models;
    notes_.push_back(fmt::format("line {}: {}: the body's collision surface is its boundary (Stroma's contact); the "
                                 "model's own primitives and settings (contactStiffness, proximity) are not carried",
                                 e->GetLineNum(), e->Name()));
  }

  /// A collision child node (is_collision_node): its models describe b's collision surface.
  void collision_node(const XMLElement* n, Body& b) {
    Solvers unused;  // no body in it: its gravity acts on nothing
    node_attributes(n, unused);
    for (const XMLElement* e = n->FirstChildElement(); e; e = e->NextSiblingElement())
      if (kCollisionModels.count(e->Name())) collision_model(e, b);
  }

  void visual_node(const XMLElement* n, const XMLElement* mo, Body& b) {
    Solvers unused;  // no body in it: its gravity acts on nothing
    node_attributes(n, unused);
    std::map<std::string, const XMLElement*> named;
    const XMLElement *ogl = nullptr, *mapping = nullptr;
    for (const XMLElement* e = n->FirstChildElement(); e; e = e->NextSiblingElement()) {
      const std::string kind = e->Name();
      if (const char* nm = e->Attribute("name")) named[nm] = e;
      if (kind == "OglModel") {
        if (ogl) fail(e, "", "a second OglModel: one visual surface per body");
        ogl = e;
      } else if (kind == "BarycentricMapping") {
        mapping = e;
      } else if (kind != "MeshOBJLoader" && !kNoEffect.count(kind)) {
        fail(e, "", "a visual node holds MeshOBJLoader, OglModel and BarycentricMapping; this component is not supported here");
      }
    }
    if (!mapping) fail(ogl, "", "no BarycentricMapping beside it: the visual surface must follow the body");
    allow(ogl, {"template", "src", "filename", "color"});
    if (ogl->Attribute("src")) {
      const XMLElement* l = named_in(named, ogl, "src", link_target(ogl, "src"));
      if (std::string(l->Name()) != "MeshOBJLoader")
        fail(ogl, "src", fmt::format("links a {}; the visual surface comes from a MeshOBJLoader", l->Name()));
      allow(l, {"filename", "handleSeams", "loadMaterial"});
      b.visual = resolve_file(l, "filename");
    } else if (ogl->Attribute("filename")) {
      b.visual = resolve_file(ogl, "filename");
    } else {
      fail(ogl, "src", "missing: link a MeshOBJLoader (src=\"@loader\") or give filename");
    }
    if (ogl->Attribute("color")) notes_.push_back(fmt::format("line {}: OglModel color: not carried (renderers colour by field)", ogl->GetLineNum()));
    allow(mapping, {"template", "input", "output"});
    if (!mapping->Attribute("input") || !mapping->Attribute("output"))
      fail(mapping, mapping->Attribute("input") ? "output" : "input", "missing: input=\"@../dofs\" output=\"@visual\"");
    // The parent node ("@.." / "@../": SOFA takes its mechanical state) or its MechanicalObject.
    std::string in = mapping->Attribute("input");
    const std::string mo_name = mo->Attribute("name") ? mo->Attribute("name") : "";
    const bool parent = in == "@.." || in == "@../" || (in.rfind("@../", 0) == 0 && in.substr(4) == mo_name);
    if (!parent)
      fail(mapping, "input", fmt::format("'{}': must be the body's MechanicalObject (@../{}) or its node (@..)", in, mo_name));
    const std::string out = link_target(mapping, "output");
    if (!named.count(out) || named.at(out) != ogl)
      fail(mapping, "output", fmt::format("'{}' is not this node's OglModel", out));
  }

  void solver_yaml(std::string& y) const {
    const XMLElement* ode = body_solver_.ode;
    const XMLElement* lin = body_solver_.linear;
    y += fmt::format("solver:\n  integrator: implicit_euler   # {} line {}\n", ode->Name(), ode->GetLineNum());
    if (!lin) throw InputError(file_, ode->GetLineNum(), "EulerImplicitSolver",
                               "no linear solver (CGLinearSolver or SparseLDLSolver) beside the ODE solver");
    if (std::string(lin->Name()) == "SparseLDLSolver") {
      allow(lin, {"template"});
      y += fmt::format("  linear_solver: cholmod   # SparseLDLSolver line {}: a sparse direct factorisation\n",
                       lin->GetLineNum());
      return;
    }
    allow(lin, {"template", "iterations", "tolerance", "threshold", "warmStart"});
    const double its = lin->Attribute("iterations") ? number(lin, "iterations") : 25;
    if (its < 1 || its != std::floor(its) || its > 1e7) fail(lin, "iterations", "must be a whole number >= 1");
    const double tol = lin->Attribute("tolerance") ? number(lin, "tolerance") : 1e-5;
    if (!(tol > 0 && tol < 1)) fail(lin, "tolerance", "must be in (0, 1)");
    if (lin->Attribute("threshold") && !(number(lin, "threshold") >= 0)) fail(lin, "threshold", "must be >= 0");
    const bool warm = boolean(lin, "warmStart", false);
    y += fmt::format("  linear_solver: cg          # CGLinearSolver line {}\n", lin->GetLineNum());
    y += "  preconditioner: none       # SOFA's CGLinearSolver is not preconditioned\n";
    y += fmt::format("  max_iterations: {}\n  tolerance: {}           # |r|/|b|, as SOFA master's CG stops\n",
                     static_cast<long>(its), num(tol));
    y += fmt::format("  warm_start: {}   # CGLinearSolver warmStart {}\n", warm ? "previous" : "off", warm ? "true" : "false (its default)");
    y += "  on_cg_cap: continue        # SOFA keeps the iterate a capped CG reaches\n";
  }

  std::string emit() const {
    std::string y = fmt::format("# Translated from {} by Stroma's SOFA-scene importer (docs/SOFA.md).\n", file_);
    std::string stem = fs::path(file_).stem().string();
    if (stem.empty()) stem = "sofa_scene";
    y += fmt::format("name: {}\n", yaml_quoted(stem));
    y += fmt::format("time_step: {}             # root dt\n", num(dt_));
    y += fmt::format("gravity: [{}, {}, {}]\n", num(gravity_[0]), num(gravity_[1]), num(gravity_[2]));
    solver_yaml(y);
    y += "bodies:\n";
    for (const Body& b : bodies_) {
      y += fmt::format("  - name: {}           # Node line {}\n", yaml_quoted(b.name), b.line);
      y += fmt::format("    mesh: {}   # loader line {}\n", yaml_quoted(b.mesh), b.mesh_line);
      if (b.scale != 1.0) y += fmt::format("    scale: {}\n", num(b.scale));
      if (b.translate != std::array<double, 3>{0, 0, 0})
        y += fmt::format("    translate: [{}, {}, {}]\n", num(b.translate[0]), num(b.translate[1]), num(b.translate[2]));
      y += "    material:\n";
      y += fmt::format("      model: {}\n", b.model);
      if (!b.rotation.empty())
        y += fmt::format("      rotation: {}{}\n", b.rotation, b.rotation == "qr" ? "   # SOFA's \"large\": the edge frame" : "");
      y += fmt::format("      young_modulus: {}\n      poisson_ratio: {}\n", num(b.young), num(b.poisson));
      y += fmt::format("      density: {}   # {}\n", num(b.density), b.mass_note);
      if (b.uniform_mass) y += "      mass_lumping: uniform\n";
      y += fmt::format("      rayleigh_mass: {}\n      rayleigh_stiffness: {}\n", num(b.rayleigh_mass),
                       num(b.rayleigh_stiffness));
      if (!b.fixed_nodes.empty() || !b.fixed_boxes.empty() || !b.fixed_along.empty()) y += "    fixed:\n";
      for (const auto& [nodes, axis] : b.fixed_along) {
        y += "      - nodes: [";
        for (size_t k = 0; k < nodes.size(); ++k) y += (k ? ", " : "") + std::to_string(nodes[k]);
        y += fmt::format("]\n        axes: [{}]   # FixedPlaneProjectiveConstraint: slides in the plane\n", "xyz"[axis]);
      }
      for (const auto& nodes : b.fixed_nodes) {
        y += "      - nodes: [";
        for (size_t k = 0; k < nodes.size(); ++k) y += (k ? ", " : "") + std::to_string(nodes[k]);
        y += "]\n";
      }
      for (const auto& bx : b.fixed_boxes)
        y += fmt::format("      - box: {{min: [{}, {}, {}], max: [{}, {}, {}]}}   # BoxROI\n", num(bx[0]), num(bx[1]),
                         num(bx[2]), num(bx[3]), num(bx[4]), num(bx[5]));
      if (!b.visual.empty()) y += fmt::format("    visual: {}\n", yaml_quoted(b.visual));
    }
    return y;
  }

  std::string file_, base_;
  std::array<double, 3> gravity_{};
  double dt_ = 0.01;
  std::vector<Body> bodies_;
  Solvers body_solver_;
  bool have_solver_ = false;
  std::vector<std::string> notes_;
};

}  // namespace

SofaTranslation translate_sofa_scene(const std::string& xml, const std::string& file, const std::string& base_dir) {
  return Translator(file, base_dir).run(xml);
}

SofaTranslation translate_sofa_scene_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "", std::string("cannot open SOFA scene: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  return translate_sofa_scene(text.str(), path, fs::path(path).parent_path().string());
}

bool is_sofa_scene_path(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".scn";
}

}  // namespace stroma
