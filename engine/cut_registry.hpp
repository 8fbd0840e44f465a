#pragma once
/// \file cut_registry.hpp
/// The cut models a served loop has built, for the threads that read its state frames.
///
/// A state frame of a cut model carries its positions in that model's DOF layout and the
/// model's serial (Model::cut_serial); the publisher needs the model to make surfaces of it.
/// The physics thread must not copy a shared_ptr into a frame (the last reference could then
/// drop, and a model be freed, on the physics thread), so the cut worker registers each model
/// it builds here, and the publisher looks frames' models up by serial. The physics thread never
/// touches this (its mutex is between the worker and the publisher).
///
/// Invariant: at most kKeep models, the newest; a frame is published within a few ticks of its
/// model being built, so its model is still here unless kKeep newer ones were built since — then
/// find() returns null and the publisher skips that frame (the next frame is of a newer model).

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>

#include "engine/model.hpp"

namespace stroma {

class CutModelRegistry {
 public:
  static constexpr size_t kKeep = 8;

  /// Worker thread: a model just built (serials increase).
  void add(std::shared_ptr<const Model> m) {
    std::lock_guard<std::mutex> lock(mutex_);
    models_.push_back(std::move(m));
    if (models_.size() > kKeep) models_.pop_front();  // (freed here, on the worker)
  }

  /// Publisher thread: the model of serial `serial`, or null if it is no longer (or not) here.
  std::shared_ptr<const Model> find(uint64_t serial) const {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& m : models_)
      if (m->cut_serial == serial) return m;
    return nullptr;
  }

 private:
  mutable std::mutex mutex_;
  std::deque<std::shared_ptr<const Model>> models_;
};

}  // namespace stroma
