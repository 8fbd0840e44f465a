#include "bench/accuracy/quarter_block_mesh.hpp"

#include <algorithm>
#include <cstdio>

namespace stroma {

std::vector<double> graded_coordinates(double h0, double ratio, double length) {
  std::vector<double> p{0.0};
  double h = h0;
  while (p.back() + h < length * 0.999) {
    p.push_back(p.back() + h);
    h *= ratio;
  }
  if (length - p.back() < 0.5 * h / ratio && p.size() > 1) p.back() = length;
  else p.push_back(length);
  return p;
}

std::string write_quarter_block(const std::string& path, double a, double H, double h0, double ratio) {
  const std::vector<double> xs = graded_coordinates(h0, ratio, a);
  std::vector<double> zs = graded_coordinates(h0, ratio, H);
  for (double& z : zs) z = H - z;
  std::reverse(zs.begin(), zs.end());
  const int nx = static_cast<int>(xs.size()), nz = static_cast<int>(zs.size());
  auto id = [&](int i, int j, int k) { return 1 + i + nx * (j + nx * k); };
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fprintf(f, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n", nx * nx * nz);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < nx; ++j)
      for (int i = 0; i < nx; ++i) std::fprintf(f, "%d %.17g %.17g %.17g\n", id(i, j, k), xs[i], xs[j], zs[k]);
  const int cells = (nx - 1) * (nx - 1) * (nz - 1);
  std::fprintf(f, "$EndNodes\n$Elements\n%d\n", 6 * cells);
  int e = 0;
  for (int k = 0; k + 1 < nz; ++k)
    for (int j = 0; j + 1 < nx; ++j)
      for (int i = 0; i + 1 < nx; ++i) {
        const int v000 = id(i, j, k), v100 = id(i + 1, j, k), v010 = id(i, j + 1, k), v110 = id(i + 1, j + 1, k);
        const int v001 = id(i, j, k + 1), v101 = id(i + 1, j, k + 1), v011 = id(i, j + 1, k + 1), v111 = id(i + 1, j + 1, k + 1);
        const int tets[6][4] = {{v000, v100, v110, v111}, {v000, v110, v010, v111}, {v000, v010, v011, v111},
                                {v000, v011, v001, v111}, {v000, v001, v101, v111}, {v000, v101, v100, v111}};
        for (const auto& t : tets) std::fprintf(f, "%d 4 2 0 1 %d %d %d %d\n", ++e, t[0], t[1], t[2], t[3]);
      }
  std::fprintf(f, "$EndElements\n");
  std::fclose(f);
  return path;
}

}  // namespace stroma
