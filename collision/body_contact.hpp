#pragma once
/// \file body_contact.hpp
/// Contact between different bodies (scenario `body_contact:`): every body's surface vertices
/// against the other bodies' surface triangles, as frictionless penalty springs.
///
/// A vertex p of body A whose closest facing surface triangle of another body B (within B's
/// depth, found through the shared surface BVH; facing: its outward normal n and A's vertex
/// normal at p point against each other, n·n_p < −0.25) has p behind it — (p − c)·n < 0 with c
/// the closest point — is pushed out along n with the pressure k·δ (δ = (c − p)·n) over the
/// vertex's share of A's rest surface area; the triangle's nodes get the opposite force, spread by
/// the barycentric weights of c. Both sides' stiffness k·A·nnᵀ goes into the implicit system on
/// their own diagonal blocks (w_a w_b on the triangle's): the pattern is fixed at load and
/// has no vertex–triangle blocks between bodies, so against a fixed body the tangent is exact and
/// between two moving bodies the coupling is lagged one tick (the forces themselves are exact).
/// Both orders of each pair of bodies are visited (A's vertices in B, B's in A). Self-contact
/// (a body against itself) is not handled.
///
/// Why "facing": the plain closest face is the minimal push-out, which near an edge of B is its
/// side face — a block resting across the edge of another gets pushed sideways off it (measured:
/// a frictionless cube slid off its base). Filtering by the vertex normal keeps the push along
/// the face the vertex came through, as for a block on a table.

#include <array>
#include <cstdint>
#include <vector>

#include "collision/contact_surface.hpp"
#include "collision/triangle_bvh.hpp"
#include "tissue/contact_spring.hpp"

namespace stroma {

/// Compiled body–body contact. Invariants: stiffness > 0; body_depth has one entry per body;
/// vertex, vertex_area, vertex_dofs, vertex_fixed are parallel and grouped by body
/// (body_vertex_begin has bodies + 1 entries); vertex_tri_begin has vertices + 1; triangle_body
/// parallels the collision triangles. Vertices and triangles are surface points
/// (collision/contact_surface.hpp).
struct BodyContactModel {
  double stiffness = 0;  ///< Pa/m: contact pressure per metre of penetration
  /// m, per body: deepest penetration into that body that is found (the BVH query radius for
  /// its triangles). Automatic: a quarter of the body's smallest extent, so a vertex found inside
  /// can never be nearer the opposite side.
  std::vector<double> body_depth;
  std::vector<int32_t> vertex;           ///< surface vertices (surface point ids), grouped by body
  std::vector<double> vertex_area;       ///< m²: a third of the adjacent rest surface triangles
  std::vector<SurfacePointDofs> vertex_dofs;  ///< how each vertex acts on the DOFs (its spring)
  std::vector<uint8_t> vertex_fixed;     ///< 1: every DOF of the vertex is fully constrained
  std::vector<int32_t> body_vertex_begin;  ///< body b's vertices: [begin[b], begin[b + 1])
  std::vector<int32_t> triangle_body;    ///< body of each collision triangle
  int32_t num_dofs = 0;                  ///< surface points below this are DOFs (above: embedded)
  /// Rest-boundary triangles around each vertex (for its normal): vertex i's are
  /// vertex_tris[vertex_tri_begin[i] .. vertex_tri_begin[i + 1]), outward, surface point ids.
  std::vector<int32_t> vertex_tri_begin;
  std::vector<std::array<int32_t, 3>> vertex_tris;
};

/// Smallest cos of the angle between a vertex normal and a face normal for the face to count as
/// facing the vertex (n·n_p < −kFacingCos).
inline constexpr double kFacingCos = 0.25;

/// One vertex–face contact of this tick: its two springs (vertex side at `spring`, triangle side
/// at `spring + 1`: their points are the vertex and its closest point on the face) and the plane
/// it is measured against, so the tick can test it at the end of the step (see
/// release_pulling_contacts).
struct BodyContactPair {
  int32_t spring = 0;
  double n[3] = {0, 0, 0};  ///< the face's outward unit normal at the start of the step
  bool speculative = false;  ///< in front of the face at the start of the step
  bool active = true;
  /// Both the vertex and the face are DOF points (no embedded point of a cut surface): the
  /// springs' points are the contact's points and the end depth is read off them exactly.
  /// Otherwise the springs act on the embedded points' material ends, and the end depth is
  /// depth0 plus the change the springs' points made.
  bool exact = true;
  double depth0 = 0;  ///< δ = (c − p)·n at the start of the step (surface points)
};

/// What body–body contact did in one tick (a tick output: TickReport::body_contact).
struct BodyContactOutput {
  int32_t contacts = 0;  ///< vertices found inside another body
  int32_t dropped = 0;   ///< contacts beyond the springs' capacity (not applied)
  double energy = 0;     ///< J: penalty potential Σ ½ k A δ²
  double max_depth = 0;  ///< m: deepest penetration this tick
};

/// Contacts between bodies at surface point positions x (BVH already refitted), skipping
/// vertices that cannot move; `boxes` is scratch of 6 doubles per body. Appends two springs per
/// contact (vertex side, triangle side; on the DOFs) and its pair, up to the vectors' capacity.
///
/// Speculative: with surface point velocities v, the step h and the body acceleration g (gravity), a vertex also
/// gets a contact when it is in front of a facing face now but (within a quarter of its step)
/// behind it at x + h·v + h²·g, where implicit Euler would take it without contact (it would
/// pass through the face during the step). Its spring is the same linear one, k·A·(δ − n·Δp): the implicit step then stops it
/// at the face instead of letting it sink in for one step unopposed — which would store a
/// penalty energy ½kAδ² far above the impact's kinetic energy (measured: 36× for a bar dropped
/// 20 mm at dt = 1 ms). A speculative contact that ends the step pulling (the vertex did not
/// reach the face) is released by the tick and the step redone. v = nullptr: penetration only.
void body_contact(const BodyContactModel& bc, const ContactSurface& surf, const TriangleBvh& bvh,
                  const double* x, const double* v, double h, const double* g, double* boxes,
                  std::vector<ContactSpring>& springs, std::vector<BodyContactPair>& pairs, BodyContactOutput& out);

/// After a step from DOF positions x0 to x: the speculative contacts whose spring pulls at the
/// end of the step (the vertex stayed in front of its face, δ < 0) are switched off (their
/// springs zeroed). Returns how many. (Contacts that started penetrating stay: a penalty contact
/// may overshoot.)
int release_pulling_contacts(const double* x0, const double* x, std::vector<BodyContactPair>& pairs,
                             std::vector<ContactSpring>& springs);

}  // namespace stroma
