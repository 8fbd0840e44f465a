#include "tissue/cut_walk_neighbours.hpp"

namespace stroma {

std::vector<int32_t> cut_copy_face_neighbours(const CutTopology& topo, const std::vector<Tet>& tets,
                                              const TetAdjacency& adj) {
  std::vector<int32_t> out(4 * topo.copies.size(), -1);
  for (size_t c = 0; c < topo.copies.size(); ++c) {
    const ElementCopy& me = topo.copies[c];
    const Tet& t = tets[size_t(me.tet)];
    for (int i = 0; i < 4; ++i) {
      const int32_t u = adj.face_neighbor[size_t(me.tet)][size_t(i)];
      if (u < 0) continue;
      const Tet& tu = tets[size_t(u)];
      // Local index in u of each of the face's nodes (the face opposite t's node i).
      int at_u[4] = {-1, -1, -1, -1};
      for (int k = 0; k < 4; ++k)
        for (int j = 0; j < 4; ++j)
          if (k != i && tu[size_t(j)] == t[size_t(k)]) at_u[k] = j;
      int32_t best = -1, best_shared = -1;
      for (int32_t o = topo.tet_copy_begin[size_t(u)]; o < topo.tet_copy_begin[size_t(u) + 1]; ++o) {
        const ElementCopy& other = topo.copies[size_t(o)];
        bool glued = true;
        int shared = 0;
        for (int k = 0; k < 4 && glued; ++k) {
          if (k == i) continue;
          if (at_u[k] < 0) {
            glued = false;  // (adjacency not of these tetrahedra: never on a CutBase)
            break;
          }
          glued = me.dof[size_t(k)] == other.dof[size_t(at_u[k])];
          shared += ((me.material >> k) & 1) & ((other.material >> at_u[k]) & 1);
        }
        if (glued && shared > best_shared) best = o, best_shared = shared;
      }
      out[4 * c + size_t(i)] = best;
    }
  }
  return out;
}

}  // namespace stroma
