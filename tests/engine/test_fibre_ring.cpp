// The inhomogeneous fibre problem (bench/accuracy/thick_ring.hpp): an inflated thick-walled ring
// with circumferential fibres, directions read per tetrahedron from the mesh, against the 1-D
// reference of the same constitutive law. Also checks the reference itself: without fibres and
// at small pressure it is the linear plane-strain Lamé solution.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "bench/accuracy/accuracy_suite.hpp"
#include "bench/accuracy/thick_ring.hpp"

using namespace stroma;
namespace fs = std::filesystem;

TEST(FibreRing, ReferenceIsLameAtSmallPressureWithoutFibres) {
  ThickRing g;
  g.k1 = 0;
  g.p0 = 1.0;  // Pa: strains ~1e-4
  const ThickRingSolution s = solve_thick_ring(g);
  // Plane strain Lamé: u(r) = (1 + ν)/E · p A²/(B² − A²) · ((1 − 2ν) r + B²/r).
  const double c = (1 + g.nu) / g.E * g.p0 * g.A * g.A / (g.B * g.B - g.A * g.A);
  const double ua = c * ((1 - 2 * g.nu) * g.A + g.B * g.B / g.A), ub = c * ((1 - 2 * g.nu) * g.B + g.B);
  EXPECT_NEAR(s.u_inner, ua, 1e-3 * ua);
  EXPECT_NEAR(s.u_outer, ub, 1e-3 * ub);
}

TEST(FibreRing, FemMatchesTheOneDimensionalReferenceAndTheFibresMatter) {
  const fs::path dir = fs::temp_directory_path() / ("stroma_fibre_ring_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const ThickRing g;
  const ThickRingSolution ref = solve_thick_ring(g);
  ThickRing matrix = g;
  matrix.k1 = 0;
  const double u_matrix = solve_thick_ring(matrix).u_inner;
  // The fibres carry most of the hoop load: the matrix alone would inflate far more.
  EXPECT_GT(u_matrix, 1.5 * ref.u_inner);
  // A real inflation: the inner wall's fibres stretched by several per cent, into the
  // exponential's stiffening.
  EXPECT_GT(ref.u_inner / g.A, 0.05);
  // Linear tetrahedra: the displacement converges at second order in the cell size.
  const AccuracyPoint coarse = run_fibre_ring(dir.string(), g, 4, 16, 1);
  const AccuracyPoint fine = run_fibre_ring(dir.string(), g, 8, 32, 1);
  ASSERT_TRUE(coarse.ok) << coarse.failure;
  ASSERT_TRUE(fine.ok) << fine.failure;
  EXPECT_DOUBLE_EQ(coarse.reference, ref.u_inner);
  EXPECT_LT(fine.error, 0.01) << fine.value << " vs " << ref.u_inner;
  EXPECT_GT(coarse.error / fine.error, 2.5) << coarse.error << " then " << fine.error;
  EXPECT_LT(fine.value, ref.u_inner);  // displacement-based elements are too stiff, not too soft
  fs::remove_all(dir);
}
