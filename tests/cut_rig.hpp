#pragma once
/// \file cut_rig.hpp
/// The cutting tests' rig: a scalpel, a suture anchored in a body, and which DOFs of a cut beam
/// went with its free end.

#include <cstdint>
#include <numeric>
#include <vector>

#include "engine/model.hpp"
#include "scene/scenario_spec.hpp"

namespace stroma::test_support {

/// A scalpel: a blade of `half_thickness` (default 0.5 mm) and `edge_length` edge that cuts
/// (toughness default 200 J/m², liver-like), fast enough for any test sweep, live for 10 s after
/// a command.
inline ToolEntry scalpel(double edge_length, double half_thickness = 0.0005, double toughness = 200) {
  ToolEntry t;
  t.spec.name = "scalpel";
  t.spec.shape = ToolShape::Blade;
  t.spec.radius = half_thickness;
  t.spec.shaft_length = edge_length;
  t.spec.timeout = 10;
  t.spec.max_speed = 50;
  t.spec.cuts = true;
  t.spec.cut_toughness = toughness;
  return t;
}

/// A grasping tip: a sphere of `radius` that can close on what is within its reach (a body's
/// nodes, a thread's point), live for 10 s after a command.
inline ToolEntry grasping_tip(const std::string& name, double radius, double max_speed) {
  ToolEntry t;
  t.spec.name = name;
  t.spec.shape = ToolShape::Sphere;
  t.spec.radius = radius;
  t.spec.timeout = 10;
  t.spec.max_speed = max_speed;
  t.spec.can_grasp = true;
  return t;
}

/// The scalpel's pose with its edge (local x) along world z, its normal (local y) along world x
/// and its back (local z) along world y, at (x, y, z): swept up (+y) it cuts the plane at x.
inline ToolPose blade_pose(double x, double y, double z) {
  ToolPose p;
  p.position = {x, y, z};
  p.orientation = {0.5, -0.5, -0.5, -0.5};
  return p;
}

/// A USP 3-0 suture (0.2 mm, E 5 GPa, 1100 kg/m³) of `length` in `segments`, straight from
/// `start` along `direction`, its first end anchored in tissue body `body`.
inline ThreadSpec anchored_suture(const std::string& body, double length, int segments, const Vec3& start,
                                  const Vec3& direction) {
  ThreadSpec th;
  th.name = "suture";
  th.length = length;
  th.segments = segments;
  th.diameter = 2e-4;
  th.young_modulus = 5e9;
  th.density = 1100;
  th.start = start;
  th.direction = direction;
  ThreadSpec::Attach a;
  a.target = body;
  th.attach.push_back(a);
  return th;
}

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
