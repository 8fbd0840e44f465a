/// \file stroma_module.cpp
/// `import stroma`: the headless engine from Python (issue 18 §1, first slice; docs/PYTHON.md).
///
/// A Simulation owns what `stroma run` owns — the compiled scenario, a State and a
/// TickWorkspace — and steps exactly as the headless runner does: the scenario's tool scripts
/// (or poses set from Python), one tick, and after a tick whose blade cut edges the cut model
/// built and swapped in. So a step in Python is a step of `stroma run`, bit for bit.
///
/// Invariants: `positions` / `velocities` are read-only NumPy views of the engine's state (no
/// copy), valid until the next topology change (a cut) or reset(); the GIL is released while
/// the engine steps; load errors raise ValueError with the engine's "file:line: field: what"
/// message.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/compiled_scenario.hpp"
#include "engine/cut_swap.hpp"
#include "engine/model.hpp"
#include "engine/scenario_spec.hpp"
#include "engine/state.hpp"
#include "engine/solver_report.hpp"
#include "engine/state_bytes.hpp"
#include "engine/tick.hpp"
#include "engine/vtu_writer.hpp"
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

class Simulation {
 public:
  explicit Simulation(const std::string& path) {
    try {
      sc_ = compile_scenario(load_scenario(path));
    } catch (const InputError& e) {
      throw py::value_error(e.what());
    }
    reset();
  }

  /// From YAML (or JSON) text; `name` stands for the file in messages, relative paths resolve
  /// against base_dir.
  Simulation(const std::string& text, const std::string& name, const std::string& base_dir) {
    try {
      sc_ = compile_scenario(parse_scenario(text, name, base_dir));
    } catch (const InputError& e) {
      throw py::value_error(e.what());
    }
    reset();
  }

  void reset() {
    if (fingerprint_ == 0) fingerprint_ = model_fingerprint(*sc_.model);
    model_ = sc_.model;
    w_ = std::make_unique<TickWorkspace>(*model_);
    s_ = State::initial(*model_);
    poses_.assign(model_->tools.size(), std::nullopt);
  }

  /// n ticks; returns the number done (fewer only when a tick could not advance).
  int step(int n) {
    if (n < 0) throw py::value_error("step: n must be >= 0");
    py::gil_scoped_release release;
    for (int k = 0; k < n; ++k) {
      inputs_.clear();
      for (size_t t = 0; t < model_->tools.size(); ++t) {
        ToolPose pose;
        if (poses_[t]) pose = *poses_[t];
        else if (!sc_.tool_scripts[t].keys.empty()) pose = sc_.tool_scripts[t].sample(s_.time);
        else continue;
        inputs_.push_back(ToolInput{static_cast<int32_t>(t), static_cast<uint64_t>(s_.step + 1), 0, pose});
      }
      const TickReport& r = tick(*model_, s_, *w_, inputs_.data(), static_cast<int>(inputs_.size()));
      // (The report lives in the workspace, which a cut retires: keep the last one.)
      if (k == n - 1 || r.status == TickStatus::NonFinite || r.cut_edges > 0) last_ = r;
      if (r.status == TickStatus::NonFinite) return k;
      if (r.cut_edges > 0) {
        CutBuild b = build_cut(*model_, s_.edge_cut);
        apply_cut(b, model_, w_, s_);
      }
    }
    return n;
  }

  void set_pose(int tool, const std::array<double, 3>& position, const std::array<double, 4>& quaternion, double jaw) {
    check_tool(tool);
    ToolPose p;
    p.position = {position[0], position[1], position[2]};
    p.orientation = quaternion;
    p.jaw = jaw;
    poses_[tool] = p;
  }

  py::dict feedback(int tool) const {
    check_tool(tool);
    py::dict d;
    if (!last_ || static_cast<size_t>(tool) >= last_->tools.size()) {
      d["force"] = std::array<double, 3>{0, 0, 0};
      d["torque"] = std::array<double, 3>{0, 0, 0};
      d["stiffness"] = std::array<double, 9>{};
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
    return d;
  }

  /// The solver the scenario runs and who chose it (engine/solver_report.hpp: the object
  /// summary.json's "solver" holds).
  py::object solver() const { return py::module_::import("json").attr("loads")(solver_json(sc_).dump()); }

  Snapshot snapshot() const { return {model_, s_, fingerprint_}; }

  void restore(const Snapshot& snap) {
    if (snap.fingerprint != fingerprint_)
      throw py::value_error("restore: the snapshot was taken from another scenario (its model differs from this one's)");
    std::shared_ptr<const Model> m = snap.model;
    if (!m) m = model_for(snap.state);
    std::string why;
    if (!state_fits_model(snap.state, *m, &why)) throw py::value_error("restore: the snapshot does not fit the model: " + why);
    if (m != model_) {  // a snapshot from before (or after) a cut: its own model
      model_ = std::move(m);
      w_ = std::make_unique<TickWorkspace>(*model_);
    }
    s_ = snap.state;
  }

  /// A read-only (n, 3) view of v, kept alive by `owner`.
  static py::array view(std::vector<double>& v, py::handle owner) {
    const py::ssize_t n = static_cast<py::ssize_t>(v.size() / 3);
    py::array a(py::dtype::of<double>(), {n, py::ssize_t{3}}, {py::ssize_t{24}, py::ssize_t{8}}, v.data(), owner);
    a.attr("setflags")(py::arg("write") = false);
    return a;
  }

  void write_vtu_file(const std::string& path) const { write_vtu(path, *model_, s_); }

  /// Moves the nodes to `x` ((n, 3), finite); velocities stay. For setting up a state.
  void set_positions(const py::array_t<double, py::array::c_style | py::array::forcecast>& x) {
    const py::ssize_t n = model_->fem.num_nodes;
    if (x.ndim() != 2 || x.shape(0) != n || x.shape(1) != 3)
      throw py::value_error("positions: expected an array of shape (" + std::to_string(n) + ", 3)");
    const double* p = x.data();
    for (py::ssize_t i = 0; i < 3 * n; ++i)
      if (!std::isfinite(p[i])) throw py::value_error("positions: entry " + std::to_string(i / 3) + " is not finite");
    std::copy(p, p + 3 * n, s_.tissue.x.begin());
  }

  /// Per element damage d ∈ [0, 1] (float32, read-only view; empty without a damage model).
  static py::array damage_view(py::object self) {
    State& s = self.cast<Simulation&>().s_;
    py::array a(py::dtype::of<float>(), {static_cast<py::ssize_t>(s.damage.size())}, {py::ssize_t{4}},
                s.damage.data(), self);
    a.attr("setflags")(py::arg("write") = false);
    return a;
  }
  /// Elements that reached warned, damaged and ruptured (cumulative).
  std::array<int64_t, 3> damage_counts() const {
    return {s_.damage_count[1], s_.damage_count[2], s_.damage_count[3]};
  }

  double time() const { return s_.time; }
  int64_t steps() const { return s_.step; }
  double time_step() const { return model_->time_step; }
  int num_nodes() const { return model_->fem.num_nodes; }
  int num_tools() const { return static_cast<int>(model_->tools.size()); }
  State& state() { return s_; }

 private:
  void check_tool(int tool) const {
    if (tool < 0 || static_cast<size_t>(tool) >= model_->tools.size())
      throw py::index_error("tool " + std::to_string(tool) + " out of range: the scenario has " +
                            std::to_string(model_->tools.size()) + " tools");
  }

  /// The model an unpickled state belongs to: the scenario's uncut one, or the cut model its
  /// edge cuts make (built from the uncut mesh and the cuts, as every cut model is).
  std::shared_ptr<const Model> model_for(const State& s) const {
    const bool cut = std::any_of(s.edge_cut.begin(), s.edge_cut.end(), [](double c) { return c != kEdgeUncut; });
    if (!cut || !sc_.model->cutting) return sc_.model;
    if (s.edge_cut.size() != sc_.model->cut_edge_dofs.size())
      throw py::value_error("restore: the snapshot's edge cuts do not fit this scenario's mesh");
    if (model_->cutting && model_->cut_edge_state == s.edge_cut) return model_;
    CutBuild b = build_cut(*sc_.model, s.edge_cut);
    return b.changed ? b.model : sc_.model;
  }

  CompiledScenario sc_;
  uint64_t fingerprint_ = 0;
  std::shared_ptr<const Model> model_;
  std::unique_ptr<TickWorkspace> w_;
  State s_;
  std::vector<std::optional<ToolPose>> poses_;
  std::vector<ToolInput> inputs_;
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
  py::class_<Simulation>(mod, "Simulation", "A scenario stepped as `stroma run` steps it")
      .def(py::init<const std::string&>(), py::arg("scenario"), "Loads and compiles a scenario YAML file")
      .def(py::init<const std::string&, const std::string&, const std::string&>(), py::arg("text"), py::arg("name"),
           py::arg("base_dir"), "From scenario YAML (or JSON) text; `name` stands for the file in error messages")
      .def("step", &Simulation::step, py::arg("n") = 1, "Advances n ticks (the GIL is released); returns ticks done")
      .def("reset", &Simulation::reset, "Back to the initial state (and the uncut model)")
      .def("snapshot", &Simulation::snapshot, "A copy of the current state")
      .def("restore", &Simulation::restore, py::arg("snapshot"), "Continues from a snapshot")
      .def("set_pose", &Simulation::set_pose, py::arg("tool"), py::arg("position"),
           py::arg("quaternion") = std::array<double, 4>{1, 0, 0, 0}, py::arg("jaw") = 0.0,
           "Commands tool `tool` to this pose (m; unit quaternion w, x, y, z; jaw rad) from the next tick on")
      .def("feedback", &Simulation::feedback, py::arg("tool"), "Force, torque, stiffness and contacts of the last tick")
      .def_property_readonly("metrics", &Simulation::metrics, "Status, CG iterations and residual of the last tick")
      .def_property_readonly("solver", &Simulation::solver,
                             "The linear solver, its preconditioner and cap policy, and who chose each (auto: the "
                             "engine, at load; summary.json's \"solver\")")
      .def("write_vtu", &Simulation::write_vtu_file, py::arg("path"), "Writes the current state as VTU")
      .def_property_readonly("time", &Simulation::time, "Simulated time (s)")
      .def_property_readonly("steps", &Simulation::steps, "Ticks done")
      .def_property_readonly("time_step", &Simulation::time_step, "Tick length (s)")
      .def_property_readonly("num_nodes", &Simulation::num_nodes)
      .def_property_readonly("num_tools", &Simulation::num_tools)
      .def_property_readonly(
          "positions", [](py::object self) { return Simulation::view(self.cast<Simulation&>().state().tissue.x, self); },
          "Node positions (m), an (n, 3) read-only view of the engine's memory")
      .def("set_positions", &Simulation::set_positions, py::arg("x"),
           "Moves the nodes to x, an (n, 3) array of finite numbers (velocities stay)")
      .def_property_readonly("damage", &Simulation::damage_view,
                             "Per-element damage in [0, 1], a read-only float32 view (empty: no damage model)")
      .def_property_readonly("damage_counts", &Simulation::damage_counts,
                             "Elements that reached warned, damaged, ruptured")
      .def_property_readonly(
          "velocities", [](py::object self) { return Simulation::view(self.cast<Simulation&>().state().tissue.v, self); },
          "Node velocities (m/s), an (n, 3) read-only view of the engine's memory");
}
