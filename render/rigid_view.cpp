#include "render/rigid_view.hpp"

#include <cmath>
#include <algorithm>

namespace stroma::render {

namespace {

/// World point of shape-frame point p: position + R(q) p.
struct Pose {
  double R[9], t[3];
  Pose(const double position[3], const double q[4]) {
    const double w = q[0], x = q[1], y = q[2], z = q[3];
    const double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
                         2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                         2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
    for (int k = 0; k < 9; ++k) R[k] = r[k];
    for (int k = 0; k < 3; ++k) t[k] = position[k];
  }
  Vec3f operator()(double a, double b, double c) const {
    return {static_cast<float>(t[0] + R[0] * a + R[1] * b + R[2] * c),
            static_cast<float>(t[1] + R[3] * a + R[4] * b + R[5] * c),
            static_cast<float>(t[2] + R[6] * a + R[7] * b + R[8] * c)};
  }
};

void add_triangle(std::vector<float>& out, const Vec3f& a, const Vec3f& b, const Vec3f& c) {
  for (const Vec3f* p : {&a, &b, &c}) out.insert(out.end(), p->begin(), p->end());
}

}  // namespace

RigidView make_rigid_view(const RigidShapeDesc& s, const double position[3], const double orientation[4],
                          const float* track, size_t track_points) {
  const Pose P(position, orientation);
  RigidView v;
  switch (s.kind) {
    case RigidShapeDesc::Sphere: {
      const Vec3f c = P(0, 0, 0);
      v.capsules.push_back({c, c, static_cast<float>(s.radius)});
      break;
    }
    case RigidShapeDesc::Capsule:
      v.capsules.push_back({P(0, 0, -0.5 * s.length), P(0, 0, 0.5 * s.length), static_cast<float>(s.radius)});
      break;
    case RigidShapeDesc::Needle: {
      v.steel = true;
      const float r = static_cast<float>(s.wire_radius);
      if (!s.curved || s.arc_radius <= 0) {
        v.capsules.push_back({P(0, 0, 0), P(0, 0, s.length), r});
        break;
      }
      const double phi = s.length / s.arc_radius;  // the arc's angle (its length over its radius)
      for (int i = 0; i < kNeedleSegments; ++i) {
        const double a0 = phi * i / kNeedleSegments, a1 = phi * (i + 1) / kNeedleSegments;
        v.capsules.push_back({P(s.arc_radius * std::cos(a0), s.arc_radius * std::sin(a0), 0),
                              P(s.arc_radius * std::cos(a1), s.arc_radius * std::sin(a1), 0), r});
      }
      break;
    }
    case RigidShapeDesc::Box: {
      const double h[3] = {0.5 * s.size[0], 0.5 * s.size[1], 0.5 * s.size[2]};
      // Corner i has coordinate k at +h[k] when bit k of i is set.
      auto corner = [&](int i) { return P((i & 1) ? h[0] : -h[0], (i & 2) ? h[1] : -h[1], (i & 4) ? h[2] : -h[2]); };
      // Each face as a quad of corners, counter-clockwise seen from outside.
      static constexpr int kFaces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
      for (const auto& f : kFaces) {
        add_triangle(v.triangles, corner(f[0]), corner(f[1]), corner(f[2]));
        add_triangle(v.triangles, corner(f[0]), corner(f[2]), corner(f[3]));
      }
      break;
    }
    case RigidShapeDesc::Mesh: {
      const size_t nv = s.vertices.size() / 3;
      auto vertex = [&](uint32_t i) {
        return P(s.vertices[3 * size_t(i)], s.vertices[3 * size_t(i) + 1], s.vertices[3 * size_t(i) + 2]);
      };
      for (size_t t = 0; t + 2 < s.triangles.size(); t += 3) {
        const uint32_t a = s.triangles[t], b = s.triangles[t + 1], c = s.triangles[t + 2];
        if (a >= nv || b >= nv || c >= nv) continue;
        add_triangle(v.triangles, vertex(a), vertex(b), vertex(c));
      }
      break;
    }
  }
  for (size_t i = 0; i < track_points; ++i) v.track.push_back({track[3 * i], track[3 * i + 1], track[3 * i + 2]});
  return v;
}

RigidView make_thread_view(const float* positions, size_t nodes, double diameter) {
  RigidView v;
  v.thread = true;
  const float r = static_cast<float>(std::max(0.5 * diameter, kThreadMinDrawRadius));
  for (size_t i = 0; i + 1 < nodes; ++i) {
    ToolView::Capsule c;
    for (int k = 0; k < 3; ++k) {
      c.a[size_t(k)] = positions[3 * i + size_t(k)];
      c.b[size_t(k)] = positions[3 * i + 3 + size_t(k)];
    }
    c.r = r;
    v.capsules.push_back(c);
  }
  return v;
}

}  // namespace stroma::render
