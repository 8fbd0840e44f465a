#include "bench/accuracy/thick_ring.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <vector>

namespace stroma {

namespace {

struct Law {
  double mu, lp, alpha, k1, k2;
  /// ψ′(I4) of the HGO fibre (tension only; the exponential's cap is far beyond this problem).
  double fibre_d1(double i4) const {
    const double x = i4 - 1;
    return x > 0 ? k1 * x * std::exp(k2 * x * x) : 0.0;
  }
  /// λ_r from q = R·W_r at radius R and λ_θ: W_r = μλ_r + λ′(λ_rλ_θ − α)λ_θ is linear in λ_r.
  double lambda_r(double q, double R, double lt) const { return (q / R + lp * alpha * lt) / (mu + lp * lt * lt); }
  double w_theta(double lr, double lt) const {
    return mu * lt + lp * (lr * lt - alpha) * lr + 2 * fibre_d1(lt * lt) * lt;
  }
};

/// Integrates from R = A with r(A) = a, q(A) = −p0·A to R = B; returns q(B) (0 at the solution)
/// and r(B) in `rb`.
double shoot(const Law& law, const ThickRing& g, double a, double* rb) {
  constexpr int kSteps = 20000;
  const double dR = (g.B - g.A) / kSteps;
  double r = a, q = -g.p0 * g.A, R = g.A;
  auto f = [&](double Rr, double rr, double qq, double* dr, double* dq) {
    const double lt = rr / Rr, lr = law.lambda_r(qq, Rr, lt);
    *dr = lr;
    *dq = law.w_theta(lr, lt);
  };
  for (int i = 0; i < kSteps; ++i) {
    double k1r, k1q, k2r, k2q, k3r, k3q, k4r, k4q;
    f(R, r, q, &k1r, &k1q);
    f(R + dR / 2, r + dR / 2 * k1r, q + dR / 2 * k1q, &k2r, &k2q);
    f(R + dR / 2, r + dR / 2 * k2r, q + dR / 2 * k2q, &k3r, &k3q);
    f(R + dR, r + dR * k3r, q + dR * k3q, &k4r, &k4q);
    r += dR / 6 * (k1r + 2 * k2r + 2 * k3r + k4r);
    q += dR / 6 * (k1q + 2 * k2q + 2 * k3q + k4q);
    R = g.A + (i + 1) * dR;
  }
  *rb = r;
  return q;
}

}  // namespace

ThickRingSolution solve_thick_ring(const ThickRing& g) {
  const double lambda = g.E * g.nu / ((1 + g.nu) * (1 - 2 * g.nu)), mu = g.E / (2 * (1 + g.nu));
  const Law law{mu, lambda + mu, 1 + mu / (lambda + mu), g.k1, g.k2};
  // q(B) grows with the inner radius a (a wider ring is in more tension). Bracket the root from
  // the rest radius (q(B) < 0: the pressure is not yet carried) outwards, then bisect; a shot that
  // overflows (a far too wide: the exponential fibres) counts as too wide.
  double rb = 0;
  auto q_end = [&](double a) {
    const double q = shoot(law, g, a, &rb);
    return std::isfinite(q) ? q : std::numeric_limits<double>::infinity();
  };
  ThickRingSolution s;
  double lo = g.A, hi = g.A * 1.01;
  if (!(q_end(lo) < 0)) throw std::runtime_error("thick ring reference: no pressure to carry");
  while (q_end(hi) < 0) {
    lo = hi;
    hi = g.A + 2 * (hi - g.A);
    if (hi > 100 * g.A) throw std::runtime_error("thick ring reference: no bracket");
  }
  for (s.shots = 0; s.shots < 200 && hi - lo > 1e-14 * g.A; ++s.shots) {
    const double mid = 0.5 * (lo + hi);
    (q_end(mid) < 0 ? lo : hi) = mid;
  }
  // The root lies in [lo, hi] (q(lo) < 0 ≤ q(hi) throughout), now ~1e-14·A wide.
  const double a1 = 0.5 * (lo + hi);
  q_end(a1);  // r(B) of the final shot
  s.u_inner = a1 - g.A;
  s.u_outer = rb - g.B;
  return s;
}

std::string write_quarter_ring_vtu(const std::string& path, const ThickRing& g, double layer, int nr, int nt, int nz) {
  auto id = [&](int i, int j, int k) { return i + (nr + 1) * (j + (nt + 1) * k); };
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + path);
  const int nodes = (nr + 1) * (nt + 1) * (nz + 1), cells = nr * nt * nz, tets = 6 * cells;
  std::fprintf(f, "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\">\n<UnstructuredGrid>\n");
  std::fprintf(f, "<Piece NumberOfPoints=\"%d\" NumberOfCells=\"%d\">\n<Points>\n", nodes, tets);
  std::fprintf(f, "<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n");
  std::vector<double> xyz(3 * static_cast<size_t>(nodes));
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= nt; ++j)
      for (int i = 0; i <= nr; ++i) {
        const double R = g.A + (g.B - g.A) * i / nr, th = 0.5 * M_PI * j / nt, z = layer * k / nz;
        // The symmetry planes exactly on x = 0 and y = 0.
        const double x = j == nt ? 0.0 : R * std::cos(th), y = j == 0 ? 0.0 : R * std::sin(th);
        double* p = &xyz[3 * static_cast<size_t>(id(i, j, k))];
        p[0] = x;
        p[1] = y;
        p[2] = z;
        std::fprintf(f, "%.17g %.17g %.17g\n", x, y, z);
      }
  std::fprintf(f, "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
  std::vector<double> dirs;
  dirs.reserve(3 * static_cast<size_t>(tets));
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < nt; ++j)
      for (int i = 0; i < nr; ++i) {
        const int v000 = id(i, j, k), v100 = id(i + 1, j, k), v010 = id(i, j + 1, k), v110 = id(i + 1, j + 1, k);
        const int v001 = id(i, j, k + 1), v101 = id(i + 1, j, k + 1), v011 = id(i, j + 1, k + 1), v111 = id(i + 1, j + 1, k + 1);
        const int tt[6][4] = {{v000, v100, v110, v111}, {v000, v110, v010, v111}, {v000, v010, v011, v111},
                              {v000, v011, v001, v111}, {v000, v001, v101, v111}, {v000, v101, v100, v111}};
        for (const auto& t : tt) {
          std::fprintf(f, "%d %d %d %d\n", t[0], t[1], t[2], t[3]);
          double c[2] = {0, 0};
          for (int v : t)
            for (int a = 0; a < 2; ++a) c[a] += xyz[3 * static_cast<size_t>(v) + a] / 4;
          const double th = std::atan2(c[1], c[0]);
          dirs.insert(dirs.end(), {-std::sin(th), std::cos(th), 0.0});
        }
      }
  std::fprintf(f, "</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
  for (int t = 1; t <= tets; ++t) std::fprintf(f, "%d\n", 4 * t);
  std::fprintf(f, "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
  for (int t = 0; t < tets; ++t) std::fprintf(f, "10\n");
  std::fprintf(f, "</DataArray>\n</Cells>\n<CellData>\n");
  std::fprintf(f, "<DataArray type=\"Float64\" Name=\"fibres\" NumberOfComponents=\"3\" format=\"ascii\">\n");
  for (size_t t = 0; t < dirs.size(); t += 3) std::fprintf(f, "%.17g %.17g %.17g\n", dirs[t], dirs[t + 1], dirs[t + 2]);
  std::fprintf(f, "</DataArray>\n</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
  std::fclose(f);
  return path;
}

}  // namespace stroma
