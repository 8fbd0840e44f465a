#pragma once
/// \file capsule_mesh.hpp
/// Triangle meshes of capsules (a cylinder with hemispherical caps): how tools are drawn.

#include <cstdint>
#include <vector>

#include "render/renderer.hpp"

namespace stroma::render {

/// Appends a capsule from a to b of radius r to an interleaved vertex array (`stride` floats
/// per vertex: position, normal, then zeros) and its triangles (counter-clockwise outside).
/// a = b gives a sphere.
void append_capsule(const Vec3f& a, const Vec3f& b, float r, std::vector<float>& vertices,
                    std::vector<uint32_t>& indices, int stride);

}  // namespace stroma::render
