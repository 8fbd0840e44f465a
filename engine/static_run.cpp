#include "engine/static_run.hpp"

#include <algorithm>
#include <cmath>

#include "engine/stage_timer.hpp"
#include "engine/trajectory.hpp"
#include "haptics/feedback.hpp"

namespace stroma {

namespace {

/// Sets the tools' poses a fraction u of the way from `from` to `to`.
void set_tool_poses(State& s, const StaticParameters& from, const StaticParameters& to, double u) {
  if (to.tool_poses.empty()) return;
  for (size_t k = 0; k < s.tools.size(); ++k) {
    const ToolPose& b = to.tool_poses[k];
    s.tools[k].pose = from.tool_poses.empty() || u >= 1.0 ? b : interpolate_pose(from.tool_poses[k], b, u);
  }
}

void scale_springs(std::vector<ContactSpring>& springs, double factor) {
  for (ContactSpring& sp : springs) {
    for (double& f : sp.force) f *= factor;
    for (double& k : sp.K) k *= factor;
    for (double& c : sp.C) c *= factor;
  }
}

}  // namespace

StaticOutcome solve_equilibrium(const Model& m, State& s, TickWorkspace& w, const StaticParameters& from,
                                const StaticParameters& to) {
  StaticOutcome out;
  TimeStepper& stepper = w.stepper();
  std::vector<double> x_equilibrium = s.tissue.x;
  double done = 0.0, step = 1.0, contact = to.contact;
  const auto inputs_at = [&](const TissueState&) {
    if (m.has_contact) {
      const int64_t t0 = steady_now_ns();
      collide(m, s, w);
      if (contact != 1.0) scale_springs(w.springs, contact);
      out.collide_ns += steady_now_ns() - t0;
    }
    return step_inputs(m, s, w);
  };
  const int64_t t0 = steady_now_ns();
  while (done < 1.0 && step >= kMinStaticIncrement) {
    const double u = std::min(1.0, done + step);
    set_tool_poses(s, from, to, u);
    contact = from.contact + u * (to.contact - from.contact);
    const double load = from.load + u * (to.load - from.load);
    const StaticResult r = stepper.solve_static(s.tissue, load, inputs_at);
    ++out.attempts;
    out.newton_iterations += r.newton_iterations;
    out.linear_iterations += r.linear_iterations;
    out.relative_residual = r.relative_residual;
    out.best_residual = r.best_residual;
    if (!r.converged && r.stalled && r.best_residual < kStaticRoundoffLevel) {
      // Newton reached the problem's round-off floor and stays there: a smaller increment would
      // stall at the same level. Stop and say why.
      std::copy(x_equilibrium.begin(), x_equilibrium.end(), s.tissue.x.begin());
      out.roundoff_stall = true;
      break;
    }
    if (r.converged) {
      done = u;
      ++out.increments;
      x_equilibrium = s.tissue.x;
      step = std::min(2.0 * step, 1.0 - done);
    } else {
      std::copy(x_equilibrium.begin(), x_equilibrium.end(), s.tissue.x.begin());
      step *= 0.5;
    }
  }
  out.converged = done >= 1.0;
  out.reached = done;
  if (!out.converged) {  // back to the last equilibrium and its parameters, contacts found there
    set_tool_poses(s, from, to, done);
    contact = from.contact + done * (to.contact - from.contact);
    inputs_at(s.tissue);
  }
  // The tools' outputs at the final positions (the contacts were found there by the last
  // iterate): for a static equilibrium the springs' forces are the contact forces themselves.
  for (size_t k = 0; k < m.tools.size(); ++k) {
    ToolOutput& o = w.report.tools[k];
    s.tools[k].force = o.force;
    s.tools[k].stiffness = o.stiffness;
    o.feedback = device_feedback(m.tools[k], s.tools[k], o, m.time_step);
  }
  out.solve_ns = steady_now_ns() - t0 - out.collide_ns;
  return out;
}

}  // namespace stroma
