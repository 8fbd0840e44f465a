#pragma once
/// \file needle_shape.hpp
/// A suture or biopsy needle's geometry (issue 42; docs/NEEDLE.md): a wire of radius r along a
/// curve of arc length L, from its tail (s = 0) to its sharp tip (s = L).
///
///  - Straight: the curve is the shape frame's z axis, c(s) = (0, 0, s); the tip at z = L.
///  - Curved: a circular arc of radius R in the shape frame's xy-plane, centred on its origin,
///    c(s) = R (cos s/R, sin s/R, 0) for s in [0, L = R·angle]: turning the needle about the shape
///    frame's z axis (its centre) drives the tip along its own arc, as surgeons drive one.
///
/// The solid is the wire swept along the curve with rounded ends (a capsule chain): its signed
/// distance is the distance to the curve less r. Mass properties integrate the wire's slices
/// (a disc each, parallel-axis shifted), exact for the straight wire's cylinder to the quadrature
/// (1e-7) and a thin torus segment's to O((r/R)²).
///
/// Invariants: r > 0; L > 0; curved ⇒ R > r and 0 < angle ≤ 2π (L = R·angle).

#include "rigid/mass_properties.hpp"

namespace stroma {

struct NeedleGeometry {
  bool curved = false;
  double wire_radius = 0;  ///< m
  double length = 0;       ///< m: arc length, tail to tip
  double arc_radius = 0;   ///< m (curved)
  double angle = 0;        ///< rad (curved): L / R
};

/// The curve's point c(s) and unit tangent t(s) (towards the tip) in the shape frame; s is
/// clamped to [0, L].
void needle_curve(const NeedleGeometry& g, double s, double* c, double* t);

/// The arc length of the curve's point nearest to q (shape frame).
double needle_nearest_s(const NeedleGeometry& g, const double* q);

/// Signed distance (m) from q (shape frame) to the needle's surface (< 0 inside the wire), with
/// its outward unit normal.
double needle_distance(const NeedleGeometry& g, const double* q, double* normal);

/// The wire's mass properties at `density` (shape frame: centre and inertia about it). Throws
/// std::invalid_argument for a geometry outside the invariants.
MassProperties needle_mass_properties(const NeedleGeometry& g, double density);

}  // namespace stroma
