// collision/triangle_bvh: the surface BVH refitted in place answers sphere queries exactly as
// brute force does.

#include <gtest/gtest.h>
#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include "collision/triangle_bvh.hpp"
#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/tick.hpp"

using namespace stroma;

TEST(TriangleBvh, SphereQueryAfterRefitEqualsBruteForceOnBoxes) {
  std::mt19937 g(5);
  std::uniform_real_distribution<double> u(-1, 1);
  const int n = 3000;
  std::vector<double> x(3 * n);
  for (double& v : x) v = u(g);
  std::vector<TriangleBvh::Triangle> tris;
  for (int i = 0; i + 2 < n; i += 3) tris.push_back({i, i + 1, (i + 7) % n});
  TriangleBvh bvh;
  bvh.build(tris, x.data());
  for (double& v : x) v += 0.3 * u(g);  // deform: the topology stays, the boxes must follow
  bvh.refit(x.data());
  for (int q = 0; q < 200; ++q) {
    const double c[3] = {u(g), u(g), u(g)};
    const double r = 0.02 + 0.2 * std::fabs(u(g));
    std::set<int32_t> got, want;
    bvh.query_sphere(c, r, x.data(), [&](int32_t t) { got.insert(t); });
    for (size_t t = 0; t < tris.size(); ++t) {
      double d2 = 0;
      for (int k = 0; k < 3; ++k) {
        double lo = 1e300, hi = -1e300;
        for (int a = 0; a < 3; ++a) {
          lo = std::min(lo, x[3 * tris[t][a] + k]);
          hi = std::max(hi, x[3 * tris[t][a] + k]);
        }
        const double v = c[k] < lo ? lo - c[k] : (c[k] > hi ? c[k] - hi : 0.0);
        d2 += v * v;
      }
      if (d2 <= r * r) want.insert(static_cast<int32_t>(t));
    }
    EXPECT_EQ(got, want) << "query " << q;
  }
}

