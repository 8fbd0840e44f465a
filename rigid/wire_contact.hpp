#pragma once
/// \file wire_contact.hpp
/// A thin wire (a needle's shaft) against the tissue's surface: the wire samples the surface,
/// not the surface the wire.
///
/// Why: rigid_tissue_contact samples each surface triangle at most 24 times per edge
/// (collision/contact_surface.hpp), 0.8 mm apart on the 16 cm liver's 20 mm triangles — as wide
/// as a 0.4 mm-radius wire, so a needle lying on the organ slipped between the samples: tick to
/// tick its energy accounting jumped by up to 59 % of a 1 cm fall's (Needle.ANeedleLetGo, before).
/// Sampling the wire instead costs its points × the few triangles near it, whatever the mesh.
///
/// The wire is a chain of spheres of its radius r on its curve (RigidBodyModel::wire_axis,
/// spaced at most r/2, so the swept solid is covered to 3 % of r). Each axis point c takes the
/// closest point q of the nearby active surface triangles (one, so a point over a shared edge is
/// not counted twice, and the direction turns continuously over a ridge between faces); its
/// signed distance σ = ±|c − q| (negative below the face's plane). Within reach, a point with
/// −r < σ < r + the step's reach gets a contact spring between the wire's point c + r·n facing
/// the tissue and the tissue point q, along n (from the wire to the tissue), of depth r − σ:
/// penetrating (σ < r) a penalty k·A·(r − σ), in front (σ ≥ r) a speculative spring as
/// rigid_tissue_contact's (released if it ends the step pulling). A = 2r × the point's share of
/// the arc length, the wire's projected area: at a depth of one radius the sampled chord's force
/// k·(4√2/3)·r² per length is within 6 % of it. An axis point deeper than r under the surface
/// makes none, nor the points `ex` excludes: near the tip, a surface ahead of the wire (the tip
/// presses it and punctures it: the wire would take its load); the part of an inserted needle's
/// wire along its track (a cut across the track makes faces the shaft crosses: pressing on them along the axis
/// would hold the needle back) and the tissue around its holes. The samples end one radius short
/// of the curve's end: the apex beyond is the tip's own contact (rigid/needle_track.hpp).
/// No allocation: the wire's world points live on the stack (kMaxWireSamples).

#include <cstdint>
#include <vector>

#include "collision/contact_surface.hpp"
#include "collision/triangle_bvh.hpp"
#include "rigid/rigid_contact.hpp"

namespace stroma {

/// The most points a wire is sampled with (a longer wire's are spaced wider than r/2).
inline constexpr int kMaxWireSamples = 512;

/// Fills b.wire_axis and b.wire_share for a needle (load time; others: cleared).
void make_wire_samples(RigidBodyModel& b);

/// The wire of body b (a needle) at state s against the tissue's surface (points x, velocities
/// v; BVH refitted): as rigid_tissue_contact, whose arguments these are.
void wire_tissue_contact(const RigidBodyModel& b, const RigidState& s, int32_t row, const ContactSurface& surf,
                         const TriangleBvh& bvh, const double* x, const double* v, double h, const Vec3& g,
                         std::vector<ContactSpring>& springs, std::vector<RigidContactPair>& pairs,
                         RigidContactOutput& out, const ContactExclusion& ex);

}  // namespace stroma
