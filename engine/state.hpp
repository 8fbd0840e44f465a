#pragma once
/// \file state.hpp
/// The small mutable simulation state (as MuJoCo's mjData): copy it to snapshot, assign it
/// back to roll back. Scratch memory lives elsewhere (TimeStepper), so copies stay small.

#include <array>
#include <cstdint>

#include "engine/model.hpp"
#include "tissue/tissue_state.hpp"

namespace stroma {

/// Simulation state at one instant: everything the next tick depends on, nothing it merely
/// reports (outputs live in TickReport). Invariants: tissue arrays have 3·num_nodes entries;
/// tools has one entry per Model::tools, rigid one per Model::rigid_bodies (unit quaternions); damage, damage_level and node_mass are sized to the
/// elements / nodes exactly when Model::has_damage; face_active to the collision faces when a
/// body with a damage model can be touched; time = step · time_step.
struct State {
  TissueState tissue;  ///< positions, velocities, solver warm start
  std::vector<ToolState> tools;  ///< one per scenario tool
  std::vector<RigidState> rigid;  ///< one per Model::rigid_bodies
  /// One per Model::rigid_bodies: a needle's insertion (rigid/needle_track.hpp; its track sized
  /// to the body's track_capacity); other bodies' stay empty and outside.
  std::vector<NeedleState> needles;
  /// Where threads go through the tissue (tissue/rod.hpp, engine/thread_attach.hpp):
  /// punctures[0, puncture_count) in the order they were made; the vector is sized to
  /// Model::puncture_capacity (no allocation in the tick).
  std::vector<RodPuncture> punctures;
  int32_t puncture_count = 0;
  // Damage (empty when no body has a damage model):
  std::vector<float> damage;          ///< per element d ∈ [0, 1]; stiffness × (1 − d)
  std::vector<uint8_t> damage_level;  ///< per element DamageLevel
  std::vector<double> node_mass;      ///< current lumped masses (ruptured elements removed)
  std::array<int64_t, 4> damage_count{};  ///< elements that reached warned / damaged / ruptured
  double first_damage_time = -1;      ///< sim time of the first onset (−1: none)
  /// Per collision face: 0 inactive (both sides intact, or both ruptured), 1 active as stored,
  /// 2 active reversed (its first element ruptured, the second is intact). Empty unless a body
  /// with a damage model can be touched by a tool.
  std::vector<uint8_t> face_active;
  /// Cutting (Model::cutting): per edge of the uncut mesh, where the blade crossed it
  /// (kEdgeUncut: not cut). It only grows; the model's topology lags it until the runner swaps
  /// in the cut model built from it (engine/cut_swap.hpp). Empty without a cutting tool.
  std::vector<double> edge_cut;
  double time = 0;     ///< simulated time (s)
  int64_t step = 0;    ///< ticks done

  /// The initial state of a model: every body at rest in its rest configuration.
  static State initial(const Model& m) {
    State s;
    s.tissue = TissueState::at_rest(m.fem);
    if (!m.initial_x.empty()) s.tissue.x = m.initial_x;  // a prestretched body starts as its mesh
    // A refreshed warped factor keeps its systems in the state (SolverHistory): sized here, so
    // the tick that hands one over copies into room it has. (-1: `auto` not resolved yet — a
    // model not made by compile_scenario; TimeStepper::prepare resolves it to a period.)
    if (m.stepper.preconditioner == Preconditioner::WarpedCholesky && m.stepper.preconditioner_refresh != 0 &&
        m.stepper.integrator == Integrator::ImplicitEuler && m.stepper.linear_solver == LinearSolverKind::CG) {
      SolverHistory& h = s.tissue.solver;
      const size_t values = 9 * static_cast<size_t>(m.fem.pattern.nnzb()), rot = 9 * static_cast<size_t>(m.fem.num_nodes);
      h.factor_matrix.assign(values, 0.0);
      h.pending_matrix.assign(values, 0.0);
      h.factor_rot.assign(rot, 0.0);
      h.pending_rot.assign(rot, 0.0);
    }
    // Kept element stiffness blocks (StepperSettings::stiffness_every): room made here, the
    // first step fills it (phase −1: none yet).
    if (m.stepper.stiffness_every > 1 && m.stepper.integrator == Integrator::ImplicitEuler) {
      s.tissue.solver.element_blocks.assign(9 * static_cast<size_t>(m.fem.pattern.nnzb()), 0.0);
      s.tissue.solver.element_blocks_next.assign(9 * static_cast<size_t>(m.fem.pattern.nnzb()), 0.0);
    }
    s.tools.assign(m.tools.size(), ToolState{});
    for (const RigidBodyModel& b : m.rigid_bodies) {
      s.rigid.push_back(b.initial);
      s.needles.emplace_back().track.resize(size_t(b.track_capacity));
    }
    s.punctures.resize(size_t(m.puncture_capacity));
    for (size_t k = 0; k < m.tools.size(); ++k) s.tools[k].pose = m.tools[k].rest_pose;
    if (m.cutting) s.edge_cut.assign(m.cut_edge_dofs.size(), kEdgeUncut);
    if (m.has_damage) {
      s.damage.assign(m.fem.elements.size(), 0.0f);
      s.damage_level.assign(m.fem.elements.size(), 0);
      s.node_mass = m.fem.mass;
      if (m.has_contact) {
        s.face_active.resize(m.collision_face_elem.size());
        for (size_t f = 0; f < s.face_active.size(); ++f)
          s.face_active[f] = (m.collision_face_elem[f][0] >= 0 && m.collision_face_elem[f][1] >= 0) ? 0 : 1;
      }
    }
    return s;
  }
};

/// Displacement of a probe in state s.
Vec3 probe_displacement(const Model& m, const State& s, const ProbeModel& p);
/// Current position of a probe in state s.
Vec3 probe_position(const Model& m, const State& s, const ProbeModel& p);

}  // namespace stroma
