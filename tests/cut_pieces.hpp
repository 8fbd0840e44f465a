#pragma once
/// \file cut_pieces.hpp
/// The tests' view of a cut beam's pieces: which DOFs went with the free end.

#include <cstdint>
#include <numeric>
#include <vector>

#include "engine/model.hpp"

namespace stroma::test_support {

/// The tissue DOFs of the piece holding the beam's free end (its node of largest rest x): the
/// connected part of the (cut) mesh, copies joined by shared DOFs. Rods' nodes are not in it.
inline std::vector<int32_t> free_piece(const Model& m) {
  const int32_t n = m.fem.num_nodes, tissue = m.fem.bodies.back().node_end;
  std::vector<int32_t> parent(static_cast<size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  for (const ElementParams& e : m.fem.elements)
    for (int k = 1; k < 4; ++k) parent[find(e.node[k])] = find(e.node[0]);
  int32_t tip = 0;
  for (int32_t d = 0; d < tissue; ++d)
    if (m.fem.rest[3 * d] > m.fem.rest[3 * tip]) tip = d;
  std::vector<int32_t> out;
  for (int32_t d = 0; d < tissue; ++d)
    if (find(d) == find(tip)) out.push_back(d);
  return out;
}

}  // namespace stroma::test_support
