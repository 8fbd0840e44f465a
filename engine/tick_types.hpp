#pragma once
/// \file tick_types.hpp
/// The types a tick works with, shared by the tick (engine/tick.hpp), its stages
/// (step_with_recovery, damage, multirate), their timer (stage_timer) and the loops that drive
/// it, so that none of them includes another: the named stages, how a tick ended, what the
/// budget cut short, the TickReport (a tick's outputs), the TickWorkspace (its scratch), and
/// the budget's accounting (close_report: written once for the tick and the multirate worker).

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include "collision/body_contact.hpp"
#include "collision/triangle_bvh.hpp"
#include "engine/damage.hpp"
#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/thread_contact.hpp"
#include "haptics/tool.hpp"
#include "rigid/rigid_contact.hpp"
#include "tissue/clock.hpp"
#include "tissue/deadline.hpp"
#include "tissue/time_stepper.hpp"

namespace stroma {

/// Named stages of a tick, in order. `Assemble` counts every element pass of the step (Newton
/// iterations' included), `Solve` the linear solves; `HandOff` is the tick's outputs for
/// clients (end-of-step tool forces and device feedback) and, in `stroma serve`, the copies
/// into the lock-free buffers that follow the tick.
/// The tick's stages, in the order their times are reported (summary.json, metrics.csv, SimStatus
/// stage_ms). `Cut` runs right after `Collide` but is numbered last: it joined later (issue 40),
/// and DDS clients index stage_ms by these numbers.
enum class Stage : int { ReadInputs, Collide, Assemble, Solve, Integrate, Damage, HandOff, Cut, Count };
inline constexpr int kStageCount = static_cast<int>(Stage::Count);
/// snake_case stage name, as used in summary.json, metrics.csv and SimStatus.
std::string_view stage_name(Stage s);

/// How a tick ended.
enum class TickStatus : uint8_t {
  Ok,
  SolverNotConverged,  ///< the linear solve hit its cap (state is still finite and advanced)
  Recovered,           ///< the full step failed (NaN/Inf in the solve or the state, or a node moving
                       ///< more than half the scene's size in one step); it was rolled back and
                       ///< redone in `substeps` sub-steps (or, out of budget, partly redone or
                       ///< held still: see TickReport::degradation)
  NonFinite            ///< no sub-step division gave a sane step either: the state was rolled
                       ///< back and not advanced (never a NaN in the state)
};

/// Most sub-steps a failed tick is retried with (2, 4, 8, 16, then 32 and 64).
inline constexpr int kMaxSubsteps = 64;
/// From this sub-step level on a capped CG solve is kept (a finite, advanced state beats none);
/// the levels above it are tried only when this one still blew up (non-finite or a node moving
/// more than half the scene), so ticks that recover at ≤ 16 sub-steps are unaffected. Measured
/// (docs/STABILITY.md): soft ν = 0.499 stable Neo-Hookean with 119 inverted elements at 10 ms
/// could not advance a single tick with 16, and recovers with 32–64.
inline constexpr int kKeepCappedSubsteps = 16;
/// Most times a tick is re-solved after releasing speculative body contacts that ended pulling
/// (each round only while the tick's budget lasts; rounds cut short count as ReleasesSkipped). A
/// step kept with contacts still pulling feeds energy in: 2 rounds let a needle falling over onto
/// the coarse liver start hundreds of speculative contacts and blow up (177 → 8,192 contacts in
/// three ticks); 8 let it settle (Needle.ANeedleLetGoFallsOntoTheLiverWithoutGainingEnergy).
inline constexpr int kMaxContactReleases = 8;

/// What the engine cut short because the tick's time budget ran out (the worst, if several).
/// Each is a stable way to finish the tick (engine/step_with_recovery.hpp).
enum class Degradation : uint8_t {
  None,
  ReleasesSkipped,  ///< pulling speculative body contacts kept for this tick (a slight stickiness)
  NewtonStopped,    ///< Newton iterations stopped at the last accepted iterate (each lowered Φ)
  SolveTruncated,   ///< CG stopped at the deadline: its iterate is kept (never worse than no
                    ///< correction: see CgSolver::solve's safe start), warm start not extrapolated
  LadderStopped,    ///< sub-steps stopped early: the tissue advanced only part of the tick
  Held              ///< no sane step in time: rolled back and held still (velocities zeroed)
};
std::string_view degradation_name(Degradation d);

/// Everything one tick produces besides the new state, in one place. It lives in the
/// TickWorkspace (its arrays sized at load) and is overwritten by the next tick: copy what you
/// keep (a copy allocates — never copy it in a real-time loop).
struct TickReport {
  TickStatus status = TickStatus::Ok;
  SolveStats solve;                         ///< linear solver iterations and residual
  NewtonStats newton;                       ///< Newton iterations (solver.newton_iterations > 1)
  double elastic_energy = 0;                ///< at the state the tick started from
  std::array<int64_t, kStageCount> stage_ns{};  ///< wall time per stage
  std::array<bool, kStageCount> stage_ran{};    ///< false: skipped (nothing to do)
  int substeps = 1;  ///< sub-steps the tick finally used (> 1: it was retried, see Recovered)
  int contact_releases = 0;  ///< re-solves after releasing pulling speculative body contacts
  int64_t total_ns = 0;
  /// Of total_ns, the time the tick waited for a late preconditioner refresh: headless runs
  /// swap refreshed factors on a fixed schedule (deterministic results) and wait for a late
  /// worker; `serve` never waits. The wait moves the tick's deadline with it and does not count
  /// against the budget (over_budget), so a headless tick does the work a served one would.
  /// Not in any stage's time (it happens in assemble's, which leaves it out).
  int64_t refresh_wait_ns = 0;
  int64_t budget_ns = 0;     ///< this tick's time budget (0: none)
  /// The deadline check at which the tick ran out of time (−1: it did not): what a session log
  /// records so that a replay makes the same cuts.
  int64_t deadline_check = -1;
  bool over_budget = false;  ///< total_ns − refresh_wait_ns > budget_ns (the budget was not kept)
  Degradation degradation = Degradation::None;  ///< what the budget cut short
  /// A step whose linear solve did not converge (capped or truncated) is kept only without an
  /// energy gain: what the guard did (the last step or sub-step it acted on) and the energy it
  /// took out over the tick (J). See TimeStepper::energy_guard.
  EnergyLimit energy_limit = EnergyLimit::None;
  double energy_removed = 0;
  std::vector<ToolOutput> tools;    ///< per scenario tool: contact, end-of-step force, feedback
  BodyContactOutput body_contact;   ///< body–body contacts (zero without `body_contact:`)
  /// Per rigid body: its contacts with the tissue and other bodies this tick (rigid_contact.hpp).
  std::vector<RigidContactOutput> rigid_contact;
  /// Per rigid body: a needle's insertion this tick (rigid/needle_track.hpp; zeros for other bodies).
  std::vector<NeedleOutput> needles;
  /// Threads through the tissue (engine/thread_attach.hpp): punctures made this tick, and
  /// those a full State::punctures could not take (should stay 0).
  int32_t punctures_made = 0, punctures_dropped = 0;
  ThreadContactOutput thread_contact;  ///< the threads' contacts this tick (engine/thread_contact.hpp)
  int damage_events = 0;            ///< elements reaching a new damage level this tick
  /// Edges of the uncut mesh the blades cut this tick (in s.edge_cut; the topology follows when
  /// the runner swaps in the cut model).
  int cut_edges = 0;
  /// Multirate (solver.fem_every > 1): whether this tick stepped the tissue (always true
  /// otherwise).
  bool tissue_stepped = true;
  /// Their records (up to the capacity fixed at load; `tool`: a tool touching tissue then).
  std::vector<DamageEventRecord> damage_records;
};

/// Per-thread scratch of the tick and its report. Not part of the state. Invariant: every
/// vector is sized (or reserved) here, once; the tick only clears and refills them.
class TickWorkspace {
 public:
  explicit TickWorkspace(const Model& m);
  TimeStepper& stepper() { return stepper_; }
  const TimeStepper& stepper() const { return stepper_; }

  /// Contact points per tick at most (further ones are dropped and counted in ToolOutput).
  static constexpr size_t kMaxContacts = 16384;
  /// Damage records kept per tick at most (the count in TickReport::damage_events is exact).
  static constexpr size_t kMaxDamageRecords = 1024;
  TriangleBvh bvh;                      ///< surface triangles, refitted every tick
  std::vector<ContactSpring> springs;   ///< this tick's contacts (capacity fixed at load)
  std::vector<double> body_boxes;       ///< body contact's per-body boxes (sized at load)
  std::vector<BodyContactPair> body_pairs;  ///< this tick's body contacts (capacity fixed at load)
  /// Surface point positions and velocities of a cut surface (sized at load; empty when the
  /// surface has no embedded points: the DOF arrays are used directly).
  std::vector<double> surface_x, surface_v;
  /// Positions and velocities at the start of the tick, for rollback (sized once).
  std::vector<double> backup_x, backup_v;
  /// The visco-elastic internal variables at the start of the tick (empty without them).
  std::vector<double> backup_visco_q, backup_visco_s0;
  /// Rigid bodies touching something this tick: the body of each row (tissue/rigid_rows.hpp),
  /// each body's row (−1: stepped free), and the rows' inputs for the step (filled per step
  /// and sub-step: the gyroscopic part depends on its length). Sized at load.
  std::vector<int32_t> row_body, body_row;
  std::vector<double> row_mass, row_inertia, row_u0, row_force, row_du;
  RigidRowsInput rigid_in;
  /// The rigid bodies at the start of the tick, for rollback.
  std::vector<RigidState> backup_rigid;
  /// 3 per spring: each spring's force where a sub-step starts (StepInputs::spring_force;
  /// engine/step_with_recovery.cpp). Sized to the springs' capacity at load.
  std::vector<double> substep_force;
  /// This tick's speculative contacts of rigid bodies and threads (capacity fixed at load;
  /// rigid/rigid_contact.hpp, engine/thread_contact.hpp): released if they end the step pulling.
  std::vector<RigidContactPair> rigid_pairs;
  /// Threads' self-contact broad phase (engine/thread_contact.hpp): every rod segment's
  /// bounding sphere and the segments sorted along the sweep axis (sized to the segments at load).
  std::vector<SegmentSphere> segment_spheres;
  std::vector<int32_t> segment_order;
  /// Where this tick's self-contact springs begin in `springs` (the continuous check after the
  /// step looks for a pair's spring from there: thread_missed_self_contacts).
  size_t self_spring_begin = 0;
  /// Per tool, its hold on a rigid body this tick: the springs [hold_begin, hold_end).
  std::vector<int32_t> hold_begin, hold_end;
  /// Per rigid body, a needle's tip contact spring this tick (−1: none; rigid/needle_track.hpp).
  std::vector<int32_t> tip_spring;
  /// Per rigid body, the element whose face its tip touches (−1: none; Model::collision_tri_elem).
  std::vector<int32_t> tip_element;
  /// The needles' sliding track points and cutting fronts this tick (capacity fixed at load).
  std::vector<NeedleSlip> needle_slips;
  TickReport report;  ///< the last tick's outputs
  /// What the energy guard that follows an inexact step costs (one energy-only element pass):
  /// the median of three passes timed when the workspace is made, then a running mean (1/8) of
  /// the guard's measured times. A budgeted tick's solve stops 1.25 × this before the deadline,
  /// so the guard does not take the tick past it. 0 for an explicit integrator or a model the guard does not apply to (TimeStepper::energy_guard_applies).
  int64_t guard_ns = 0;

 private:
  TimeStepper stepper_;
};

/// The budget's accounting, in one place for every caller that times engine work (tick(),
/// `serve`'s multirate tissue worker): the work that started at t0 under `deadline_ns` (0: none)
/// took total_ns; it is over budget when it ended past the deadline, its waits for a late
/// preconditioner refresh left out (TickReport::refresh_wait_ns).
inline void close_report(TickReport& r, int64_t t0, int64_t deadline_ns) {
  r.total_ns = steady_now_ns() - t0;
  r.over_budget = deadline_ns > 0 && t0 + r.total_ns - r.refresh_wait_ns > deadline_ns;
}

}  // namespace stroma
