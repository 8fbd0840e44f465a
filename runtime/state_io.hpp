#pragma once
/// \file state_io.hpp
/// Reference states for regression checks: node positions as CSV (`node,x,y,z`, full double
/// precision, global node order), and the comparison `stroma check` reports.

#include <string>
#include <vector>

#include "engine/model.hpp"
#include "engine/state.hpp"

namespace stroma {

/// Writes the positions of every node of `s` (17 significant digits: round-trips exactly).
void write_state_csv(const std::string& path, const State& s);
/// Reads positions written by write_state_csv (3n values). Throws InputError (file:line).
std::vector<double> read_state_csv(const std::string& path);

/// Nodal position differences between two position arrays of equal size.
struct StateDifference {
  double max_error = 0;   ///< largest Euclidean nodal difference (m)
  double mean_error = 0;  ///< mean Euclidean nodal difference (m)
  int32_t worst_node = -1;
};
StateDifference compare_positions(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace stroma
