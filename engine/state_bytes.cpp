#include "engine/state_bytes.hpp"

#include <algorithm>
#include <cstring>
#include <type_traits>

#include "tissue/input_error.hpp"
#include "tissue/warped_preconditioner.hpp"

namespace stroma {

namespace {

constexpr char kMagic[12] = {'S', 'T', 'R', 'O', 'M', 'A', '-', 'S', 'T', 'A', 'T', 'E'};
/// 2: the solver's history (SolverHistory) after the step counter.
constexpr uint32_t kVersion = 10;  // 3: ToolState.posed; 4: rigid bodies; 5: a tool's grasp of a body; 6: needles;
                                  // 7: refresh ids as presence flags (one encoding per state); track
                                  // points name their body (needles through two bites); 8: a tool's
                                  // grasp of a thread; threads' punctures; 9: the thread segment
                                  // a tool let go of; 10: the kept element stiffness blocks
const char* const kWhat = "<state bytes>";

static_assert(std::is_trivially_copyable_v<ToolState>, "ToolState is copied as bytes");
static_assert(std::is_trivially_copyable_v<ElementParams>, "ElementParams is hashed as bytes");

/// FNV-1a, 64 bits: a fingerprint, not a defence against a crafted collision.
struct Fnv {
  uint64_t h = 1469598103934665603ull;
  void add(const void* p, size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
  }
  template <class T>
  void value(const T& v) { add(&v, sizeof v); }
  template <class T>
  void array(const std::vector<T>& v) {
    value(static_cast<uint64_t>(v.size()));
    if (!v.empty()) add(v.data(), v.size() * sizeof(T));
  }
};

class Writer {
 public:
  template <class T>
  void value(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    out_.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  template <class T>
  void array(const std::vector<T>& v) {
    value(static_cast<uint64_t>(v.size()));
    if (!v.empty()) out_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  std::string take() { return std::move(out_); }

 private:
  std::string out_;
};

class Reader {
 public:
  explicit Reader(const std::string& b) : b_(b) {}
  template <class T>
  void value(T& v, const char* field) {
    need(sizeof v, field);
    std::memcpy(&v, b_.data() + at_, sizeof v);
    at_ += sizeof v;
  }
  /// A byte that must be 0 or 1 (any other value would re-encode differently).
  bool flag(const char* field) {
    uint8_t b = 0;
    value(b, field);
    if (b > 1) throw InputError(kWhat, 0, field, "a flag of " + std::to_string(b) + " (0 or 1)");
    return b == 1;
  }
  template <class T>
  void array(std::vector<T>& v, const char* field) {
    uint64_t n = 0;
    value(n, field);
    // Checked against the bytes left before anything is allocated.
    if (n > (b_.size() - at_) / sizeof(T))
      throw InputError(kWhat, 0, field, "count " + std::to_string(n) + " is more than the bytes left hold");
    v.resize(static_cast<size_t>(n));
    if (n > 0) std::memcpy(v.data(), b_.data() + at_, static_cast<size_t>(n) * sizeof(T));
    at_ += static_cast<size_t>(n) * sizeof(T);
  }
  void finish() const {
    if (at_ != b_.size())
      throw InputError(kWhat, 0, "trailing bytes", std::to_string(b_.size() - at_) + " bytes after the state");
  }

 private:
  void need(size_t n, const char* field) const {
    if (b_.size() - at_ < n) throw InputError(kWhat, 0, field, "truncated: the bytes end inside it");
  }
  const std::string& b_;
  size_t at_ = 0;
};

}  // namespace

namespace {

/// Padding-free plain records, hashed as their bytes (a new field changes the size: the
/// static_asserts below then ask for a look at model_fingerprint).
static_assert(sizeof(ElementParams) == 4 * sizeof(int32_t) + 13 * sizeof(double), "ElementParams has padding");
static_assert(sizeof(FibreParams) == 5 * sizeof(double), "FibreParams has padding");
static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 has padding");
static_assert(sizeof(RigidState) == 13 * sizeof(double), "RigidState has padding (or a new field: hash and encode it)");

void hash_rigid(Fnv& f, const RigidBodyModel& b) {
  f.array(std::vector<char>(b.name.begin(), b.name.end()));
  f.value(static_cast<int>(b.shape));
  for (const double v : {b.radius, b.length, b.size[0], b.size[1], b.size[2], b.mass.mass, b.mass.volume})
    f.value(v);
  for (const double v : b.mass.inertia) f.value(v);
  for (const double v : b.shape_origin) f.value(v);
  f.array(b.surface_vertices);
  f.array(b.surface_triangles);
  f.value(static_cast<uint8_t>(b.fixed));
  f.value(b.initial);
  for (const double v : {b.contact_stiffness, b.contact_damping, b.friction}) f.value(v);
  f.value(static_cast<uint8_t>(b.needle.curved));
  for (const double v : {b.needle.wire_radius, b.needle.length, b.needle.arc_radius, b.needle.angle}) f.value(v);
  f.value(b.track_capacity);
}

void hash_stepper(Fnv& f, const StepperSettings& s) {
  f.value(static_cast<int>(s.integrator));
  f.value(static_cast<int>(s.linear_solver));
  f.value(static_cast<int>(s.preconditioner));
  f.value(s.max_iterations);
  f.value(s.tolerance);
  f.value(static_cast<int>(s.warm_start));
  f.value(s.static_tolerance);
  f.value(s.static_max_newton);
  f.value(s.newton_iterations);
  f.value(s.newton_tolerance);
  f.value(s.preconditioner_refresh);
  f.value(static_cast<uint8_t>(s.refresh_follows_pace));
  f.value(s.stiffness_every);
}

void hash_tool(Fnv& f, const ToolSpec& t) {
  f.array(std::vector<char>(t.name.begin(), t.name.end()));
  for (const double v : {t.workspace_min[0], t.workspace_min[1], t.workspace_min[2], t.workspace_max[0],
                         t.workspace_max[1], t.workspace_max[2], t.max_speed, t.timeout, t.radius, t.shaft_radius,
                         t.shaft_length, t.contact_stiffness, t.contact_damping, t.friction, t.max_force,
                         t.coupling_stiffness, t.coupling_damping, t.grasp_close, t.grasp_open, t.grasp_reach,
                         t.grasp_stiffness, t.cut_toughness, t.blade_height})
    f.value(v);
  for (const double v : t.rest_pose.position) f.value(v);
  for (const double v : t.rest_pose.orientation) f.value(v);
  f.value(static_cast<int>(t.on_invalid));
  f.value(static_cast<int>(t.shape));
  f.value(static_cast<uint8_t>(t.can_grasp));
  f.value(static_cast<uint8_t>(t.cuts));
}

void hash_damage(Fnv& f, const DamageModel& d) {
  f.value(static_cast<uint8_t>(d.enabled));
  f.value(static_cast<int>(d.measure));
  f.value(d.warning);
  f.value(d.onset);
  f.value(d.rupture);
}

void hash_constants(Fnv& f, const ModelConstants& m) {
  hash_stepper(f, m.stepper);
  f.value(m.time_step);
  f.value(m.fem_every);
  f.value(static_cast<uint8_t>(m.haptic_secant));
  f.value(static_cast<uint8_t>(m.substep_on_cg_cap));
  f.value(m.time_budget);
  f.value(m.max_step_displacement);
  f.value(static_cast<uint64_t>(m.tools.size()));
  for (const ToolSpec& t : m.tools) hash_tool(f, t);
  f.value(static_cast<uint64_t>(m.rigid_bodies.size()));
  for (const RigidBodyModel& b : m.rigid_bodies) hash_rigid(f, b);
  for (const NeedleTissue& t : m.needle_tissue) {
    f.value(static_cast<uint8_t>(t.enabled));
    for (const double v : {t.puncture_force, t.cutting_force, t.friction_static, t.friction_kinetic, t.track_stiffness,
                           t.track_spacing})
      f.value(v);
  }
  f.value(static_cast<uint8_t>(m.has_damage));
  for (const DamageModel& d : m.body_damage) hash_damage(f, d);
  for (const DamageModel& d : m.region_damage) hash_damage(f, d);
  f.value(static_cast<uint8_t>(m.has_contact));
  f.value(static_cast<uint8_t>(m.cutting != nullptr));
}

}  // namespace

uint64_t constants_fingerprint(const ModelConstants& m) {
  Fnv f;
  hash_constants(f, m);
  return f.h;
}

uint64_t model_fingerprint(const Model& m) {
  // Everything of the compiled model a tick reads, so that two models with the same fingerprint
  // step a state alike: the FEM system, the step's settings, the tools, damage, contact.
  Fnv f;
  const FemModel& fem = m.fem;
  f.value(fem.num_nodes);
  f.array(fem.rest);
  f.array(fem.elements);
  for (const ElementRange& r : fem.ranges) {
    f.value(r.begin);
    f.value(r.end);
    f.value(static_cast<int>(r.kernel));
    f.value(static_cast<uint8_t>(r.fixed));
    f.value(static_cast<uint8_t>(r.fibres));
    f.value(r.visco);
    f.value(static_cast<uint8_t>(r.smoothed));
    f.value(r.element_share);
    f.value(r.patch_elements);
    f.value(r.element_bulk_share);
  }
  f.array(fem.mass);
  f.array(fem.element_density);
  f.array(fem.fibres);
  for (const PronySeries& p : fem.visco) {
    f.value(p.terms);
    for (int k = 0; k < p.terms; ++k) {
      f.value(p.g[k]);
      f.value(p.tau[k]);
    }
  }
  f.array(fem.alpha);
  f.array(fem.constrained);
  f.array(fem.f_ext);
  f.value(fem.gravity);
  for (const BodyRange& b : fem.bodies) {
    f.value(b.density);
    f.value(b.node_begin);
    f.value(b.element_begin);
  }
  hash_constants(f, m.constants());
  f.array(m.element_region_damage);
  f.value(static_cast<uint8_t>(m.body_contact.has_value()));
  if (m.body_contact) {
    f.value(m.body_contact->stiffness);
    f.array(m.body_contact->body_depth);
  }
  f.array(m.collision_triangles);
  return f.h;
}

std::string encode_state(const State& s, uint64_t fingerprint) {
  Writer w;
  for (char c : kMagic) w.value(c);
  w.value(kVersion);
  w.value(fingerprint);
  w.value(static_cast<uint32_t>(sizeof(ToolState)));
  w.array(s.tissue.x);
  w.array(s.tissue.v);
  w.array(s.tissue.dv);
  w.array(s.tissue.dv_prev);
  w.array(s.tissue.visco_q);
  w.array(s.tissue.visco_s0);
  w.array(s.tools);
  w.array(s.rigid);
  w.value(static_cast<uint64_t>(s.needles.size()));
  for (const NeedleState& n : s.needles) {
    w.value(n.phase);
    w.value(n.tissue_body);
    w.value(n.count);
    w.array(n.track);
    w.value(n.front);
    w.value(n.has_front);
    w.value(n.tip_touching);
    w.value(n.punctures);
    w.value(n.tip_offset);
  }
  w.array(s.punctures);
  w.value(s.puncture_count);
  w.array(s.damage);
  w.array(s.damage_level);
  w.array(s.node_mass);
  w.value(s.damage_count);
  w.value(s.first_damage_time);
  w.array(s.face_active);
  w.array(s.edge_cut);
  w.value(s.time);
  w.value(s.step);
  const SolverHistory& h = s.tissue.solver;
  w.value(h.converged_in_a_row);
  // A refresh id names a factor within one process only (decode gives fresh ones), so the bytes
  // say whether there is one, not which: a decoded state re-encodes to the same bytes.
  w.value(static_cast<uint8_t>(h.factor_id != 0));
  w.value(h.factor_key);
  w.array(h.factor_matrix);
  w.array(h.factor_rot);
  w.value(static_cast<uint8_t>(h.pending_id != 0));
  w.value(h.pending_key);
  w.array(h.pending_matrix);
  w.array(h.pending_rot);
  w.value(h.steps_since_offer);
  w.value(h.period);
  w.value(h.lag);
  w.value(static_cast<uint8_t>(h.demand));
  w.value(h.pace_iterations);
  w.value(h.typical_iterations);
  w.value(h.warped_solves);
  w.value(h.element_blocks_key);
  w.value(h.element_blocks_phase);
  w.array(h.element_blocks);
  w.array(h.element_blocks_next);
  return w.take();
}

State decode_state(const std::string& bytes, uint64_t* fingerprint) {
  Reader r(bytes);
  char magic[sizeof kMagic];
  for (char& c : magic) r.value(c, "magic");
  if (std::memcmp(magic, kMagic, sizeof kMagic) != 0)
    throw InputError(kWhat, 0, "magic", "not a Stroma state (it does not start with STROMA-STATE)");
  uint32_t version = 0;
  r.value(version, "version");
  if (version != kVersion)
    throw InputError(kWhat, 0, "version",
                     "format " + std::to_string(version) + "; this build reads " + std::to_string(kVersion));
  uint64_t fp = 0;
  r.value(fp, "fingerprint");
  uint32_t tool_size = 0;
  r.value(tool_size, "tool size");
  if (tool_size != sizeof(ToolState))
    throw InputError(kWhat, 0, "tool size",
                     "tools of " + std::to_string(tool_size) + " bytes; this build's are " +
                         std::to_string(sizeof(ToolState)) + " (written by another build)");
  State s;
  r.array(s.tissue.x, "x");
  r.array(s.tissue.v, "v");
  r.array(s.tissue.dv, "dv");
  r.array(s.tissue.dv_prev, "dv_prev");
  r.array(s.tissue.visco_q, "visco_q");
  r.array(s.tissue.visco_s0, "visco_s0");
  r.array(s.tools, "tools");
  r.array(s.rigid, "rigid");
  uint64_t needles = 0;
  r.value(needles, "needles");
  if (needles != s.rigid.size())
    throw InputError(kWhat, 0, "needles", std::to_string(needles) + " needle states for " + std::to_string(s.rigid.size()) + " rigid bodies");
  s.needles.resize(size_t(needles));
  for (NeedleState& n : s.needles) {
    r.value(n.phase, "needle.phase");
    r.value(n.tissue_body, "needle.tissue_body");
    r.value(n.count, "needle.count");
    r.array(n.track, "needle.track");
    r.value(n.front, "needle.front");
    r.value(n.has_front, "needle.has_front");
    r.value(n.tip_touching, "needle.tip_touching");
    r.value(n.punctures, "needle.punctures");
    r.value(n.tip_offset, "needle.tip_offset");
    if (n.count < 0 || size_t(n.count) > n.track.size() || static_cast<uint8_t>(n.phase) > 2)
      throw InputError(kWhat, 0, "needle", "a needle's track count or phase is out of range");
  }
  r.array(s.punctures, "punctures");
  r.value(s.puncture_count, "puncture_count");
  if (s.puncture_count < 0 || size_t(s.puncture_count) > s.punctures.size())
    throw InputError(kWhat, 0, "puncture_count", "a thread's puncture count is out of range");
  r.array(s.damage, "damage");
  r.array(s.damage_level, "damage_level");
  r.array(s.node_mass, "node_mass");
  r.value(s.damage_count, "damage_count");
  r.value(s.first_damage_time, "first_damage_time");
  r.array(s.face_active, "face_active");
  r.array(s.edge_cut, "edge_cut");
  r.value(s.time, "time");
  r.value(s.step, "step");
  SolverHistory& h = s.tissue.solver;
  r.value(h.converged_in_a_row, "solver.converged_in_a_row");
  const bool has_factor = r.flag("solver.factor_id");
  r.value(h.factor_key, "solver.factor_key");
  r.array(h.factor_matrix, "solver.factor_matrix");
  r.array(h.factor_rot, "solver.factor_rot");
  const bool has_pending = r.flag("solver.pending_id");
  r.value(h.pending_key, "solver.pending_key");
  r.array(h.pending_matrix, "solver.pending_matrix");
  r.array(h.pending_rot, "solver.pending_rot");
  r.value(h.steps_since_offer, "solver.steps_since_offer");
  r.value(h.period, "solver.period");
  r.value(h.lag, "solver.lag");
  h.demand = r.flag("solver.demand");
  r.value(h.pace_iterations, "solver.pace_iterations");
  r.value(h.typical_iterations, "solver.typical_iterations");
  r.value(h.warped_solves, "solver.warped_solves");
  r.value(h.element_blocks_key, "solver.element_blocks_key");
  r.value(h.element_blocks_phase, "solver.element_blocks_phase");
  r.array(h.element_blocks, "solver.element_blocks");
  r.array(h.element_blocks_next, "solver.element_blocks_next");
  r.finish();
  // Refresh ids name factors within one process: a state from elsewhere gets fresh ones, so no
  // stepper here mistakes them for a factor it holds (it remakes them from the systems kept).
  h.factor_id = has_factor ? new_refresh_id() : 0;
  h.pending_id = has_pending ? new_refresh_id() : 0;
  if (fingerprint) *fingerprint = fp;
  return s;
}

namespace {
/// Needle states (rigid/needle_track.hpp's invariants) that index the model only where it has
/// the elements, nodes and bodies they name: bytes from a file or another process never index
/// out of bounds.
bool needle_tracks_fit(const State& s, const State& ref, const Model& m, std::string* why) {
  auto fail = [&](size_t k, const std::string& what) {
    if (why) *why = "needle " + std::to_string(k) + ": " + what;
    return false;
  };
  auto point_fits = [&](const TrackPoint& tp) {
    return tp.tet >= 0 && size_t(tp.tet) < m.fem.elements.size() && tp.node == m.fem.elements[size_t(tp.tet)].node &&
           tp.body >= 0 && size_t(tp.body) < m.fem.bodies.size() && tp.tet >= m.fem.bodies[size_t(tp.body)].element_begin &&
           tp.tet < m.fem.bodies[size_t(tp.body)].element_end && tp.surface <= 2 && tp.sliding <= 2;
  };
  for (size_t k = 0; k < s.needles.size() && k < ref.needles.size(); ++k) {
    const NeedleState& n = s.needles[k];
    if (n.track.size() != ref.needles[k].track.size()) return fail(k, "its track capacity differs from the model's");
    if (n.phase == NeedlePhase::Outside && (n.count != 0 || n.has_front)) return fail(k, "outside with a track");
    if (n.phase != NeedlePhase::Outside && (n.tissue_body < 0 || size_t(n.tissue_body) >= m.fem.bodies.size() ||
                                            m.needle_tissue.size() != m.fem.bodies.size()))
      return fail(k, "in a tissue body the model does not have");
    if (n.phase == NeedlePhase::Exited && (n.count < 1 || n.has_front)) return fail(k, "exited without an exit point");
    if (n.phase == NeedlePhase::Inserted && n.count == 0 && !n.has_front) return fail(k, "inserted with no track");
    for (int32_t i = 0; i < n.count; ++i)
      if (!point_fits(n.track[size_t(i)])) return fail(k, "a track point names an element the model does not have");
    if (n.has_front && !point_fits(n.front)) return fail(k, "its front names an element the model does not have");
  }
  return true;
}

/// Whether the threads' punctures are the model's: capacity, count, rods, elements.
bool punctures_fit(const State& s, const State& ref, const Model& m, std::string* why) {
  auto fail = [&](const std::string& what) {
    if (why) *why = "thread punctures: " + what;
    return false;
  };
  if (s.punctures.size() != ref.punctures.size()) return fail("their capacity differs from the model's");
  if (s.puncture_count < 0 || size_t(s.puncture_count) > s.punctures.size()) return fail("count out of range");
  for (int32_t i = 0; i < s.puncture_count; ++i) {
    const RodPuncture& p = s.punctures[size_t(i)];
    if (p.rod < 0 || size_t(p.rod) >= m.fem.rods.size()) return fail("a puncture names a thread the model does not have");
    const RodRange& r = m.fem.rods[size_t(p.rod)];
    if (!(p.sigma >= 0 && p.sigma <= r.segments()) || !(p.stiffness > 0)) return fail("a puncture is off its thread");
    for (const int32_t n : p.node)
      if (n < 0 || n >= (m.fem.bodies.empty() ? 0 : m.fem.bodies.back().node_end)) return fail("a puncture names a node that is not tissue");
  }
  return true;
}
}  // namespace

bool state_fits_model(const State& s, const Model& m, std::string* why) {
  const State ref = State::initial(m);
  auto check = [&](size_t have, size_t want, const char* what) {
    if (have == want) return true;
    if (why) *why = std::string(what) + ": " + std::to_string(have) + " values, the model's state has " + std::to_string(want);
    return false;
  };
  if (const int32_t ph = s.tissue.solver.element_blocks_phase; ph < -1 || ph >= std::max(1, m.stepper.stiffness_every)) {
    if (why) *why = "the solver's history: a stiffness phase of " + std::to_string(ph) + " (solver.stiffness_every " +
                    std::to_string(m.stepper.stiffness_every) + ")";
    return false;
  }
  return check(s.tissue.x.size(), ref.tissue.x.size(), "positions") &&
         check(s.tissue.v.size(), ref.tissue.v.size(), "velocities") &&
         check(s.tissue.dv.size(), ref.tissue.dv.size(), "warm start") &&
         check(s.tissue.dv_prev.size(), ref.tissue.dv_prev.size(), "warm start") &&
         check(s.tissue.visco_q.size(), ref.tissue.visco_q.size(), "visco-elastic branches") &&
         check(s.tissue.visco_s0.size(), ref.tissue.visco_s0.size(), "visco-elastic stresses") &&
         check(s.tools.size(), ref.tools.size(), "tools") && check(s.rigid.size(), ref.rigid.size(), "rigid bodies") &&
         check(s.needles.size(), ref.needles.size(), "needles") && needle_tracks_fit(s, ref, m, why) &&
         punctures_fit(s, ref, m, why) && check(s.damage.size(), ref.damage.size(), "damage") &&
         check(s.damage_level.size(), ref.damage_level.size(), "damage levels") &&
         check(s.node_mass.size(), ref.node_mass.size(), "node masses") &&
         check(s.face_active.size(), ref.face_active.size(), "collision faces") &&
         check(s.edge_cut.size(), ref.edge_cut.size(), "edge cuts") &&
         check(s.tissue.solver.factor_matrix.size(), ref.tissue.solver.factor_matrix.size(), "the solver's history") &&
         check(s.tissue.solver.pending_matrix.size(), ref.tissue.solver.pending_matrix.size(), "the solver's history") &&
         check(s.tissue.solver.factor_rot.size(), ref.tissue.solver.factor_rot.size(), "the solver's history") &&
         check(s.tissue.solver.pending_rot.size(), ref.tissue.solver.pending_rot.size(), "the solver's history") &&
         check(s.tissue.solver.element_blocks.size(), ref.tissue.solver.element_blocks.size(), "the solver's history") &&
         check(s.tissue.solver.element_blocks_next.size(), ref.tissue.solver.element_blocks_next.size(),
               "the solver's history");
}

}  // namespace stroma
