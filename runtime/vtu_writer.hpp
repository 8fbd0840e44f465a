#pragma once
/// \file vtu_writer.hpp
/// ParaView output: VTK XML unstructured grids (ASCII) of the deformed bodies with point
/// displacement and per-element von Mises stress, and .pvd time series.

#include <string>
#include <utility>
#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"

namespace stroma {

/// Writes all bodies of state `s` to one .vtu file (one piece per body). Throws
/// std::runtime_error if the file cannot be written.
void write_vtu(const std::string& path, const Model& m, const State& s);

/// Writes a ParaView collection referencing (time, file) pairs (file names relative to the .pvd).
void write_pvd(const std::string& path, const std::vector<std::pair<double, std::string>>& frames);

}  // namespace stroma
