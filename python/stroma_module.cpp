/// \file stroma_module.cpp
/// `import stroma`: the headless engine from Python (issue 18 §1, first slice; docs/PYTHON.md).
///
/// A Simulation owns what `stroma run` owns — the compiled scenario, a State and a
/// TickWorkspace — and steps exactly as the headless runner does: the scenario's tool scripts
/// (or poses set from Python), one tick, and after a tick whose blade cut edges the cut model
/// built and swapped in. So a step in Python is a step of `stroma run`, bit for bit.
///
/// Invariants: `positions`, `velocities` and `damage` are read-only NumPy arrays the module
/// owns (never views of engine memory, which a reset or a cut frees): each is refreshed in place
/// after every step, reset, restore and set_positions while its length stays; when a cut or a
/// restore changes the node or element count, a new array is made and the old one keeps its last
/// values (its shape tells: a length that differs from num_nodes). So no array ever reads freed
/// memory. The GIL is released while the engine steps; load errors raise ValueError with the
/// engine's "file:line: field: what" message.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/cut_swap.hpp"
#include "engine/model.hpp"
#include "engine/simulation.hpp"
#include "engine/state.hpp"
#include "engine/state_bytes.hpp"
#include "engine/tick.hpp"
#include "runtime/vtu_writer.hpp"
#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "scene/solver_report.hpp"
#include "tissue/input_error.hpp"

namespace py = pybind11;
using namespace stroma;

namespace {

/// A snapshot: a copy of the state, the fingerprint of its scenario's uncut model, and (in the
/// process that took it) the model it belongs to, which a cut may replace. A pickled snapshot
/// travels as encode_state's bytes and comes back without a model: restore() rebuilds it from
/// the scenario and the state's edge cuts.
struct Snapshot {
  std::shared_ptr<const Model> model;  ///< null after unpickling
  State state;
  uint64_t fingerprint = 0;
};

/// The Python face of the engine's Simulation (engine/simulation.hpp): the same commands port
/// (set_pose is checked, clamped or refused and counted as a served command is), the same cut
/// stage (synchronous), the scenario's scripts submitted for the tools Python does not pose.
class PySimulation {
 public:
  explicit PySimulation(const std::string& path) {
    try {
      sc_ = compile_scenario(load_scenario(path));
    } catch (const InputError& e) {
      throw py::value_error(e.what());
    }
    reset();
  }

  /// From YAML (or JSON) text; `name` stands for the file in messages, relative paths resolve
  /// against base_dir.
  PySimulation(const std::string& text, const std::string& name, const std::string& base_dir) {
    try {
      sc_ = compile_scenario(parse_scenario(text, name, base_dir));
    } catch (const InputError& e) {
      throw py::value_error(e.what());
    }
    reset();
  }

  void reset() {
    if (fingerprint_ == 0) fingerprint_ = model_fingerprint(*sc_.model);
    // A fresh Simulation: a reset run is a new run (workspace caches included), bit for bit.
    SimulationOptions o;
    o.hold = ToolHold::Repeat;  // a pose set from Python stays set
    sim_ = std::make_unique<Simulation>(sc_.model, o);
    last_.reset();  // feedback() is of this run's ticks only
    refresh_views();
  }

  /// n ticks; returns the number done (fewer only when a tick could not advance).
  int step(int n) {
    if (n < 0) throw py::value_error("step: n must be >= 0");
    int done = n;
    {
      py::gil_scoped_release release;
      for (int k = 0; k < n; ++k) {
        sim_->submit_scripts(sc_.tool_scripts);
        const TickReport& r = sim_->advance();
        if (k == n - 1 || r.status == TickStatus::NonFinite) last_ = r;
        if (r.status == TickStatus::NonFinite) {
          done = k;
          break;
        }
      }
    }
    refresh_views();
    return done;
  }

  /// Checked as every front end's commands are (engine/tool_commands.hpp): "accepted",
  /// "clamped" (applied, moved into the limits) or "rejected" (not applied; the tool keeps its
  /// last pose). Counted in `commands`.
  std::string set_pose(int tool, const std::array<double, 3>& position, const std::array<double, 4>& quaternion,
                       double jaw) {
    check_tool(tool);
    ToolPose p;
    p.position = {position[0], position[1], position[2]};
    p.orientation = quaternion;
    p.jaw = jaw;
    const State& s = sim_->state();
    const int64_t t_ns = std::llround(s.time * 1e9);  // takes effect at the next tick's start
    const ToolCheck c = sim_->commands().submit(tool, p, static_cast<uint64_t>(s.step + 1), t_ns, t_ns);
    if (c.result == ToolCheck::Rejected) return "rejected";
    sim_->state().tools[tool].posed = true;  // state: a snapshot keeps who drives the tool
    return c.result == ToolCheck::Clamped ? "clamped" : "accepted";
  }

  py::dict commands() const {
    const CommandCounters& c = sim_->commands().counters();
    py::dict d;
    d["accepted"] = c.accepted.load();
    d["clamped"] = c.clamped.load();
    d["rejected"] = c.rejected.load();
    d["last_reason"] = std::string(sim_->commands().last_reason());
    return d;
  }

  /// Where tool `tool` is now (its state's pose: the last command applied, or its rest pose).
  py::dict tool_pose(int tool) const {
    check_tool(tool);
    const ToolPose& p = sim_->state().tools[size_t(tool)].pose;
    py::dict d;
    d["position"] = std::array<double, 3>{p.position[0], p.position[1], p.position[2]};
    d["orientation"] = p.orientation;
    d["jaw"] = p.jaw;
    return d;
  }

  py::dict feedback(int tool) const {
    check_tool(tool);
    py::dict d;
    if (!last_ || static_cast<size_t>(tool) >= last_->tools.size()) {
      // No tick since the start, a reset or a restore: the state's own account of the last
      // solved step (zero at the start; a snapshot's, restored — never a tick of another run).
      const ToolState& ts = sim_->state().tools[size_t(tool)];
      d["force"] = std::array<double, 3>{ts.force[0], ts.force[1], ts.force[2]};
      d["torque"] = std::array<double, 3>{0, 0, 0};
      d["stiffness"] = ts.stiffness;
      d["contacts"] = 0;
      return d;
    }
    const ToolOutput& o = last_->tools[tool];
    d["force"] = std::array<double, 3>{o.force[0], o.force[1], o.force[2]};
    d["torque"] = std::array<double, 3>{o.torque[0], o.torque[1], o.torque[2]};
    d["stiffness"] = o.stiffness;
    d["contacts"] = o.contacts;
    return d;
  }

  py::dict metrics() const {
    py::dict d;
    if (!last_) return d;
    d["status"] = static_cast<int>(last_->status);
    d["cg_iterations"] = last_->solve.iterations;
    d["cg_residual"] = last_->solve.relative_residual;
    d["substeps"] = last_->substeps;
    d["total_ms"] = static_cast<double>(last_->total_ns) * 1e-6;
    py::dict stages;  // the stages that ran, ms
    for (int k = 0; k < kStageCount; ++k)
      if (last_->stage_ran[k])
        stages[py::str(std::string(stage_name(static_cast<Stage>(k))))] = static_cast<double>(last_->stage_ns[k]) * 1e-6;
    d["stage_ms"] = stages;
    if (!sim_->model().fem.rods.empty()) {  // the threads' contacts this tick (docs/THREAD.md, "Contact")
      const ThreadContactOutput& t = last_->thread_contact;
      py::dict tc;
      tc["tissue"] = t.tissue, tc["self"] = t.self, tc["tools"] = t.tools, tc["rigid"] = t.rigid;
      tc["dropped"] = t.dropped, tc["missed"] = t.missed, tc["unchecked"] = t.unchecked;
      d["thread_contact"] = tc;
    }
    return d;
  }

  /// The solver the scenario runs and who chose it (scene/solver_report.hpp: the object
  /// summary.json's "solver" holds).
  py::object solver() const { return py::module_::import("json").attr("loads")(solver_json(sc_).dump()); }

  Snapshot snapshot() const { return {sim_->model_ptr(), sim_->state(), fingerprint_}; }

  void restore(const Snapshot& snap) {
    if (snap.fingerprint != fingerprint_)
      throw py::value_error("restore: the snapshot was taken from another scenario (its model differs from this one's)");
    std::shared_ptr<const Model> m = snap.model;
    if (!m) m = model_for(snap.state);
    std::string why;
    if (!state_fits_model(snap.state, *m, &why)) throw py::value_error("restore: the snapshot does not fit the model: " + why);
    sim_->restore(std::move(m), snap.state);
    last_.reset();  // feedback() is the restored state's, not of the tick before the restore
    refresh_views();
  }

  /// The module's read-only arrays of the state (see the file comment), made on first use.
  py::array positions() { return mirror(x_, sim_->state().tissue.x, 3); }
  py::array velocities() { return mirror(v_, sim_->state().tissue.v, 3); }
  py::array damage() { return mirror(d_, sim_->state().damage, 1); }
  /// Rigid bodies' poses, (k, 7): centre of mass x, y, z and orientation w, x, y, z.
  py::array rigid_poses() { return mirror(rp_, rigid_rows_of(sim_->state(), true), 7); }
  /// Rigid bodies' velocities, (k, 6): of the centre of mass (m/s), angular (rad/s), world.
  py::array rigid_velocities() { return mirror(rv_, rigid_rows_of(sim_->state(), false), 6); }
  /// Per thread (docs/THREAD.md): its name, its nodes' range in `positions` (first, end), its
  /// segments' rest length, stretch and bending stiffness, and its nodes' positions now (a
  /// (nodes, 3) copy) and length along them.
  py::list threads() const {
    py::list out;
    const FemModel& f = sim_->model().fem;
    const std::vector<double>& x = sim_->state().tissue.x;
    for (const RodRange& r : f.rods) {
      py::dict d;
      d["name"] = r.name;
      d["nodes"] = py::make_tuple(r.node_begin, r.node_end);
      d["segment_length"] = r.segment_length;
      d["stretch_stiffness"] = r.stretch_stiffness;
      d["bend_stiffness"] = r.bend_stiffness;
      py::array_t<double> pos({static_cast<py::ssize_t>(r.nodes()), static_cast<py::ssize_t>(3)});
      double* p = pos.mutable_data();
      double length = 0;
      for (int32_t i = r.node_begin; i < r.node_end; ++i) {
        for (int k = 0; k < 3; ++k) p[3 * (i - r.node_begin) + k] = x[3 * static_cast<size_t>(i) + k];
        if (i > r.node_begin) {
          const double* a = x.data() + 3 * static_cast<size_t>(i - 1);
          length += std::sqrt((a[3] - a[0]) * (a[3] - a[0]) + (a[4] - a[1]) * (a[4] - a[1]) + (a[5] - a[2]) * (a[5] - a[2]));
        }
      }
      d["positions"] = pos;
      d["length"] = length;
      // Where it goes through the tissue (docs/THREAD.md): each puncture's tissue body, the
      // thread's point tied there (sigma, in segments from its first node) and the material
      // point now.
      py::list punctures;
      const State& st = sim_->state();
      for (int32_t i = 0; i < st.puncture_count; ++i) {
        const RodPuncture& p = st.punctures[size_t(i)];
        if (&f.rods[size_t(p.rod)] != &r) continue;
        py::dict q;
        q["body"] = f.bodies[size_t(p.body)].name;
        q["sigma"] = p.sigma;
        py::array_t<double> pt(3);
        double* o = pt.mutable_data();
        for (int c = 0; c < 3; ++c) {
          o[c] = 0;
          for (int a = 0; a < 4; ++a) o[c] += p.w[a] * x[3 * static_cast<size_t>(p.node[a]) + c];
        }
        q["point"] = pt;
        punctures.append(q);
      }
      d["punctures"] = punctures;
      out.append(d);
    }
    return out;
  }
  /// Per rigid body: name, shape, mass, inertia (body frame, about the centre of mass), fixed,
  /// and its contacts of the last tick (count, penalty energy, force on it).
  py::list rigid_bodies() const {
    py::list out;
    const Model& m = sim_->model();
    for (size_t k = 0; k < m.rigid_bodies.size(); ++k) {
      const RigidBodyModel& b = m.rigid_bodies[k];
      py::dict d;
      d["name"] = b.name;
      static const char* kShapes[] = {"sphere", "box", "capsule", "mesh", "needle"};
      d["shape"] = kShapes[static_cast<int>(b.shape)];
      d["mass"] = b.mass.mass;
      d["inertia"] = std::vector<double>(b.mass.inertia.begin(), b.mass.inertia.end());
      d["fixed"] = b.fixed;
      const bool has = last_ && k < last_->rigid_contact.size();  // (no tick yet: none)
      d["contacts"] = has ? last_->rigid_contact[k].contacts : 0;
      d["contact_energy"] = has ? last_->rigid_contact[k].energy : 0.0;
      d["contact_force"] = has ? std::vector<double>(last_->rigid_contact[k].force.begin(),
                                                     last_->rigid_contact[k].force.end())
                               : std::vector<double>(3, 0.0);
      if (b.shape == RigidShape::Needle) {  // its insertion (rigid/needle_track.hpp)
        const NeedleState& ns = sim_->state().needles[k];
        const bool tick = last_ && k < last_->needles.size();
        py::dict n;
        n["phase"] = needle_phase_name(ns.phase);
        n["punctures"] = ns.punctures;
        n["inserted_length"] = tick ? last_->needles[k].inserted_length : 0.0;
        n["tip_force"] = tick ? last_->needles[k].tip_force : 0.0;
        n["friction_force"] = tick ? last_->needles[k].friction_force : 0.0;
        // The track: each point's tissue position (m, world) and the needle's arc length it is at.
        std::vector<double> pts, arc;
        for (int32_t i = 0; i < ns.count; ++i) {
          const TrackPoint& tp = ns.track[size_t(i)];
          for (int c = 0; c < 3; ++c) {
            double v = 0;
            for (int a = 0; a < 4; ++a) v += tp.w[a] * sim_->state().tissue.x[size_t(3 * tp.node[size_t(a)] + c)];
            pts.push_back(v);
          }
          arc.push_back(tp.s);
        }
        py::array_t<double> track({static_cast<py::ssize_t>(ns.count), py::ssize_t{3}});
        std::copy(pts.begin(), pts.end(), track.mutable_data());
        n["track"] = track;
        n["track_s"] = arc;
        d["needle"] = n;
      }
      out.append(d);
    }
    return out;
  }

  void write_vtu_file(const std::string& path) const { write_vtu(path, sim_->model(), sim_->state()); }

  /// Moves the nodes to `x` ((n, 3), finite); velocities stay. For setting up a state.
  void set_positions(const py::array_t<double, py::array::c_style | py::array::forcecast>& x) {
    const py::ssize_t n = sim_->model().fem.num_nodes;
    if (x.ndim() != 2 || x.shape(0) != n || x.shape(1) != 3)
      throw py::value_error("positions: expected an array of shape (" + std::to_string(n) + ", 3)");
    const double* p = x.data();
    for (py::ssize_t i = 0; i < 3 * n; ++i)
      if (!std::isfinite(p[i])) throw py::value_error("positions: entry " + std::to_string(i / 3) + " is not finite");
    std::copy(p, p + 3 * n, sim_->state().tissue.x.begin());
    refresh_views();
  }
  /// Elements that reached warned, damaged and ruptured (cumulative).
  std::array<int64_t, 3> damage_counts() const {
    const State& s = sim_->state();
    return {s.damage_count[1], s.damage_count[2], s.damage_count[3]};
  }

  /// Each tool's name, shape size, limits and rest pose (the model's ToolSpec), for front ends
  /// that build on them (the Gymnasium environment's spaces).
  py::list tools() const {
    py::list out;
    for (const ToolSpec& t : sim_->model().tools) {
      py::dict d;
      d["name"] = t.name;
      d["radius"] = t.radius;
      d["max_speed"] = t.max_speed;
      d["max_force"] = t.max_force;
      d["on_invalid"] = t.on_invalid == InvalidCommandPolicy::Clamp ? "clamp" : "reject";
      py::dict ws;
      ws["min"] = std::array<double, 3>{t.workspace_min[0], t.workspace_min[1], t.workspace_min[2]};
      ws["max"] = std::array<double, 3>{t.workspace_max[0], t.workspace_max[1], t.workspace_max[2]};
      d["workspace"] = ws;
      d["rest_position"] = t.rest_pose.position;
      d["rest_orientation"] = t.rest_pose.orientation;
      out.append(d);
    }
    return out;
  }

  double time() const { return sim_->state().time; }
  int64_t steps() const { return sim_->state().step; }
  double time_step() const { return sim_->model().time_step; }
  int num_nodes() const { return sim_->model().fem.num_nodes; }
  int num_tools() const { return static_cast<int>(sim_->model().tools.size()); }
  State& state() { return sim_->state(); }

 private:
  void check_tool(int tool) const {
    if (tool < 0 || static_cast<size_t>(tool) >= sim_->model().tools.size())
      throw py::index_error("tool " + std::to_string(tool) + " out of range: the scenario has " +
                            std::to_string(sim_->model().tools.size()) + " tools");
  }

  /// The model an unpickled state belongs to: the scenario's uncut one, or the cut model its
  /// edge cuts make (built from the uncut mesh and the cuts, as every cut model is).
  std::shared_ptr<const Model> model_for(const State& s) const {
    const bool cut = std::any_of(s.edge_cut.begin(), s.edge_cut.end(), [](double c) { return c != kEdgeUncut; });
    if (!cut || !sc_.model->cutting) return sc_.model;
    if (s.edge_cut.size() != sc_.model->cut_edge_dofs.size())
      throw py::value_error("restore: the snapshot's edge cuts do not fit this scenario's mesh");
    if (sim_->model().cutting && sim_->model().cut_edge_state == s.edge_cut) return sim_->model_ptr();
    CutBuild b = build_cut(*sc_.model, s.edge_cut);
    return b.changed ? b.model : sc_.model;
  }

  /// `arr` (made, or made anew when the length changed) holding `src`, read-only to Python.
  template <typename T>
  static py::array mirror(py::object& slot, const std::vector<T>& src, py::ssize_t width) {
    const py::ssize_t rows = static_cast<py::ssize_t>(src.size()) / width;
    if (!slot || py::reinterpret_borrow<py::array>(slot).size() != static_cast<py::ssize_t>(src.size())) {
      const std::vector<py::ssize_t> shape = width == 1 ? std::vector<py::ssize_t>{rows} : std::vector<py::ssize_t>{rows, width};
      py::array a(py::dtype::of<T>(), shape);
      a.attr("setflags")(py::arg("write") = false);
      slot = a;
    }
    py::array arr = py::reinterpret_borrow<py::array>(slot);
    // The module writes what Python may only read (the flag guards Python, not us).
    std::copy(src.begin(), src.end(), static_cast<T*>(const_cast<void*>(arr.data())));
    return arr;
  }
  /// After every change of the state: the arrays handed out follow it (only those made).
  void refresh_views() {
    const State& s = sim_->state();
    if (x_) mirror(x_, s.tissue.x, 3);
    if (v_) mirror(v_, s.tissue.v, 3);
    if (d_) mirror(d_, s.damage, 1);
    if (rp_) mirror(rp_, rigid_rows_of(s, true), 7);
    if (rv_) mirror(rv_, rigid_rows_of(s, false), 6);
  }
  /// The rigid bodies' poses (7 per body) or velocities (6 per body), flattened.
  static std::vector<double> rigid_rows_of(const State& s, bool poses) {
    std::vector<double> out;
    out.reserve(s.rigid.size() * 7);
    for (const RigidState& r : s.rigid) {
      if (poses) {
        out.insert(out.end(), r.x.begin(), r.x.end());
        out.insert(out.end(), r.q.begin(), r.q.end());
      } else {
        out.insert(out.end(), r.v.begin(), r.v.end());
        out.insert(out.end(), r.w.begin(), r.w.end());
      }
    }
    return out;
  }

  py::object x_, v_, d_;  ///< positions, velocities, damage arrays (null until first asked for)
  py::object rp_, rv_;    ///< rigid poses and velocities (likewise)
  CompiledScenario sc_;
  uint64_t fingerprint_ = 0;
  std::unique_ptr<Simulation> sim_;
  std::optional<TickReport> last_;
};

}  // namespace

PYBIND11_MODULE(_stroma, mod) {
  mod.doc() = "Stroma: soft-tissue FEM for surgical simulation (the headless engine)";
  py::class_<Snapshot>(mod, "Snapshot",
                       "A copy of a simulation's state (Simulation.snapshot()); picklable, to restore in another "
                       "process into a Simulation of the same scenario")
      .def_property_readonly("time", [](const Snapshot& s) { return s.state.time; }, "Simulated time (s)")
      .def_property_readonly("steps", [](const Snapshot& s) { return s.state.step; }, "Ticks done")
      .def(py::pickle(
          [](const Snapshot& s) { return py::bytes(encode_state(s.state, s.fingerprint)); },
          [](const py::bytes& b) {
            Snapshot s;
            try {
              s.state = decode_state(std::string(b), &s.fingerprint);
            } catch (const InputError& e) {
              throw py::value_error(std::string("Snapshot: ") + e.what());
            }
            return s;
          }));
  py::class_<PySimulation>(mod, "Simulation", "A scenario stepped as `stroma run` steps it")
      .def(py::init<const std::string&>(), py::arg("scenario"), "Loads and compiles a scenario YAML file")
      .def(py::init<const std::string&, const std::string&, const std::string&>(), py::arg("text"), py::arg("name"),
           py::arg("base_dir"), "From scenario YAML (or JSON) text; `name` stands for the file in error messages")
      .def("step", &PySimulation::step, py::arg("n") = 1, "Advances n ticks (the GIL is released); returns ticks done")
      .def("reset", &PySimulation::reset, "Back to the initial state (and the uncut model)")
      .def("snapshot", &PySimulation::snapshot, "A copy of the current state")
      .def("restore", &PySimulation::restore, py::arg("snapshot"), "Continues from a snapshot")
      .def("set_pose", &PySimulation::set_pose, py::arg("tool"), py::arg("position"),
           py::arg("quaternion") = std::array<double, 4>{1, 0, 0, 0}, py::arg("jaw") = 0.0,
           "Commands tool `tool` to this pose (m; unit quaternion w, x, y, z; jaw rad) from the next tick on, "
           "checked against the tool's limits as every front end's commands are: returns 'accepted', 'clamped' "
           "(moved into the workspace or speed limit) or 'rejected' (not applied: non-finite, not a unit "
           "quaternion, or outside the limits under on_invalid: reject)")
      .def_property_readonly("commands", &PySimulation::commands,
                             "Tool commands accepted, clamped and rejected so far, and the last reason")
      .def("feedback", &PySimulation::feedback, py::arg("tool"), "Force, torque, stiffness and contacts of the last tick")
      .def("tool_pose", &PySimulation::tool_pose, py::arg("tool"),
           "Where the tool is now: position (m), orientation (unit quaternion w, x, y, z), jaw (rad)")
      .def_property_readonly("metrics", &PySimulation::metrics, "Status, CG iterations and residual of the last tick")
      .def_property_readonly("solver", &PySimulation::solver,
                             "The linear solver, its preconditioner and cap policy, and who chose each (auto: the "
                             "engine, at load; summary.json's \"solver\")")
      .def("write_vtu", &PySimulation::write_vtu_file, py::arg("path"), "Writes the current state as VTU")
      .def_property_readonly("time", &PySimulation::time, "Simulated time (s)")
      .def_property_readonly("steps", &PySimulation::steps, "Ticks done")
      .def_property_readonly("time_step", &PySimulation::time_step, "Tick length (s)")
      .def_property_readonly("num_nodes", &PySimulation::num_nodes)
      .def_property_readonly("num_tools", &PySimulation::num_tools)
      .def_property_readonly("tools", &PySimulation::tools,
                             "Per tool: name, radius, max_speed, max_force, on_invalid, workspace {min, max}, "
                             "rest_position and rest_orientation (where it is before its first command)")
      .def_property_readonly("positions", &PySimulation::positions,
                             "Node positions (m), an (n, 3) read-only array the module keeps up to date after every "
                             "step, reset, restore and set_positions (a cut that adds nodes makes a new one; one "
                             "taken before keeps its last values)")
      .def("set_positions", &PySimulation::set_positions, py::arg("x"),
           "Moves the nodes to x, an (n, 3) array of finite numbers (velocities stay)")
      .def_property_readonly("damage", &PySimulation::damage,
                             "Per-element damage in [0, 1], a read-only float32 array kept up to date as positions "
                             "is (empty: no damage model)")
      .def_property_readonly("damage_counts", &PySimulation::damage_counts,
                             "Elements that reached warned, damaged, ruptured")
      .def_property_readonly("velocities", &PySimulation::velocities,
                             "Node velocities (m/s), an (n, 3) read-only array kept up to date as positions is")
      .def_property_readonly("rigid_poses", &PySimulation::rigid_poses,
                             "Rigid bodies' poses, a (k, 7) read-only array kept up to date as positions is: centre "
                             "of mass x, y, z (m) and orientation quaternion w, x, y, z (body to world)")
      .def_property_readonly("rigid_velocities", &PySimulation::rigid_velocities,
                             "Rigid bodies' velocities, a (k, 6) read-only array: centre of mass (m/s) and angular "
                             "(rad/s), world")
      .def_property_readonly("threads", &PySimulation::threads,
                             "Per thread (docs/THREAD.md): name, nodes (first, end: its rows of positions and "
                             "velocities), segment_length (rest, m), stretch_stiffness and bend_stiffness (N/m), "
                             "positions ((nodes, 3) copy, m) and length (along its nodes now, m)")
      .def_property_readonly("rigid_bodies", &PySimulation::rigid_bodies,
                             "Per rigid body: name, shape, mass, inertia (body frame), fixed, and the last tick's "
                             "contacts, contact_energy and contact_force (N, on the body); a needle's `needle`: phase "
                             "(outside, inserted, exited), punctures, inserted_length (m), tip_force and friction_force "
                             "(N, along its tip), track ((p, 3) tissue points, m) and track_s (their arc lengths, m)");
}
