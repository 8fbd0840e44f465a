#include "collision/body_contact.hpp"

#include <algorithm>
#include <cmath>

#include "tissue/triangle_closest_point.hpp"

namespace stroma {

namespace {

/// Adds the (area-weighted, twice the area long) normal of triangle t at positions x to n.
inline void accumulate_normal(const double* x, const std::array<int32_t, 3>& t, double* n) {
  const double* a = x + 3 * t[0];
  const double* b = x + 3 * t[1];
  const double* c = x + 3 * t[2];
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  n[0] += u[1] * w[2] - u[2] * w[1];
  n[1] += u[2] * w[0] - u[0] * w[2];
  n[2] += u[0] * w[1] - u[1] * w[0];
}

inline double norm3(const double* a) { return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

/// δ = (c − p)·n: how far vertex p is behind the plane through the face point c (w on tri).
inline double depth_at(const double* x, int32_t vertex, const std::array<int32_t, 3>& tri, const double* w,
                       const double* n) {
  double d = 0;
  for (int k = 0; k < 3; ++k) {
    const double c = w[0] * x[3 * tri[0] + k] + w[1] * x[3 * tri[1] + k] + w[2] * x[3 * tri[2] + k];
    d += (c - x[3 * vertex + k]) * n[k];
  }
  return d;
}

}  // namespace

void body_contact(const BodyContactModel& bc, const ContactSurface& surf, const TriangleBvh& bvh,
                  const double* x, const double* v, double h, const double* g, double* boxes,
                  std::vector<ContactSpring>& springs, std::vector<BodyContactPair>& pairs, BodyContactOutput& out) {
  out = BodyContactOutput{};
  pairs.clear();
  const int nb = static_cast<int>(bc.body_vertex_begin.size()) - 1;
  const double hv = v ? h : 0.0;
  // Broad phase: each body's surface box now and at the predicted positions, grown by its depth.
  for (int b = 0; b < nb; ++b) {
    double* bx = boxes + 6 * b;
    const double r = bc.body_depth[b];
    for (int k = 0; k < 3; ++k) bx[k] = 1e300, bx[3 + k] = -1e300;
    for (int32_t i = bc.body_vertex_begin[b]; i < bc.body_vertex_begin[b + 1]; ++i)
      for (int k = 0; k < 3; ++k) {
        const double c = x[3 * bc.vertex[i] + k];
        const double c1 = c + (v ? hv * (v[3 * bc.vertex[i] + k] + hv * g[k]) : 0.0);
        bx[k] = std::min({bx[k], c - r, c1 - r});
        bx[3 + k] = std::max({bx[3 + k], c + r, c1 + r});
      }
  }
  auto in_box = [](const double* bx, const double* p) {
    return p[0] >= bx[0] && p[0] <= bx[3] && p[1] >= bx[1] && p[1] <= bx[4] && p[2] >= bx[2] && p[2] <= bx[5];
  };
  auto boxes_overlap = [](const double* a, const double* b) {
    for (int k = 0; k < 3; ++k)
      if (a[k] > b[3 + k] || b[k] > a[3 + k]) return false;
    return true;
  };
  for (int a = 0; a < nb; ++a) {
    const double* ba = boxes + 6 * a;
    bool any = false;
    for (int b = 0; b < nb && !any; ++b) any = b != a && boxes_overlap(ba, boxes + 6 * b);
    if (!any) continue;
    for (int32_t i = bc.body_vertex_begin[a]; i < bc.body_vertex_begin[a + 1]; ++i) {
      const int32_t vi = bc.vertex[i];
      if (bc.vertex_fixed[i]) continue;  // cannot move: the other side's vertices do the work
      const double* p = x + 3 * vi;
      // Where the vertex is headed this step (its own velocity; the face's motion is seen from
      // the other side, whose vertices are tested against this body's faces).
      double q[3] = {p[0], p[1], p[2]};
      if (v)
        for (int k = 0; k < 3; ++k) q[k] += hv * (v[3 * vi + k] + hv * g[k]);
      double r = 0;  // query radius: the largest depth of the bodies whose box it is in
      bool inside = false;  // in (or headed into) another body's own box, not just its margin
      for (int b = 0; b < nb; ++b)
        if (b != a && (in_box(boxes + 6 * b, p) || in_box(boxes + 6 * b, q))) {
          r = std::max(r, bc.body_depth[b]);
          const double rb = bc.body_depth[b];
          const double* gb = boxes + 6 * b;  // grown by rb on every side: shrink back
          const double own[6] = {gb[0] + rb, gb[1] + rb, gb[2] + rb, gb[3] - rb, gb[4] - rb, gb[5] - rb};
          inside = inside || in_box(own, p) || in_box(own, q);
        }
      if (r == 0) continue;
      // The vertex's normal (area-weighted over its surface triangles, not normalised).
      double np[3] = {0, 0, 0};
      for (int32_t j = bc.vertex_tri_begin[i]; j < bc.vertex_tri_begin[i + 1]; ++j)
        accumulate_normal(x, bc.vertex_tris[j], np);
      const double np_len = norm3(np);
      // Narrow phase: the closest active facing triangle of another body within its depth of
      // the predicted position (the current one without velocities).
      const double step = std::sqrt((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) +
                                    (q[2] - p[2]) * (q[2] - p[2]));
      int32_t best = -1;
      std::array<double, 3> best_w{};
      const Vec3 qv{q[0], q[1], q[2]};
      // Two radii: most vertices touch (or miss) a face much closer than the depth a body can
      // hold, and the search within the small radius returns the same closest face when there
      // is one there (the closest one is the closest one); only vertices with nothing near pay
      // for the full radius, and only if they are inside another body's box — a vertex outside
      // it cannot be inside that body, and a face it could reach this step is within the small
      // radius. (Bar resting on the block: the full radius for every bar vertex was ~60 % of
      // the tick.)
      for (const double radius : {step + 0.125 * r, step + r}) {
        if (radius > step + 0.125 * r && !inside) break;
        double best_d2 = radius * radius;
        bvh.query_sphere(q, radius, x, [&](int32_t t) {
          if (bc.triangle_body[t] == a || (surf.active && surf.active[t] == 0)) return;
          const auto& tri = surf.triangles[t];
          double nt[3] = {0, 0, 0};
          accumulate_normal(x, tri, nt);
          const double sign = (surf.active && surf.active[t] == 2) ? -1.0 : 1.0;
          const double nt_len = norm3(nt);
          if (!(sign * (nt[0] * np[0] + nt[1] * np[1] + nt[2] * np[2]) < -kFacingCos * nt_len * np_len)) return;
          auto node = [&](int c) { return Vec3{x[3 * tri[c]], x[3 * tri[c] + 1], x[3 * tri[c] + 2]}; };
          const Vec3 A = node(0), B = node(1), C = node(2);
          // The face's plane is no farther than its closest point: skip faces that cannot win.
          const double plane = (qv[0] - A[0]) * nt[0] + (qv[1] - A[1]) * nt[1] + (qv[2] - A[2]) * nt[2];
          if (plane * plane >= best_d2 * nt_len * nt_len) return;
          const auto w = closest_on_triangle(qv, A, B, C);
          double d2 = 0;
          for (int k = 0; k < 3; ++k) {
            const double d = qv[k] - (w[0] * A[k] + w[1] * B[k] + w[2] * C[k]);
            d2 += d * d;
          }
          const double rb = bc.body_depth[bc.triangle_body[t]] + step;
          if (d2 < best_d2 && d2 <= rb * rb) best = t, best_d2 = d2, best_w = w;
        });
        if (best >= 0) break;
      }
      if (best < 0) continue;
      const auto& tri = surf.triangles[best];
      double n[3] = {0, 0, 0};
      accumulate_normal(x, tri, n);
      const double len = norm3(n);
      if (!(len > 0)) continue;  // degenerate (collapsed) face: no direction to push along
      const double sign = (surf.active && surf.active[best] == 2) ? -1.0 : 1.0;
      for (double& c : n) c *= sign / len;
      const double depth = depth_at(x, vi, tri, best_w.data(), n);  // now
      double ahead = depth;                                          // at x + h·v
      for (int k = 0; k < 3; ++k) ahead -= (q[k] - p[k]) * n[k];
      if (depth <= 0 && ahead <= -0.25 * step) continue;  // in front now and after the step
      // A vertex deeper than the face's body can hold was not found above unless it is within
      // reach; one found behind the face but beyond the depth would be on the wrong side.
      if (depth > bc.body_depth[bc.triangle_body[best]]) continue;
      ++out.contacts;
      if (springs.size() + 2 > springs.capacity() || pairs.size() >= pairs.capacity()) {
        ++out.dropped;
        continue;
      }
      const double kA = bc.stiffness * bc.vertex_area[i];
      if (depth > 0) {
        out.energy += 0.5 * kA * depth * depth;
        out.max_depth = std::max(out.max_depth, depth);
      }
      ContactSpring sv, st;  // vertex side: +f; triangle side: −f; both stiffness kA·nnᵀ
      set_spring_point(bc.vertex_dofs[i], sv);
      set_spring_point(surf.dofs[best], best_w[0], best_w[1], best_w[2], st);
      for (int k = 0; k < 3; ++k) {
        sv.force[k] = kA * depth * n[k];  // attractive (δ < 0) for a speculative contact: the
        st.force[k] = -sv.force[k];       // linearised spring only pushes once the face is reached
        for (int l = 0; l < 3; ++l) sv.K[3 * k + l] = st.K[3 * k + l] = kA * n[k] * n[l];
      }
      BodyContactPair pr;
      pr.spring = static_cast<int32_t>(springs.size());
      pr.speculative = depth <= 0;
      for (int k = 0; k < 3; ++k) pr.n[k] = n[k];
      pr.exact = vi < bc.num_dofs && tri[0] < bc.num_dofs && tri[1] < bc.num_dofs && tri[2] < bc.num_dofs;
      pr.depth0 = depth;
      pairs.push_back(pr);
      springs.push_back(sv);
      springs.push_back(st);
    }
  }
}

int release_pulling_contacts(const double* x0, const double* x, std::vector<BodyContactPair>& pairs,
                             std::vector<ContactSpring>& springs) {
  int released = 0;
  for (BodyContactPair& pr : pairs) {
    if (!pr.active || !pr.speculative) continue;
    // δ = (c − p)·n from the pair's own springs: the face point (triangle side) and the vertex.
    double c[3], p[3];
    spring_point(springs[pr.spring + 1], x, c);
    spring_point(springs[pr.spring], x, p);
    double depth = 0;
    if (pr.exact) {
      for (int k = 0; k < 3; ++k) depth += (c[k] - p[k]) * pr.n[k];
    } else {  // a cut surface's point: its start depth moved by what the springs' points did
      double c0[3], p0[3];
      spring_point(springs[pr.spring + 1], x0, c0);
      spring_point(springs[pr.spring], x0, p0);
      depth = pr.depth0;
      for (int k = 0; k < 3; ++k) depth += ((c[k] - c0[k]) - (p[k] - p0[k])) * pr.n[k];
    }
    if (depth >= 0) continue;
    pr.active = false;
    for (int s = 0; s < 2; ++s) {
      ContactSpring& sp = springs[pr.spring + s];
      std::fill(std::begin(sp.force), std::end(sp.force), 0.0);
      std::fill(std::begin(sp.K), std::end(sp.K), 0.0);
    }
    ++released;
  }
  return released;
}

}  // namespace stroma
