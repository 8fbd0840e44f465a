#pragma once
/// \file tick.hpp
/// One simulation tick as a short function of named, timed stages:
///   read inputs → collide → assemble → solve → integrate → damage → hand off.
/// Stages a scene does not need are skipped (and report zero time). The same tick runs
/// headless and in the real-time server. It never allocates, locks, logs or throws: problems
/// come back as a status code.

#include <array>
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
  NonFinite            ///< NaN/Inf appeared in the solve; the state was not advanced
};

/// What one tick reports.
struct TickReport {
  TickStatus status = TickStatus::Ok;
  SolveStats solve;                         ///< linear solver iterations and residual
  double elastic_energy = 0;                ///< at the state the tick started from
  std::array<int64_t, kStageCount> stage_ns{};  ///< wall time per stage
  std::array<bool, kStageCount> stage_ran{};    ///< false: skipped (nothing to do)
  int damage_events = 0;                        ///< elements reaching a new damage level
  int64_t total_ns = 0;
};

/// Per-thread scratch of the tick (the TimeStepper's work arrays). Not part of the state.
class TickWorkspace {
 public:
  explicit TickWorkspace(const Model& m) : stepper_(m.fem, m.stepper) {
    stepper_.prepare(m.time_step);
    if (m.has_damage) damage_events.reserve(1024);
    if (m.has_contact) {  // pay only for use: no tool shape, no BVH
      bvh.build(m.collision_triangles, m.fem.rest.data());
      springs.reserve(kMaxContacts);
    }
  }
  TimeStepper& stepper() { return stepper_; }
  const TimeStepper& stepper() const { return stepper_; }

  /// Contact points per tick at most (further ones are dropped and counted in ToolState).
  static constexpr size_t kMaxContacts = 16384;
  TriangleBvh bvh;                      ///< surface triangles, refitted every tick
  std::vector<ContactSpring> springs;   ///< this tick's contacts (capacity fixed at load)
  /// Elements that reached a new damage level this tick (capacity fixed at load).
  std::vector<DamageEventRecord> damage_events;

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
