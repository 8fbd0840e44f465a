#include "engine/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "engine/cut_worker.hpp"
#include "tissue/clock.hpp"
#include "tissue/demand.hpp"

namespace stroma {

Simulation::Simulation(std::shared_ptr<const Model> model, SimulationOptions options)
    : opt_(options),
      model_(model ? std::move(model) : throw std::invalid_argument("Simulation: no model")),
      original_(model_),
      state_(State::initial(*model_)),
      initial_(state_),
      work_(std::make_unique<TickWorkspace>(*model_)),
      port_(model_->tools, model_->time_step) {
  if (opt_.realtime) work_->stepper().set_realtime(true);
  const size_t n = model_->tools.size();
  inputs_.reserve(2 * n + 16);
  held_.reserve(n);
  if (model_->cutting && opt_.cut_builds == CutBuilds::OnWorker)
    cutter_ = std::make_unique<CutWorker>(model_, model_->cut_edge_dofs.size(), opt_.registry);
  if (opt_.multirate_on_worker && model_->fem_every > 1)
    multirate_ = std::make_unique<MultirateWorker>(*model_, *work_, state_);
}

Simulation::~Simulation() = default;

int Simulation::submit_scripts(const std::vector<Trajectory>& scripts, double at) {
  int n = 0;
  const size_t tools = std::min(scripts.size(), model_->tools.size());
  const double t_sample = at >= 0 ? at : state_.time;
  const int64_t client_ns = std::llround(t_sample * 1e9);
  for (size_t t = 0; t < tools; ++t) {
    if (scripts[t].keys.empty() || state_.tools[t].posed) continue;
    port_.submit(static_cast<int>(t), scripts[t].sample(t_sample), static_cast<uint64_t>(state_.step + 1), client_ns,
                 client_ns);
    ++n;
  }
  return n;
}

int Simulation::take_commands() {
  inputs_.resize(model_->tools.size());  // within the capacity reserved at construction
  int n = port_.take(inputs_.data(), static_cast<int>(model_->tools.size()));
  inputs_.resize(static_cast<size_t>(n));
  if (opt_.hold == ToolHold::Repeat) {
    // A tool with a new command takes it; every other tool commanded before repeats the pose
    // its state holds (the last command applied) — read from the state, so a restored state
    // repeats what it held (a pose set from Python stays set across a snapshot), in tool order.
    size_t taken = 0;
    held_.clear();
    for (size_t t = 0; t < state_.tools.size(); ++t) {
      if (taken < static_cast<size_t>(n) && inputs_[taken].tool == static_cast<int32_t>(t)) {
        held_.push_back(inputs_[taken++]);
      } else if (state_.tools[t].last_command_time >= 0) {
        const ToolState& ts = state_.tools[t];
        ToolInput in;
        in.tool = static_cast<int32_t>(t);
        in.pose = ts.pose;
        in.client_time_ns = ts.client_time_ns;
        in.seq = static_cast<uint64_t>(state_.step + 1);
        held_.push_back(in);
      }
    }
    inputs_.assign(held_.begin(), held_.end());  // within the reserved capacity
  }
  return static_cast<int>(inputs_.size());
}

const TickReport& Simulation::step(Deadline deadline, const ToolInput* trusted, int trusted_count) {
  // (Synchronous) the last swap's old model, workspace and state: the report of the tick before
  // it is not read any more. Only a swap fills it: a served tick never builds or frees one here.
  if (retired_.model) retired_ = CutBuild{};
  STROMA_DEMAND(!multirate_ || trusted_count == 0, "Simulation::step: no replayed inputs with the multirate worker");
  if (multirate_) return step_multirate(deadline, [](const TickReport&, const State&, int64_t, const TickReport&) {});
  take_commands();
  for (int k = 0; k < trusted_count; ++k) inputs_.push_back(trusted[k]);
  return tick(*model_, state_, *work_, inputs_.data(), static_cast<int>(inputs_.size()), deadline);
}

bool Simulation::apply_build(CutBuild& b) {
  const int64_t refreshes = work_->stepper().preconditioner_refreshes();
  if (!apply_cut(b, model_, work_, state_)) return false;
  retired_refreshes_ += refreshes;  // the retired workspace's
  ++topology_swaps_;
  return true;
}

CutStageResult Simulation::cut(int cut_edges) {
  CutStageResult res;
  if (!model_->cutting) return res;
  if (cutter_) {
    const uint64_t posted = cutter_->stats().posted;
    res.swapped = cutter_->service(model_, work_, state_, cut_edges, state_.step);
    res.posted = cutter_->stats().posted != posted;
    if (res.swapped) {
      ++topology_swaps_;
      build_ms_total_ += cutter_->stats().build_ms_last;
      build_ms_max_ = std::max(build_ms_max_, cutter_->stats().build_ms_last);
    }
    return res;
  }
  if (cut_edges <= 0) return res;
  // The blade cut edges: the topology follows before the next tick. The old model, workspace
  // and state stay in retired_ until then, so the tick's report is still readable.
  CutBuild b = build_cut(*model_, state_.edge_cut);
  res.build_ms = b.build_ms;
  build_ms_total_ += b.build_ms;
  build_ms_max_ = std::max(build_ms_max_, b.build_ms);
  res.swapped = apply_build(b);
  if (res.swapped) retired_ = std::move(b);
  return res;
}

const TickReport& Simulation::advance(Deadline deadline) {
  const TickReport& r = step(deadline);
  if (model_->cutting) cut(r.cut_edges);
  return r;  // (a swap keeps the retired workspace, and r with it, until the next step)
}

bool Simulation::reset() {
  if (cutter_) {
    if (!cutter_->reset(original_, model_, work_)) return false;
  } else if (model_ != original_) {
    retired_ = CutBuild{};
    model_ = original_;
    work_ = std::make_unique<TickWorkspace>(*model_);
    if (opt_.realtime) work_->stepper().set_realtime(true);
  }
  state_ = initial_;  // a copy into arrays at least as large: no allocation
  if (multirate_) multirate_->reset();
  if (!opt_.commands_from_another_thread) port_.seed(state_.tools);
  return true;
}

void Simulation::restore(std::shared_ptr<const Model> m, const State& s) {
  if (cutter_ || multirate_ || opt_.commands_from_another_thread)
    throw std::logic_error("Simulation::restore: only for a simulation stepped and commanded on one thread");
  retired_ = CutBuild{};
  if (m != model_) {
    model_ = std::move(m);
    work_ = std::make_unique<TickWorkspace>(*model_);
    if (opt_.realtime) work_->stepper().set_realtime(true);
  }
  state_ = s;
  if (!opt_.commands_from_another_thread) port_.seed(state_.tools);
}

bool Simulation::swap_recorded(const std::vector<double>& edge_cut, double* build_ms) {
  CutBuild b = build_cut(*model_, edge_cut);
  build_ms_total_ += b.build_ms;
  build_ms_max_ = std::max(build_ms_max_, b.build_ms);
  if (build_ms) *build_ms = b.build_ms;
  if (!apply_build(b)) return false;
  retired_ = std::move(b);
  return true;
}

}  // namespace stroma
