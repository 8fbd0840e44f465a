#pragma once
/// \file gl_context.hpp
/// An off-screen OpenGL context with no display: OSMesa (Mesa's software rasteriser, llvmpipe),
/// core profile 3.3 or newer. The only file that includes OSMesa's header. One context per
/// thread that renders; it is current on the thread that created it.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace stroma::render {

/// Owns an OSMesa core-profile context and the small colour buffer OSMesa needs to make it
/// current (the renderer draws into its own framebuffer objects and reads pixels back).
class GlContext {
 public:
  /// Creates a context of at least GL `major`.`minor` core and makes it current. Throws
  /// std::runtime_error naming what failed (no OSMesa, no core profile of that version).
  GlContext(int width, int height, int major = 3, int minor = 3);
  ~GlContext();
  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  /// "4.5 (Core Profile) Mesa 22.3.6" and "llvmpipe (LLVM 15.0.6, 256 bits)".
  std::string version() const;
  std::string renderer() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stroma::render
