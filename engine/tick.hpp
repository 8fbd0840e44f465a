#pragma once
/// \file tick.hpp
/// One simulation tick as a short function of named, timed stages:
///   read inputs → collide → assemble → solve → integrate → damage → hand off.
/// Stages a scene does not need are skipped (and report zero time). The same tick runs
/// headless and in the real-time server. It never allocates, locks, logs or throws: problems
/// come back as a status code.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string_view>

#include "engine/model.hpp"
#include "collision/triangle_bvh.hpp"
#include "engine/damage.hpp"
#include "engine/state.hpp"
#include "tissue/time_stepper.hpp"

namespace stroma {

/// Named stages of a tick, in order.
enum class Stage : int { ReadInputs, Collide, Assemble, Solve, Integrate, Damage, HandOff, Count };
inline constexpr int kStageCount = static_cast<int>(Stage::Count);
/// snake_case stage name, as used in summary.json and metrics.csv.
std::string_view stage_name(Stage s);

/// How a tick ended.
enum class TickStatus : uint8_t {
  Ok,
  SolverNotConverged,  ///< the linear solve hit its cap (state is still finite and advanced)
  Recovered,           ///< the full step failed (NaN/Inf in the solve or the state, or a node moving
                       ///< more than half the scene's size in one step); it was rolled back and
                       ///< redone in `substeps` sub-steps
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
/// Most times a tick is re-solved after releasing speculative body contacts that ended pulling.
inline constexpr int kMaxContactReleases = 2;

/// What one tick reports.
struct TickReport {
  TickStatus status = TickStatus::Ok;
  SolveStats solve;                         ///< linear solver iterations and residual
  NewtonStats newton;                       ///< Newton iterations (solver.newton_iterations > 1)
  double elastic_energy = 0;                ///< at the state the tick started from
  std::array<int64_t, kStageCount> stage_ns{};  ///< wall time per stage
  std::array<bool, kStageCount> stage_ran{};    ///< false: skipped (nothing to do)
  int damage_events = 0;                        ///< elements reaching a new damage level
  int substeps = 1;  ///< sub-steps the tick finally used (> 1: it was retried, see Recovered)
  int64_t total_ns = 0;
};

/// Per-thread scratch of the tick (the TimeStepper's work arrays). Not part of the state.
class TickWorkspace {
 public:
  explicit TickWorkspace(const Model& m) : stepper_(m.fem, m.stepper) {
    stepper_.prepare(m.time_step);
    backup_x.resize(m.fem.rest.size());
    backup_v.resize(m.fem.rest.size());
    // A step (or sub-step) that moves a node by more than half the scene's size has diverged.
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (size_t i = 0; i < m.fem.rest.size(); ++i) {
      lo[i % 3] = std::min(lo[i % 3], m.fem.rest[i]);
      hi[i % 3] = std::max(hi[i % 3], m.fem.rest[i]);
    }
    const double d2 = (hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                      (hi[2] - lo[2]) * (hi[2] - lo[2]);
    max_step_displacement = 0.5 * std::sqrt(d2);
    if (m.has_damage) damage_events.reserve(1024);
    if (m.has_contact) {  // pay only for use: no tool shape, no BVH
      bvh.build(m.collision_triangles, m.fem.rest.data());
      springs.reserve(kMaxContacts);
    }
    if (m.body_contact) {
      body_boxes.resize(6 * m.fem.bodies.size());
      body_pairs.reserve(kMaxContacts / 2);
    }
  }
  TimeStepper& stepper() { return stepper_; }
  const TimeStepper& stepper() const { return stepper_; }

  /// Contact points per tick at most (further ones are dropped and counted in ToolState).
  static constexpr size_t kMaxContacts = 16384;
  TriangleBvh bvh;                      ///< surface triangles, refitted every tick
  std::vector<ContactSpring> springs;   ///< this tick's contacts (capacity fixed at load)
  std::vector<double> body_boxes;       ///< body contact's per-body boxes (sized at load)
  std::vector<BodyContactPair> body_pairs;  ///< this tick's body contacts (capacity fixed at load)
  /// Elements that reached a new damage level this tick (capacity fixed at load).
  std::vector<DamageEventRecord> damage_events;
  /// Positions and velocities at the start of the tick, for rollback (sized once).
  std::vector<double> backup_x, backup_v;
  /// Largest node displacement one step (or sub-step) may make before it counts as diverged.
  double max_step_displacement = 0;

 private:
  TimeStepper stepper_;
};

/// Collide stage on its own: contacts of every shaped tool at s.x into w (and the tools'
/// contact outputs into s.tools). tick() calls it; the static solver calls it per iteration.
void collide(const Model& m, State& s, TickWorkspace& w);

/// Advances `s` by one time step of the model. `inputs` are tool commands that take effect at
/// the start of this tick (read_inputs stage; skipped when the scene has no tools).
TickReport tick(const Model& m, State& s, TickWorkspace& w, const ToolInput* inputs = nullptr,
                int input_count = 0);

}  // namespace stroma
