/// \file scenario_loader.cpp
/// load_scenario / parse_scenario: YAML text -> validated ScenarioSpec.
///
/// The schema is strict: every map checks its keys against the allowed set (unknown keys are
/// errors, with a "did you mean" suggestion), every value is type- and range-checked, and every
/// error is an InputError carrying the file, the 1-based line and the dotted field path.
///
/// The checking itself is the generic schema layer (scene/yaml_schema.hpp: `Field`,
/// `MapReader`, ranges, choice tables). The section parsers below only say which key goes where,
/// with which range.

#include <algorithm>
#include <charconv>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <initializer_list>
#include <map>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "scene/scenario_spec.hpp"
#include "scene/sofa_scene.hpp"
#include "scene/yaml_schema.hpp"
#include "tissue/input_error.hpp"
#include "tissue/rod.hpp"

namespace stroma {
namespace {

using yaml::physical_range;
using yaml::at_least;
using yaml::Choices;
using yaml::did_you_mean;
using yaml::Field;
using yaml::format_number;
using yaml::greater_than;
using yaml::join;
using yaml::MapReader;
using yaml::open_interval;
using yaml::Range;

// ---------------------------------------------------------------------------------------------
// Enumerations

const Choices<Integrator> kIntegrators = {{"implicit_euler", Integrator::ImplicitEuler},
                                          {"symplectic_euler", Integrator::SymplecticEuler},
                                          {"static", Integrator::Static}};
const Choices<LinearSolverKind> kLinearSolvers = {{"cg", LinearSolverKind::CG},
                                                  {"cholmod", LinearSolverKind::Cholmod}};
const Choices<std::optional<Preconditioner>> kPreconditioners = {{"auto", std::nullopt},
                                                                 {"jacobi", Preconditioner::Jacobi},
                                                                 {"block_jacobi", Preconditioner::BlockJacobi},
                                                                 {"none", Preconditioner::None},
                                                                 {"warped_cholesky", Preconditioner::WarpedCholesky}};
// true/false kept as aliases: true = the best guess (extrapolate), false = off.
const Choices<WarmStart> kWarmStarts = {{"extrapolate", WarmStart::Extrapolate},
                                        {"previous", WarmStart::Previous},
                                        {"off", WarmStart::Off},
                                        {"true", WarmStart::Extrapolate},
                                        {"false", WarmStart::Off}};
const Choices<DamageMeasure> kDamageMeasures = {{"von_mises", DamageMeasure::VonMises},
                                                {"principal_strain", DamageMeasure::PrincipalStrain}};
const Choices<ElementModel> kElementModels = {{"corotational", ElementModel::Corotational},
                                              {"linear", ElementModel::Linear},
                                              {"stable_neo_hookean", ElementModel::StableNeoHookean},
                                              {"st_venant_kirchhoff", ElementModel::StVenantKirchhoff}};
const Choices<ColorFieldSpec> kColorFields = {{"none", ColorFieldSpec::None},
                                              {"stress", ColorFieldSpec::Stress},
                                              {"damage", ColorFieldSpec::Damage}};
const Choices<RotationMethod> kRotationMethods = {{"polar", RotationMethod::Polar},
                                                  {"qr", RotationMethod::QR}};
const Choices<bool> kMassLumpings = {{"volume", false}, {"uniform", true}};

// ---------------------------------------------------------------------------------------------
// Section parsers

struct Context {
  std::string file;
  std::string base_dir;
};

std::string resolve_path(const std::string& p, const std::string& base_dir) {
  namespace fs = std::filesystem;
  const fs::path path(p);
  if (path.is_absolute() || base_dir.empty()) return path.lexically_normal().string();
  return (fs::path(base_dir) / path).lexically_normal().string();
}

/// Where a section or value is, for errors raised after parsing (compile): the line of the key
/// that introduced it, or of the list item, so that a section points at its heading.
SourceLocation location_of(const Field& f) { return {f.file(), f.key_line()}; }
SourceLocation location_of(const MapReader& m) { return {m.file(), m.line()}; }

// Each parser takes the Field of its section and declares the section's allowed keys.

const Choices<CapPolicy> kCapPolicies = {
    {"auto", CapPolicy::Auto}, {"substep", CapPolicy::Substep}, {"continue", CapPolicy::Continue}};
const Choices<bool> kHapticModels = {{"secant", true}, {"hold", false}};

/// An optional key holding a whole number >= 1 or one of `words` (each stored as its value);
/// anything else is an error naming what was `expected`.
void read_count_or_words(const MapReader& m, const char* key, std::initializer_list<std::pair<const char*, int>> words,
                         const std::string& expected, int& out) {
  const auto f = m.opt(key);
  if (!f) return;
  const std::string v = f->yaml().IsScalar() ? f->yaml().Scalar() : std::string();
  for (const auto& [word, value] : words)
    if (v == word) {
      out = value;
      return;
    }
  if (v.empty() || v.find_first_not_of("+-0123456789") != std::string::npos)
    f->fail("expected " + expected + ", got " + f->got());
  f->get(out, greater_than(0));
}

SolverSpec parse_solver(const Field& f) {
  const MapReader m = f.map({"integrator", "linear_solver", "preconditioner", "max_iterations",
                             "tolerance", "warm_start", "static_tolerance", "static_max_newton", "on_cg_cap",
                             "newton_iterations", "newton_tolerance", "time_budget",
                             "preconditioner_refresh", "fem_every", "haptic_model", "stiffness_every"});
  SolverSpec s;
  s.where = location_of(m);
  if (auto i = m.opt("integrator")) s.integrator_where = location_of(*i);
  m.read("integrator", s.integrator, kIntegrators);
  m.read("linear_solver", s.linear_solver, kLinearSolvers);
  m.read("preconditioner", s.preconditioner, kPreconditioners);
  m.read("max_iterations", s.max_iterations, greater_than(0));
  m.read("tolerance", s.tolerance, open_interval(0, 1));
  m.read("warm_start", s.warm_start, kWarmStarts);
  m.read("static_tolerance", s.static_tolerance, greater_than(0));
  m.read("static_max_newton", s.static_max_newton, greater_than(0));
  m.read("on_cg_cap", s.on_cg_cap, kCapPolicies);
  read_count_or_words(m, "newton_iterations", {{"auto", 0}}, "a whole number >= 1 or auto", s.newton_iterations);
  m.read("newton_tolerance", s.newton_tolerance, open_interval(0, 1));
  read_count_or_words(m, "preconditioner_refresh", {{"auto", -1}, {"off", 0}},
                      "a whole number of steps >= 1, auto or off", s.preconditioner_refresh);
  read_count_or_words(m, "stiffness_every", {}, "a whole number of steps >= 1", s.stiffness_every);
  if (const auto f = m.opt("fem_every")) {
    s.fem_every_where = location_of(*f);
    read_count_or_words(m, "fem_every", {}, "a whole number of ticks >= 1", s.fem_every);
  }
  m.read("haptic_model", s.haptic_secant, kHapticModels);
  if (const auto f = m.opt("time_budget")) {  // seconds > 0, or none (stored as 0)
    s.time_budget_where = location_of(*f);
    if (f->yaml().IsScalar() && f->yaml().Scalar() == "none")
      s.time_budget = 0;
    else
      f->get(s.time_budget, greater_than(0));
  }
  return s;
}

/// `damage:` of a material or a region: thresholds on a per-element measure.
DamageSpec parse_damage(const Field& f) {
  const MapReader dm = f.map({"measure", "warning", "onset", "rupture"});
  DamageSpec d;
  d.enabled = true;
  dm.read("measure", d.measure, kDamageMeasures);
  dm.require("onset", d.onset, greater_than(0));
  dm.require("rupture", d.rupture, greater_than(0));
  dm.read("warning", d.warning, greater_than(0));
  if (d.rupture <= d.onset)
    dm.req("rupture").fail("rupture = " + format_number(d.rupture) + " must be greater than onset = " +
                           format_number(d.onset));
  if (d.warning > d.onset)
    dm.req("warning").fail("warning = " + format_number(d.warning) + " must not exceed onset = " +
                           format_number(d.onset) + " (it warns before harm)");
  if (d.warning == 0) d.warning = d.onset;
  return d;
}

/// `fibres: {direction: [x, y, z] | mesh, k1: PA, k2: NUMBER}`.
FibreSpec parse_fibres(const Field& f) {
  const MapReader m = f.map({"direction", "k1", "k2"});
  FibreSpec s;
  s.where = location_of(m);
  const Field dir = m.req("direction");
  if (dir.is_scalar()) {
    if (dir.string() != "mesh")
      dir.fail("expected [x, y, z] (the rest fibre direction) or 'mesh' (each tetrahedron's from the mesh's "
               "cell data 'fibres'), got " + dir.got());
    s.from_mesh = true;
  } else {
    const Vec3 d = dir.vec3();
    const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(len > 1e-12) || !std::isfinite(len)) dir.fail("the fibre direction must be a finite non-zero vector");
    for (int k = 0; k < 3; ++k) s.direction[k] = d[k] / len;
  }
  m.require("k1", s.k1,
            physical_range(1e-9, 1e12, "Pa: tendon and ligament fibres are ~1e5..1e8 Pa, arterial ~1e3..1e6 Pa"));
  Range k2 = physical_range(0, 1e3, "");
  k2.note_hi = "dimensionless: exp(k2 (I4-1)^2) overflows the stiffness beyond ~1e3";
  m.read("k2", s.k2, k2);
  return s;
}

/// `viscoelastic: {model: prony, terms: [{g, tau}, ...]}` | `{model: standard_linear_solid, g,
/// tau}` | `{model: maxwell, tau}` | `{model: kelvin_voigt, tau}` (tissue/viscoelastic.hpp).
ViscoSpec parse_viscoelastic(const Field& f) {
  const MapReader m = f.map({"model", "terms", "g", "tau"});
  ViscoSpec v;
  v.where = location_of(m);
  static const Choices<std::string> kModels = {{"prony", "prony"},
                                               {"standard_linear_solid", "standard_linear_solid"},
                                               {"maxwell", "maxwell"},
                                               {"kelvin_voigt", "kelvin_voigt"}};
  m.require("model", v.model, kModels);
  Range g_range{0.0, 1.0, true, false, "", "g = 1 leaves no long-term stiffness (a fluid: model maxwell)"};
  Range tau_range = greater_than(0);
  tau_range.hi = 1e9;
  tau_range.hi_closed = true;
  auto only = [&](std::initializer_list<const char*> keys, const char* why) {
    for (const char* k : {"terms", "g", "tau"}) {
      bool allowed = false;
      for (const char* a : keys) allowed |= std::string(a) == k;
      if (!allowed)
        if (auto x = m.opt(k)) x->fail(fmt::format("'{}' is not a parameter of model {} ({})", k, v.model, why));
    }
  };
  if (v.model == "prony") {
    only({"terms"}, "give terms: [{g, tau}, ...]");
    const std::vector<Field> items = m.req("terms").list();
    if (items.empty() || items.size() > static_cast<size_t>(kMaxPronyTerms))
      m.req("terms").fail(fmt::format("a Prony series has 1 to {} terms, got {}", kMaxPronyTerms, items.size()));
    double sum = 0;
    for (const Field& item : items) {
      const MapReader t = item.map({"g", "tau"});
      const int i = v.series.terms++;
      t.require("g", v.series.g[i], g_range);
      t.require("tau", v.series.tau[i], tau_range);
      sum += v.series.g[i];
    }
    if (!(sum < 1))
      m.req("terms").fail(fmt::format("the relative moduli g sum to {:g}: they must sum to less than 1 (the long-term "
                                      "modulus E(1 - sum g) must stay > 0)",
                                      sum));
  } else if (v.model == "standard_linear_solid") {
    only({"g", "tau"}, "g: the Maxwell arm's share of the instantaneous modulus, tau: its relaxation time");
    v.series.terms = 1;
    m.require("g", v.series.g[0], g_range);
    m.require("tau", v.series.tau[0], tau_range);
  } else if (v.model == "maxwell") {
    only({"tau"}, "a Maxwell fluid relaxes completely: tau = viscosity / young_modulus");
    v.series.terms = 1;
    v.series.g[0] = 1.0;
    m.require("tau", v.series.tau[0], tau_range);
  } else {
    only({"tau"}, "tau = viscosity / young_modulus");
    m.require("tau", v.kelvin_voigt_tau, tau_range);
  }
  return v;
}

/// `locking_free: node_smoothing | element_patches` |
/// `{method: node_smoothing, stabilisation: SHARE}` |
/// `{method: element_patches, patch_elements: K, element_bulk: SHARE}`.
LockingFreeSpec parse_locking_free(const Field& f) {
  LockingFreeSpec l;
  l.where = location_of(f);
  auto method = [&](const Field& m) {
    const std::string name = m.string();
    if (name != "node_smoothing" && name != "element_patches")
      m.fail("expected node_smoothing (node-based strain smoothing) or element_patches (the volumetric strain "
             "averaged over patches of elements, F-bar-patch), got " + m.got());
    if (name == "element_patches") l = LockingFreeSpec::element_patches();
    l.method = name;
  };
  if (f.is_scalar()) {
    const SourceLocation where = l.where;
    method(f);
    l.where = where;
    return l;
  }
  const MapReader m = f.map({"method", "stabilisation", "patch_elements", "element_bulk"});
  method(m.req("method"));
  l.where = location_of(m);
  const bool patches = l.method == "element_patches";
  if (auto st = m.opt("stabilisation")) {
    if (patches)
      st->fail("stabilisation belongs to method node_smoothing (element_patches keep the whole deviatoric part on "
               "the elements; element_bulk is theirs)");
    Range share = physical_range(0, 1, "");
    share.note_lo = "the share of the deviatoric stiffness kept on the elements: 0 is pure node smoothing";
    share.note_hi = "1 keeps all of it on the elements: only the bulk is smoothed";
    l.stabilisation = st->number(share);
  }
  if (auto k = m.opt("patch_elements")) {
    if (!patches) k->fail("patch_elements belongs to method element_patches");
    const double v = k->number();
    if (v != std::floor(v) || v < 2 || v > 64)
      k->fail("expected a whole number of tetrahedra from 2 to 64 (a patch's least size), got " + k->got());
    l.patch_elements = static_cast<int>(v);
  }
  if (auto b = m.opt("element_bulk")) {
    if (!patches) b->fail("element_bulk belongs to method element_patches");
    const double v = b->number();
    if (!(v >= 0 && v < 1))
      b->fail("expected the share of the bulk modulus kept on each element, from 0 (all of it averaged over the "
              "patch) to below 1, got " + b->got());
    l.element_bulk = v;
  }
  return l;
}

MaterialSpec parse_material(const Field& f) {
  const MapReader m = f.map({"model", "rotation", "young_modulus", "poisson_ratio", "density",
                             "rayleigh_mass", "rayleigh_stiffness", "damage", "fibres", "viscoelastic",
                             "locking_free", "mass_lumping", "needle"});
  MaterialSpec mat;
  mat.where = location_of(m);
  Range nu = open_interval(-1, 0.5);
  nu.note_hi = "0.5 is incompressible; use 0.49 or lower";
  m.read("model", mat.model, kElementModels);
  m.read("rotation", mat.rotation, kRotationMethods);
  // Physical ranges wide enough for any consistent unit system (SI; mm-tonne-s, where water is
  // 1e-9 t/mm^3 and 1 kPa is 1e-3 MPa; density 1 in mesh units) and narrow enough that
  // masses, stiffnesses and their products with h and h^2 stay far from overflow and underflow.
  m.require("young_modulus", mat.young_modulus,
            physical_range(1e-9, 1e12, "soft tissue is 1e2..1e6 Pa, bone 2e10 Pa, diamond 1e12 Pa; 1 Pa is 1e-6 in MPa"));
  m.require("poisson_ratio", mat.poisson_ratio, nu);
  m.require("density", mat.density,
            physical_range(1e-12, 1e6, "tissue is ~1000 kg/m^3 in SI, 1e-9 t/mm^3 in mm-tonne-s units"));
  Range alpha = physical_range(0, 1e6, "");
  alpha.note_hi = "1/s: a mass damping above 1e6/s stops any motion within a microsecond";
  Range beta = physical_range(0, 1e3, "");
  beta.note_hi = "s: tissue is 1e-3..1e-1 s";
  m.read("rayleigh_mass", mat.rayleigh_mass, alpha);
  m.read("rayleigh_stiffness", mat.rayleigh_stiffness, beta);
  m.read("mass_lumping", mat.uniform_mass, kMassLumpings);
  if (auto f2 = m.opt("damage")) mat.damage = parse_damage(*f2);
  if (auto f2 = m.opt("fibres")) {
    mat.fibres = parse_fibres(*f2);
    if (mat.model != ElementModel::StableNeoHookean && mat.model != ElementModel::StVenantKirchhoff)
      f2->fail("fibres need a hyperelastic matrix: model stable_neo_hookean or st_venant_kirchhoff");
  }
  if (auto f2 = m.opt("viscoelastic")) {
    mat.viscoelastic = parse_viscoelastic(*f2);
    const bool polar = mat.model == ElementModel::Corotational && mat.rotation == RotationMethod::Polar;
    const bool hyper = mat.model == ElementModel::StableNeoHookean || mat.model == ElementModel::StVenantKirchhoff;
    if (mat.viscoelastic->model != "kelvin_voigt" && !polar && !hyper)
      f2->fail("a Prony series needs model corotational with rotation polar, stable_neo_hookean or "
               "st_venant_kirchhoff (its overstresses live in the element's polar frame)");
    if (mat.viscoelastic->model == "kelvin_voigt" && m.opt("rayleigh_stiffness"))
      f2->fail("kelvin_voigt is stiffness damping with rayleigh_stiffness = tau: give one of them");
  }
  if (auto f2 = m.opt("needle")) {
    const MapReader nm = f2->map({"puncture_force", "cutting_force", "friction", "track_stiffness", "track_spacing"});
    NeedleTissueSpec n;
    n.where = location_of(nm);
    const Range force = physical_range(1e-6, 1e3, "N: needles puncture soft tissue at ~0.1..5 N");
    nm.require("puncture_force", n.puncture_force, force);
    nm.require("cutting_force", n.cutting_force, force);
    const MapReader fm = nm.req("friction").map({"static", "kinetic"});
    const Range per_length = physical_range(0, 1e5, "N per m of inserted length: liver ~1..50 N/m");
    fm.require("static", n.friction_static, per_length);
    fm.require("kinetic", n.friction_kinetic, per_length);
    if (n.friction_kinetic > n.friction_static)
      fm.req("kinetic").fail("kinetic friction (" + format_number(n.friction_kinetic) + " N/m) exceeds static (" +
                             format_number(n.friction_static) + " N/m)");
    nm.read("track_stiffness", n.track_stiffness,
            physical_range(1e-6, 1e12, "N/m per m of track (automatic: 100 * young_modulus)"));
    nm.read("track_spacing", n.track_spacing, physical_range(1e-6, 1, "m between track points (automatic: half the mean surface edge)"));
    mat.needle = n;
  }
  if (auto f2 = m.opt("locking_free")) {
    mat.locking_free = parse_locking_free(*f2);
    if (mat.model != ElementModel::Corotational && mat.model != ElementModel::Linear)
      f2->fail("locking_free needs model corotational or linear (the hyperelastic models have no smoothed form yet)");
    if (mat.viscoelastic && mat.viscoelastic->model != "kelvin_voigt")
      f2->fail("locking_free with a Prony series is not supported yet");
  }
  return mat;
}

/// `regions:` entry: `{region: NAME_OR_TAG, material: {young_modulus, poisson_ratio, density,
/// rayleigh_stiffness}}` — a region of the mesh and what of the body's material it changes.
RegionSpec parse_region(const Field& f) {
  const MapReader m = f.map({"region", "material"});
  RegionSpec r;
  r.where = location_of(m);
  const Field which = m.req("region");
  r.region_where = location_of(which);
  const std::string text = which.string();
  int32_t tag = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), tag);
  if (ec == std::errc() && ptr == text.data() + text.size()) r.tag = tag;
  else r.name = text;
  const MapReader mm =
      m.req("material").map({"young_modulus", "poisson_ratio", "density", "rayleigh_stiffness", "damage", "fibres"});
  Range nu = open_interval(-1, 0.5);
  nu.note_hi = "0.5 is incompressible; use 0.49 or lower";
  Range beta = physical_range(0, 1e3, "");
  beta.note_hi = "s: tissue is 1e-3..1e-1 s";
  // Each key optional: what a region does not give is its body's.
  auto optional = [&](const char* key, std::optional<double>& out, const Range& range) {
    if (!mm.opt(key)) return;
    double v = 0;
    mm.require(key, v, range);
    out = v;
  };
  optional("young_modulus", r.young_modulus,
           physical_range(1e-9, 1e12, "soft tissue is 1e2..1e6 Pa, a stiff tumour ~10x its organ"));
  optional("poisson_ratio", r.poisson_ratio, nu);
  optional("density", r.density, physical_range(1e-12, 1e6, "tissue is ~1000 kg/m^3 in SI"));
  optional("rayleigh_stiffness", r.rayleigh_stiffness, beta);
  if (auto d = mm.opt("damage")) r.damage = parse_damage(*d);
  if (auto d = mm.opt("fibres")) r.fibres = parse_fibres(*d);
  if (!r.young_modulus && !r.poisson_ratio && !r.density && !r.rayleigh_stiffness && !r.damage && !r.fibres)
    m.req("material").fail("a region's material changes at least one of young_modulus, poisson_ratio, density, "
                           "rayleigh_stiffness, damage, fibres (the rest is the body's)");
  return r;
}

BoxSpec parse_box(const Field& f) {
  const MapReader m = f.map({"min", "max"});
  BoxSpec box;
  const Field min = m.req("min");
  const Field max = m.req("max");
  box.min = min.vec3();
  box.max = max.vec3();
  for (int k = 0; k < 3; ++k) {
    if (box.min[k] > box.max[k]) {
      min.fail("box min[" + std::to_string(k) + "] = " + format_number(box.min[k]) +
               " is greater than max[" + std::to_string(k) + "] = " + format_number(box.max[k]) +
               ": min must be <= max componentwise");
    }
  }
  return box;
}

SurfaceSelectSpec parse_surface_select(const Field& f) {
  const MapReader m = f.map({"normal", "max_angle"});
  SurfaceSelectSpec s;
  const Field normal = m.req("normal");
  const Vec3 n = normal.vec3();
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (!(len > 1e-12) || !std::isfinite(len)) normal.fail("normal must be a finite non-zero vector");
  for (int k = 0; k < 3; ++k) s.normal[k] = n[k] / len;
  Range angle = greater_than(0);
  angle.hi = 180;
  angle.hi_closed = true;
  m.read("max_angle", s.max_angle_deg, angle);
  return s;
}

/// The selection part of a `fixed:` or `loads:` entry: `box`, `surface` or both (their
/// intersection), or `nodes` alone.
NodeSelection parse_selection(const MapReader& m) {
  NodeSelection sel;
  sel.where = location_of(m);
  const auto box = m.opt("box");
  const auto surface = m.opt("surface");
  const auto nodes = m.opt("nodes");
  if ((box || surface) && nodes) {
    const int later = std::max(box ? box->key_line() : surface->key_line(), nodes->key_line());
    throw InputError(m.file(), later, m.path(), "give 'nodes' alone, or 'box' and/or 'surface', not both kinds");
  }
  if (!box && !surface && !nodes) m.fail("a node selection needs 'box', 'surface' (or both) or 'nodes'");
  if (box) sel.box = parse_box(*box);
  if (surface) sel.surface = parse_surface_select(*surface);
  if (nodes) {
    const auto items = nodes->list();
    if (items.empty()) nodes->fail("empty node list: give at least one 0-based node index");
    Range index = at_least(0);
    index.note_lo = "node indices are 0-based";
    for (const auto& item : items) sel.nodes.push_back(item.integer<int>(index));
  }
  return sel;
}

NodeSelection parse_fixed(const Field& f) {
  const MapReader m = f.map({"box", "surface", "nodes", "axes"});
  NodeSelection sel = parse_selection(m);
  if (auto a = m.opt("axes")) {
    const auto items = a->list();
    if (items.empty()) a->fail("empty axes list: give some of x, y, z (or omit axes to fix all)");
    sel.axes = 0;
    for (const auto& item : items) {
      const std::string name = item.string();
      if (name == "x") sel.axes |= 1;
      else if (name == "y") sel.axes |= 2;
      else if (name == "z") sel.axes |= 4;
      else item.fail("unknown axis '" + name + "': expected x, y or z");
    }
  }
  return sel;
}

NodalLoadSpec parse_load(const Field& f) {
  const MapReader m = f.map({"box", "surface", "nodes", "force", "per_node"});
  NodalLoadSpec load;
  load.select = parse_selection(m);
  m.require("force", load.force);
  m.read("per_node", load.per_node);
  return load;
}

BodySpec parse_body(const MapReader& m, const Context& ctx) {
  BodySpec b;
  b.where = location_of(m);
  m.require("name", b.name);
  std::string mesh;
  m.require("mesh", mesh);
  b.mesh_where = location_of(m.req("mesh"));
  b.mesh_path = resolve_path(mesh, ctx.base_dir);
  m.read("scale", b.scale, physical_range(1e-9, 1e9, "a unit conversion: 1e-3 turns mm into m"));
  m.read("translate", b.translate);
  for (int k = 0; k < 3; ++k)
    if (!(std::fabs(b.translate[k]) <= 1e9))
      m.req("translate").fail(fmt::format("translate component {} = {} is out of range: must be within +-1e9", k,
                                          format_number(b.translate[k])));
  if (const auto f = m.opt("prestretch")) {
    if (f->yaml().IsSequence()) {
      f->get(b.prestretch);
    } else {
      double s = 1;
      f->get(s);
      b.prestretch = {s, s, s};
    }
    for (int k = 0; k < 3; ++k)
      if (!(b.prestretch[k] >= 0.5 && b.prestretch[k] <= 2.0))
        f->fail(fmt::format("prestretch {} = {} is out of range: the mesh's stretch over the body's rest shape, "
                            "0.5 to 2 (1: the mesh is at rest; a number, or [sx, sy, sz])",
                            "xyz"[k], format_number(b.prestretch[k])));
  }
  b.material = parse_material(m.req("material"));
  for (const auto& item : m.list("fixed")) b.fixed.push_back(parse_fixed(item));
  for (const auto& item : m.list("loads")) b.loads.push_back(parse_load(item));
  for (const auto& item : m.list("regions")) b.regions.push_back(parse_region(item));
  if (auto f = m.opt("visual")) {
    // `visual: FILE` or `visual: {mesh: FILE, max_distance: D}`.
    VisualSpec v;
    std::string path;
    if (f->is_scalar()) {
      path = f->string();
      v.where = location_of(*f);
    } else {
      const MapReader vm = f->map({"mesh", "max_distance"});
      vm.require("mesh", path);
      v.where = location_of(vm.req("mesh"));
      vm.read("max_distance", v.max_distance, at_least(0));
    }
    v.mesh_path = resolve_path(path, ctx.base_dir);
    b.visual = v;
  }
  return b;
}

/// A colour: three numbers in 0..1 (sRGB).
Vec3 parse_color(const Field& f) {
  const Vec3 c = f.vec3();
  for (double x : c)
    if (!(x >= 0 && x <= 1)) f.fail("colour components must be in 0..1 (sRGB), got " + format_number(x));
  return c;
}

RenderSpec parse_render(const Field& f) {
  const MapReader m = f.map({"camera", "view_direction", "light", "colors", "color_field", "color_range",
                             "wireframe", "contacts"});
  RenderSpec r;
  if (auto c = m.opt("camera")) {
    const MapReader cm = c->map({"position", "target", "up", "fov"});
    if (cm.opt("position") || cm.opt("target")) {
      cm.require("position", r.camera_position);
      cm.require("target", r.camera_target);
      r.has_camera = true;
      const Vec3 d{r.camera_target[0] - r.camera_position[0], r.camera_target[1] - r.camera_position[1],
                   r.camera_target[2] - r.camera_position[2]};
      if (d[0] == 0 && d[1] == 0 && d[2] == 0) cm.req("target").fail("target must differ from position");
    }
    if (auto u = cm.opt("up")) {
      const Vec3 up = u->vec3();
      if (up[0] == 0 && up[1] == 0 && up[2] == 0) u->fail("up must not be zero");
      r.camera_up = up;
    }
    cm.read("fov", r.fov_deg, open_interval(0, 170));
  }
  if (auto v = m.opt("view_direction")) {
    r.view_direction = v->vec3();
    if (r.view_direction[0] == 0 && r.view_direction[1] == 0 && r.view_direction[2] == 0)
      v->fail("view_direction must not be zero");
  }
  if (auto l = m.opt("light")) {
    const MapReader lm = l->map({"direction"});
    lm.read("direction", r.light_direction);
  }
  if (auto c = m.opt("colors")) {
    const MapReader cm = c->map({"tissue", "background"});
    if (auto t = cm.opt("tissue")) r.tissue_color = parse_color(*t);
    if (auto b = cm.opt("background")) r.background_color = parse_color(*b);
  }
  m.read("color_field", r.color_field, kColorFields);
  if (auto cr = m.opt("color_range")) {
    const auto items = cr->list();
    if (items.size() != 2) cr->fail("expected [min, max]");
    r.color_min = items[0].number();
    r.color_max = items[1].number();
    if (!(r.color_max > r.color_min)) cr->fail("max must be greater than min");
  }
  m.read("wireframe", r.wireframe);
  m.read("contacts", r.contacts);
  return r;
}

ProbeSpec parse_probe(const MapReader& m) {
  ProbeSpec p;
  p.where = location_of(m);
  m.require("name", p.name);
  m.require("body", p.body);
  m.require("point", p.point);
  return p;
}

RunSpec parse_run(const Field& f) {
  const MapReader m = f.map({"duration", "steps"});
  RunSpec run;
  const auto duration = m.opt("duration");
  const auto steps = m.opt("steps");
  if (duration && steps) {
    const int later = std::max(duration->key_line(), steps->key_line());
    throw InputError(m.file(), later, m.path(), "give either 'duration' or 'steps', not both");
  }
  m.read("duration", run.duration, greater_than(0));
  m.read("steps", run.steps, greater_than(0));
  return run;
}

BodyContactSpec parse_body_contact(const Field& f) {
  BodyContactSpec c;
  c.where = location_of(f);
  if (f.is_null()) return c;  // `body_contact:` alone: automatic settings
  const MapReader m = f.map({"stiffness", "max_depth"});
  m.read("stiffness", c.stiffness, at_least(0));
  m.read("max_depth", c.max_depth, at_least(0));
  return c;
}

CheckSpec parse_check(const Field& f) {
  const MapReader m = f.map({"max_error", "mean_error"});
  CheckSpec c;
  m.read("max_error", c.max_error, greater_than(0));
  m.read("mean_error", c.mean_error, greater_than(0));
  return c;
}

const Choices<InvalidCommandPolicy> kInvalidPolicies = {{"reject", InvalidCommandPolicy::Reject},
                                                        {"clamp", InvalidCommandPolicy::Clamp}};

const Choices<ToolShape> kToolShapes = {{"sphere", ToolShape::Sphere},
                                        {"probe", ToolShape::Probe},
                                        {"blade", ToolShape::Blade},
                                        {"grasper", ToolShape::Grasper}};

/// Tool quantities, whatever the scene's units (SI or mm-tonne-s): bounded, so no value the
/// loader accepts overflows the contact, coupling or speed arithmetic at tick 0 (issue 15).
const Range kToolLength = physical_range(1e-9, 1e9, "a length: instruments are ~1e-4..1e-1 m (0.1..100 mm)");
const Range kToolStiffness = physical_range(1e-9, 1e12, "N/m: tissue contact is ~1e1..1e5 N/m (1e-2..1e2 N/mm)");
const Range kToolDamping = physical_range(0, 1e9, "N*s/m");
const Range kToolForce = physical_range(1e-9, 1e9, "N: haptic devices render ~1..40 N");

ToolEntry parse_tool(const MapReader& m, const Context& ctx) {
  ToolEntry t;
  t.where = location_of(m);
  m.require("name", t.spec.name);
  std::string script;
  if (m.read("script", script)) t.script = resolve_path(script, ctx.base_dir);
  if (auto w = m.opt("workspace")) {
    const BoxSpec b = parse_box(*w);
    t.spec.workspace_min = b.min;
    t.spec.workspace_max = b.max;
  }
  if (auto f = m.opt("pose")) {
    const MapReader pm = f->map({"position", "orientation"});
    t.has_pose = true;
    if (auto p = pm.opt("position")) t.spec.rest_pose.position = p->vec3();
    if (auto o = pm.opt("orientation")) {
      const std::vector<Field> q = o->list();
      if (q.size() != 4) o->fail("expected a unit quaternion [w, x, y, z] (4 numbers), got " + std::to_string(q.size()));
      double n2 = 0;
      for (int k = 0; k < 4; ++k) {
        t.spec.rest_pose.orientation[k] = q[k].number();
        n2 += t.spec.rest_pose.orientation[k] * t.spec.rest_pose.orientation[k];
      }
      if (!(std::fabs(std::sqrt(n2) - 1.0) <= 1e-3))
        o->fail("|q| = " + format_number(std::sqrt(n2)) + ": orientation must be a unit quaternion [w, x, y, z]");
      for (double& v : t.spec.rest_pose.orientation) v /= std::sqrt(n2);
    }
  }
  m.read("max_speed", t.spec.max_speed, physical_range(1e-9, 1e9, "a speed: hands move ~0.01..1 m/s (10..1000 mm/s)"));
  m.read("timeout", t.spec.timeout, physical_range(1e-6, 1e6, "s: how long a silent client's pose is held"));
  m.read("on_invalid", t.spec.on_invalid, kInvalidPolicies);
  if (auto f = m.opt("shape")) {
    const MapReader sm = f->map({"type", "radius", "shaft_radius", "length"});
    sm.require("type", t.spec.shape, kToolShapes);
    sm.require("radius", t.spec.radius, kToolLength);
    if (t.spec.shape == ToolShape::Probe) {
      sm.require("length", t.spec.shaft_length, kToolLength);
      t.spec.shaft_radius = t.spec.radius;
      sm.read("shaft_radius", t.spec.shaft_radius, kToolLength);
      if (t.spec.shaft_radius > t.spec.radius)
        sm.req("shaft_radius").fail("shaft_radius = " + format_number(t.spec.shaft_radius) +
                                    " must not exceed the tip radius " + format_number(t.spec.radius));
    } else if (t.spec.shape == ToolShape::Blade || t.spec.shape == ToolShape::Grasper) {
      sm.require("length", t.spec.shaft_length, kToolLength);
      if (sm.opt("shaft_radius")) sm.req("shaft_radius").fail("'shaft_radius' belongs to type probe");
    } else if (sm.opt("length") || sm.opt("shaft_radius")) {
      sm.fail("'length' and 'shaft_radius' belong to types probe, blade, grasper (a sphere has only a radius)");
    }
  }
  if (auto f = m.opt("contact")) {
    const MapReader cm = f->map({"stiffness", "damping", "friction"});
    cm.read("stiffness", t.spec.contact_stiffness, kToolStiffness);
    cm.read("damping", t.spec.contact_damping, kToolDamping);
    cm.read("friction", t.spec.friction, physical_range(0, 10, "a Coulomb coefficient: tissue on steel is ~0.1..1"));
  }
  m.read("max_force", t.spec.max_force, kToolForce);
  if (auto f = m.opt("coupling")) {
    const MapReader cm = f->map({"stiffness", "damping"});
    cm.require("stiffness", t.spec.coupling_stiffness, kToolStiffness);
    cm.read("damping", t.spec.coupling_damping, kToolDamping);
    if (t.spec.shape == ToolShape::None)
      f->fail("a coupled tool needs a shape (the proxy is what touches the tissue)");
  }
  if (auto f = m.opt("grasp")) {
    const MapReader gm = f->map({"close", "open", "reach", "stiffness"});
    t.spec.can_grasp = true;
    gm.read("close", t.spec.grasp_close, physical_range(0, 6.3, "rad: a jaw angle, 0 closed .. ~1.5 wide open"));
    gm.read("open", t.spec.grasp_open, physical_range(1e-9, 6.3, "rad: a jaw angle, 0 closed .. ~1.5 wide open"));
    gm.read("reach", t.spec.grasp_reach, physical_range(1e-9, 1e3, "a multiple of the tool's radius"));
    gm.read("stiffness", t.spec.grasp_stiffness, kToolStiffness);
    if (t.spec.grasp_open <= t.spec.grasp_close)
      gm.req("open").fail("open must be greater than close (hysteresis), got open = " +
                          format_number(t.spec.grasp_open) + ", close = " + format_number(t.spec.grasp_close));
    if (t.spec.shape == ToolShape::None)
      f->fail("a grasping tool needs a shape (shape: {type: sphere, radius: ...})");
  }
  if (auto f = m.opt("cut")) {
    const MapReader cm = f->map({"toughness", "height"});
    t.spec.cuts = true;
    cm.read("toughness", t.spec.cut_toughness,
            physical_range(0, 1e6, "J/m^2: energy per cut area, liver ~1e2..3e2, skin ~1e3..3e3"));
    cm.read("height", t.spec.blade_height, kToolLength);
    if (t.spec.shape != ToolShape::Blade)
      f->fail("only a blade cuts (shape: {type: blade, radius: ..., length: ...}): its edge is what sweeps the cut");
    if (t.spec.can_grasp) f->fail("a cutting blade cannot also grasp");
  }
  return t;
}

/// Names must be unique within a list; reports the second occurrence.
void check_unique_name(std::map<std::string, int>& seen, const std::string& name,
                       const Field& name_field, const char* what) {
  const auto [it, inserted] = seen.emplace(name, name_field.line());
  if (!inserted) {
    name_field.fail(std::string("duplicate ") + what + " name '" + name +
                    "' (first defined at line " + std::to_string(it->second) + ")");
  }
}

/// A unit quaternion [w, x, y, z] (within 1e-3 of unit length; normalised).
std::array<double, 4> parse_unit_quaternion(const Field& o) {
  const std::vector<Field> q = o.list();
  if (q.size() != 4) o.fail("expected a unit quaternion [w, x, y, z] (4 numbers), got " + std::to_string(q.size()));
  std::array<double, 4> out{};
  double n2 = 0;
  for (int k = 0; k < 4; ++k) {
    out[size_t(k)] = q[size_t(k)].number();
    n2 += out[size_t(k)] * out[size_t(k)];
  }
  if (!(std::fabs(std::sqrt(n2) - 1.0) <= 1e-3))
    o.fail("|q| = " + format_number(std::sqrt(n2)) + ": orientation must be a unit quaternion [w, x, y, z]");
  for (double& v : out) v /= std::sqrt(n2);
  return out;
}

const Choices<RigidShapeKind> kRigidShapes = {{"sphere", RigidShapeKind::Sphere},
                                                    {"box", RigidShapeKind::Box},
                                                    {"capsule", RigidShapeKind::Capsule},
                                                    {"mesh", RigidShapeKind::Mesh},
                                                    {"needle", RigidShapeKind::Needle}};

RigidBodySpec parse_rigid_body(const MapReader& m, const Context& ctx) {
  RigidBodySpec r;
  r.where = {ctx.file, m.line()};
  m.require("name", r.name);
  const Field shape = m.req("shape");
  r.shape_where = {ctx.file, shape.key_line()};
  const MapReader sm = shape.map({"type", "radius", "length", "size", "file", "scale", "wire_radius", "angle"});
  sm.require("type", r.shape, kRigidShapes);
  const Range length = physical_range(1e-6, 10, "m: a suture needle's wire is ~1e-4 m, an instrument ~0.01..0.3 m");
  auto only = [&](std::initializer_list<const char*> keys) {
    for (const char* k : {"radius", "length", "size", "file", "scale", "wire_radius", "angle"}) {
      bool ok = false;
      for (const char* a : keys) ok = ok || std::string(a) == k;
      if (!ok)
        if (auto f = sm.opt(k)) f->fail(std::string("a ") + sm.req("type").string() + " has no " + k);
    }
  };
  switch (r.shape) {
    case RigidShapeKind::Sphere:
      only({"radius"});
      sm.require("radius", r.radius, length);
      break;
    case RigidShapeKind::Capsule:
      only({"radius", "length"});
      sm.require("radius", r.radius, length);
      sm.require("length", r.length, physical_range(0, 10, "m: the cylinder between the two hemispheres"));
      break;
    case RigidShapeKind::Box: {
      only({"size"});
      const Field f = sm.req("size");
      r.size = f.vec3();
      for (double v : r.size)
        if (!(v >= 1e-6 && v <= 10)) f.fail("box sizes must be within 1e-6..10 m, got " + format_number(v));
      break;
    }
    case RigidShapeKind::Needle: {
      only({"wire_radius", "length", "radius", "angle"});
      sm.require("wire_radius", r.wire_radius, physical_range(1e-6, 0.01, "m: suture needles' wires are ~1e-4..1e-3 m"));
      const auto len = sm.opt("length"), rad = sm.opt("radius"), ang = sm.opt("angle");
      if (len && (rad || ang)) (rad ? *rad : *ang).fail("a needle is straight (length) or curved (radius and angle), not both");
      if (!len && !rad && !ang)
        shape.fail("a needle without a tip: give its length (straight, along z) or its radius and angle (curved)");
      if (len) {
        sm.require("length", r.length, physical_range(1e-4, 1, "m: the wire from tail to tip"));
      } else {
        sm.require("radius", r.radius, physical_range(1e-4, 1, "m: the arc's radius (suture needles ~3..20 mm)"));
        sm.require("angle", r.angle_deg, physical_range(1, 360, "degrees of arc: 135 is a 3/8 circle, 180 a 1/2 circle"));
        if (!(r.radius > r.wire_radius)) sm.req("radius").fail("a curved needle's radius must exceed its wire_radius");
      }
      break;
    }
    case RigidShapeKind::Mesh: {
      only({"file", "scale"});
      std::string file;
      sm.require("file", file);
      r.mesh_path = resolve_path(file, ctx.base_dir);
      sm.read("scale", r.mesh_scale, physical_range(1e-9, 1e9, "multiplies the file's coordinates (0.001: mm to m)"));
      break;
    }
  }
  m.require("density", r.density, physical_range(1, 1e5, "kg/m^3: steel ~7800, plastic ~1000..1400, water 1000"));
  if (auto f = m.opt("pose")) {
    const MapReader pm = f->map({"position", "orientation"});
    if (auto p = pm.opt("position")) r.position = p->vec3();
    if (auto o = pm.opt("orientation")) r.orientation = parse_unit_quaternion(*o);
  }
  if (auto f = m.opt("velocity")) {
    const MapReader vm = f->map({"linear", "angular"});
    if (auto v = vm.opt("linear")) r.velocity = v->vec3();
    if (auto w = vm.opt("angular")) r.angular_velocity = w->vec3();
  }
  m.read("fixed", r.fixed);
  if (auto f = m.opt("contact")) {
    const MapReader cm = f->map({"stiffness", "damping", "friction"});
    cm.read("stiffness", r.contact_stiffness,
            physical_range(1e-9, 1e12, "Pa/m: contact pressure per metre of penetration (automatic: 100*E/feature)"));
    cm.read("damping", r.contact_damping, physical_range(0, 1e9, "Pa*s/m: contact pressure per penetration rate"));
    cm.read("friction", r.friction, physical_range(0, 10, "a Coulomb coefficient: tissue on steel is ~0.1..1"));
  }
  if (r.fixed)
    if (auto f = m.opt("velocity")) f->fail("a fixed body does not move: remove its velocity, or fixed");
  return r;
}

ThreadSpec parse_thread(const MapReader& m, const Context& ctx) {
  ThreadSpec t;
  t.where = {ctx.file, m.line()};
  m.require("name", t.name);
  m.require("length", t.length, physical_range(1e-4, 10, "m: a suture is ~0.1..0.75 m long"));
  {
    const Field f = m.req("segments");
    t.segments = f.integer<int>();
    if (t.segments < 2) f.fail("a thread needs at least 2 segments (its bending acts at the nodes between them), got " + std::to_string(t.segments));
    if (t.segments > 100000) f.fail("at most 100000 segments, got " + std::to_string(t.segments));
  }
  m.require("diameter", t.diameter,
            physical_range(1e-6, 0.01, "m: USP 3-0 suture is 0.2..0.25 mm, 5-0 0.1 mm, 0 0.35..0.4 mm"));
  m.require("young_modulus", t.young_modulus,
            physical_range(1e3, 1e12, "Pa: polyglactin and nylon sutures are ~1..10 GPa, silk ~5..10 GPa"));
  m.require("density", t.density, physical_range(1, 1e5, "kg/m^3: sutures are ~1000..1500"));
  const double solid_ei = rod_solid_flexural_rigidity(t.young_modulus, t.diameter);
  m.read("bending_stiffness", t.bending_stiffness,
         physical_range(1e-20, 1e3, "N*m^2: a 3-0 monofilament (0.2 mm, E 5 GPa) ~4e-7, a braid of the same ~1e-9..1e-8"));
  if (t.bending_stiffness > solid_ei * (1 + 1e-12))
    m.req("bending_stiffness")
        .fail(fmt::format("{} N*m^2 is more than a solid rod of this diameter and young_modulus bends with "
                          "(E*pi*d^4/64 = {:.3e} N*m^2): a thread is at most solid",
                          format_number(t.bending_stiffness), solid_ei));
  // The bending over the stretching stiffness, EI/(EA·l²), at least a solid rod's at
  // kThreadMaxSegmentRatio diameters a segment, 1/(16·ratio²): the longest segment 4·ratio·√(EI/EA).
  const double ei = rod_flexural_rigidity(t.young_modulus, t.diameter, t.bending_stiffness);
  const double seg = t.length / t.segments;
  const double max_seg = 4 * kThreadMaxSegmentRatio * std::sqrt(ei / rod_axial_rigidity(t.young_modulus, t.diameter));
  if (seg > max_seg * (1 + 1e-9))
    m.req("segments").fail(fmt::format(
        "segments of {} m are {} diameters long; at most {} m ({} diameters) for this thread: beyond, the bending "
        "stiffness E*I/l^3 is below {:.1e} of the stretching stiffness E*A/l (for a solid rod their ratio is "
        "d^2 / (16 l^2)), under what the step's solves resolve — use at least {} segments",
        format_number(seg), format_number(seg / t.diameter), format_number(max_seg),
        format_number(max_seg / t.diameter), 1.0 / (16 * kThreadMaxSegmentRatio * kThreadMaxSegmentRatio),
        static_cast<long>(std::ceil(t.length / max_seg * (1 - 1e-9)))));
  const auto path = m.opt("path");
  if (path) {
    if (m.opt("start") || m.opt("direction")) path->fail("a thread starts straight (start, direction) or along a path, not both");
    const std::vector<Field> pts = path->list();
    if (pts.size() < 2) path->fail("a path needs at least 2 points, got " + std::to_string(pts.size()));
    double len = 0;
    for (size_t i = 0; i < pts.size(); ++i) {
      t.path.push_back(pts[i].vec3());
      if (i > 0) {
        const Vec3 &a = t.path[i - 1], &b = t.path[i];
        len += std::sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
      }
    }
    if (std::abs(len - t.length) > 1e-6)
      path->fail(fmt::format("the path is {} m long, the thread {} m: they must agree (within 1e-6 m)",
                             format_number(len), format_number(t.length)));
  } else if (!m.opt("start") && !m.opt("direction") && m.opt("attach")) {
    t.from_needle = true;  // checked below: the first end must be attached to a needle
  } else {
    m.require("start", t.start);
    if (auto f = m.opt("direction")) {
      const Vec3 d = f->vec3();
      const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (!(len > 1e-12) || !std::isfinite(len)) f->fail("the direction must be a finite non-zero vector");
      for (int k = 0; k < 3; ++k) t.direction[k] = d[k] / len;
    }
  }
  if (auto f = m.opt("damping")) {
    const MapReader dm = f->map({"rayleigh_mass", "rayleigh_stiffness"});
    dm.read("rayleigh_mass", t.rayleigh_mass, physical_range(0, 1e6, "1/s"));
    dm.read("rayleigh_stiffness", t.rayleigh_stiffness, physical_range(0, 10, "s"));
  }
  m.read("friction", t.friction, physical_range(0, 2, "Coulomb coefficient of the thread on tissue: ~0.1..0.4"));
  m.read("contact_stiffness", t.contact_stiffness,
         physical_range(1e-3, 1e15, "Pa/m: pressure on the tissue per metre of the thread's penetration (automatic: "
                                    "10*E_max/diameter)"));
  if (auto f = m.opt("fixed"))
    for (const Field& e : f->list()) {
      const std::string which = e.string();
      if (which == "first") t.fix_first = true;
      else if (which == "last") t.fix_last = true;
      else e.fail("expected first or last (the thread's end nodes), got " + e.got());
    }
  if (auto f = m.opt("attach")) {
    for (const Field& e : f->list()) {
      const MapReader am = e.map({"end", "needle", "tissue"});
      ThreadSpec::Attach a;
      a.where = {ctx.file, am.line()};
      const Field end = am.req("end");
      const std::string which = end.string();
      if (which == "last") a.last = true;
      else if (which != "first") end.fail("expected first or last (the thread's end nodes), got " + end.got());
      const auto needle = am.opt("needle"), tissue = am.opt("tissue");
      if (needle && tissue) tissue->fail("an end is attached to a needle or to a tissue body, not both");
      if (!needle && !tissue) e.fail("an attachment names a needle (needle: NAME) or a tissue body (tissue: NAME)");
      a.needle = static_cast<bool>(needle);
      a.target = (needle ? *needle : *tissue).string();
      for (const ThreadSpec::Attach& b : t.attach)
        if (b.last == a.last) end.fail("the thread's " + which + " end is attached twice");
      if (a.last ? t.fix_last : t.fix_first)
        end.fail("the thread's " + which + " end is fixed (fixed: [" + which + "]) and attached: one or the other");
      t.attach.push_back(a);
    }
  }
  if (t.from_needle && !std::any_of(t.attach.begin(), t.attach.end(), [](const ThreadSpec::Attach& a) {
        return a.needle && !a.last;
      }))
    m.fail("missing `start`: a thread starts at `start` (along `direction`) or along a `path` — or, with its first "
           "end attached to a needle (attach: [{end: first, needle: NAME}]), at the needle's tail");
  return t;
}

ScenarioSpec parse_root(const MapReader& m, const Context& ctx) {
  ScenarioSpec s;
  s.file = ctx.file;
  m.read("name", s.name);
  m.read("time_step", s.time_step,
         physical_range(1e-7, 1.0, "s: a step above 1 s resolves no tissue motion; below 1e-7 s h^2*K vanishes "
                                   "beside the mass"));
  m.read("gravity", s.gravity);
  for (int k = 0; k < 3; ++k)
    if (!(std::fabs(s.gravity[k]) <= 1e6))
      m.req("gravity").fail(fmt::format("gravity component {} = {} is out of range: must be within +-1e6 (9.81 m/s^2 "
                                        "is 9810 mm/s^2)",
                                        k, format_number(s.gravity[k])));
  if (auto f = m.opt("solver")) s.solver = parse_solver(*f);

  const Field bodies = m.req("bodies");
  const auto body_items = bodies.list();
  if (body_items.empty()) bodies.fail("at least one body is required");
  std::map<std::string, int> body_names;
  for (const auto& item : body_items) {
    const MapReader bm =
        item.map({"name", "mesh", "scale", "translate", "prestretch", "material", "regions", "fixed", "loads", "visual"});
    s.bodies.push_back(parse_body(bm, ctx));
    check_unique_name(body_names, s.bodies.back().name, bm.req("name"), "body");
  }

  std::map<std::string, int> probe_names;
  std::vector<std::string> known_bodies;
  for (const auto& b : s.bodies) known_bodies.push_back(b.name);
  for (const auto& item : m.list("probes")) {
    const MapReader pm = item.map({"name", "body", "point"});
    s.probes.push_back(parse_probe(pm));
    const ProbeSpec& p = s.probes.back();
    check_unique_name(probe_names, p.name, pm.req("name"), "probe");
    if (body_names.count(p.body) == 0) {
      pm.req("body").fail("unknown body '" + p.body + "': " + did_you_mean(p.body, known_bodies) +
                          "bodies are: " + join(known_bodies));
    }
  }

  std::map<std::string, int> tool_names;
  for (const auto& item : m.list("tools")) {
    const MapReader tm = item.map({"name", "script", "pose", "workspace", "max_speed", "timeout", "on_invalid",
                                   "shape", "contact", "max_force", "grasp", "coupling", "cut"});
    s.tools.push_back(parse_tool(tm, ctx));
    check_unique_name(tool_names, s.tools.back().spec.name, tm.req("name"), "tool");
  }

  std::map<std::string, int> rigid_names;
  for (const auto& item : m.list("rigid_bodies")) {
    const MapReader rm = item.map({"name", "shape", "density", "pose", "velocity", "fixed", "contact"});
    s.rigid_bodies.push_back(parse_rigid_body(rm, ctx));
    check_unique_name(rigid_names, s.rigid_bodies.back().name, rm.req("name"), "rigid body");
    if (body_names.count(s.rigid_bodies.back().name))
      rm.req("name").fail("'" + s.rigid_bodies.back().name + "' is already the name of a tissue body");
  }

  std::map<std::string, int> thread_names;
  for (const auto& item : m.list("threads")) {
    const MapReader tm = item.map({"name", "length", "segments", "diameter", "young_modulus", "density", "start",
                                   "direction", "path", "damping", "fixed", "attach", "friction", "contact_stiffness",
                                   "bending_stiffness"});
    s.threads.push_back(parse_thread(tm, ctx));
    const std::string& name = s.threads.back().name;
    check_unique_name(thread_names, name, tm.req("name"), "thread");
    if (body_names.count(name) || rigid_names.count(name))
      tm.req("name").fail("'" + name + "' is already the name of a tissue or rigid body");
    const std::vector<Field> attach = tm.opt("attach") ? tm.req("attach").list() : std::vector<Field>{};
    for (size_t ai = 0; ai < attach.size(); ++ai) {
      const ThreadSpec::Attach& a = s.threads.back().attach[ai];
      const MapReader am = attach[ai].map({"end", "needle", "tissue"});
      if (a.needle) {
        std::vector<std::string> needles;
        for (const RigidBodySpec& r : s.rigid_bodies)
          if (r.shape == RigidShapeKind::Needle) needles.push_back(r.name);
        if (std::find(needles.begin(), needles.end(), a.target) != needles.end()) continue;
        am.req("needle").fail(
            (rigid_names.count(a.target) ? "'" + a.target + "' is a rigid body but not a needle: "
                                         : "unknown needle '" + a.target + "': " + did_you_mean(a.target, needles)) +
            (needles.empty() ? std::string("the scenario has no needle") : "needles are: " + join(needles)));
      } else if (!body_names.count(a.target)) {
        am.req("tissue").fail("unknown tissue body '" + a.target + "': " + did_you_mean(a.target, known_bodies) +
                              "bodies are: " + join(known_bodies));
      }
    }
  }

  if (auto f = m.opt("body_contact")) {
    if (s.bodies.size() < 2) f->fail("body_contact needs at least two bodies (this scenario has one)");
    s.body_contact = parse_body_contact(*f);
  }
  if (auto f = m.opt("run")) s.run = parse_run(*f);
  if (auto f = m.opt("check")) s.check = parse_check(*f);
  if (auto f = m.opt("render")) s.render = parse_render(*f);
  return s;
}

}  // namespace

ScenarioSpec parse_scenario(const std::string& yaml_text, const std::string& file,
                            const std::string& base_dir) {
  const YAML::Node root = yaml::load_single_document(yaml_text, file);
  if (!root || root.IsNull()) throw InputError(file, 0, "", "scenario file is empty");

  const Context ctx{file, base_dir};
  const int root_line = root.Mark().line >= 0 ? root.Mark().line + 1 : 1;
  const Field root_field(&ctx.file, root, "", root_line);
  const MapReader m = root_field.map(
      {"name", "time_step", "gravity", "solver", "bodies", "probes", "tools", "rigid_bodies", "threads", "body_contact", "run",
       "check", "render"});
  return parse_root(m, ctx);
}

ScenarioSpec load_scenario(const std::string& path) {
  namespace fs = std::filesystem;
  if (is_sofa_scene_path(path)) {
    // A SOFA scene: translated (or refused, naming the scene's line) and then loaded as the
    // scenario it translates to; `stroma run --explain` prints that scenario.
    const SofaTranslation t = translate_sofa_scene_file(path);
    return parse_scenario(t.yaml, path + " (as translated: stroma run --explain)", fs::path(path).parent_path().string());
  }
  std::error_code ec;
  if (fs::is_directory(path, ec))
    throw InputError(path, 0, "", "cannot open scenario file: it is a directory");
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int err = errno;
    throw InputError(path, 0, "",
                     std::string("cannot open scenario file") +
                         (err != 0 ? std::string(": ") + std::strerror(err) : std::string()));
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw InputError(path, 0, "", "cannot read scenario file");
  return parse_scenario(text.str(), path, fs::path(path).parent_path().string());
}

}  // namespace stroma
