#pragma once
/// \file serve_stats.hpp
/// `serve --stats FILE`, one part owning its option: the session's statistics as JSON at exit —
/// timing and misses, stage means, solver health, budgets, commands and controls, recording,
/// cutting and damage (docs/DDS.md lists the fields).

#include <cstdint>

#include <nlohmann/json.hpp>

#include "dds/dds_participant.hpp"
#include "engine/model.hpp"
#include "runtime/physics_loop.hpp"
#include "runtime/realtime.hpp"
#include "server/input_counters.hpp"
#include "server/serve.hpp"
#include "server/serve_record.hpp"

namespace stroma {

/// The --stats JSON of a finished session.
nlohmann::ordered_json stats_json(const ServeOptions& o, const Model& model, const PhysicsLoop& loop,
                                  const RealtimeResult& rt, const DdsParticipant& pp, const InputCounters& counters,
                                  uint64_t status_sent, const RecordStatus& record);

}  // namespace stroma
