#include "engine/tick.hpp"

#include <chrono>
#include <cmath>

namespace stroma {

std::string_view stage_name(Stage s) {
  switch (s) {
    case Stage::ReadInputs: return "read_inputs";
    case Stage::Collide: return "collide";
    case Stage::Assemble: return "assemble";
    case Stage::Solve: return "solve";
    case Stage::Integrate: return "integrate";
    case Stage::Damage: return "damage";
    case Stage::HandOff: return "hand_off";
    case Stage::Count: break;
  }
  return "?";
}

namespace {

inline int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

/// Times one stage into the report.
class StageTimer {
 public:
  StageTimer(TickReport& r, Stage s) : r_(r), s_(static_cast<int>(s)), t0_(now_ns()) {}
  ~StageTimer() {
    r_.stage_ns[s_] = now_ns() - t0_;
    r_.stage_ran[s_] = true;
  }

 private:
  TickReport& r_;
  int s_;
  int64_t t0_;
};

bool all_finite(const std::vector<double>& a) {
  double acc = 0;
  for (double v : a) acc += v * 0.0;  // NaN/Inf poison the sum; finite values add exact zeros
  return acc == 0.0;
}

}  // namespace

TickReport tick(const Model& m, State& s, TickWorkspace& w, const ToolInput* inputs,
                int input_count) {
  TickReport r;
  const int64_t t0 = now_ns();
  const double h = m.time_step;
  TimeStepper& stepper = w.stepper();
  if (!m.tools.empty()) {
    StageTimer t(r, Stage::ReadInputs);
    for (int i = 0; i < input_count; ++i) {
      const ToolInput& in = inputs[i];
      ToolState& ts = s.tools[in.tool];
      ts.pose = in.pose;
      ts.seq = in.seq;
      ts.client_time_ns = in.client_time_ns;
      ts.last_command_time = s.time;
      ts.active = true;
    }
    // A silent client: the tool holds its last accepted pose, then goes idle.
    for (size_t k = 0; k < s.tools.size(); ++k)
      if (s.tools[k].active && s.time - s.tools[k].last_command_time > m.tools[k].timeout)
        s.tools[k].active = false;
  }
  // collide: tools touch nothing until contact exists (issue 4) → skipped.
  {
    StageTimer t(r, Stage::Assemble);
    r.elastic_energy = stepper.assemble(s.tissue, h);
  }
  {
    StageTimer t(r, Stage::Solve);
    r.solve = stepper.solve(s.tissue);
  }
  if (!std::isfinite(r.solve.relative_residual) || !all_finite(s.tissue.dv)) {
    r.status = TickStatus::NonFinite;
    std::fill(s.tissue.dv.begin(), s.tissue.dv.end(), 0.0);  // keep the warm start usable
    r.total_ns = now_ns() - t0;
    return r;
  }
  {
    StageTimer t(r, Stage::Integrate);
    stepper.integrate(s.tissue, h);
  }
  // damage, hand_off: nothing to do headless without damage models or subscribers → skipped.
  s.time = static_cast<double>(s.step + 1) * h;
  ++s.step;
  if (!r.solve.converged) r.status = TickStatus::SolverNotConverged;
  r.total_ns = now_ns() - t0;
  return r;
}

}  // namespace stroma
