#pragma once
/// \file png_io.hpp
/// PNG files through libpng. Writing uses a fast zlib level by default: at the default level
/// (6) a 640x480 frame takes ~55 ms here, at level 1 a fraction of that (docs/PERFORMANCE.md).

#include <cstdint>
#include <string>
#include <vector>

namespace stroma::render {

/// An 8-bit image, rows top to bottom, `channels` bytes per pixel (3 = RGB, 4 = RGBA).
struct Image {
  int width = 0, height = 0, channels = 3;
  std::vector<uint8_t> pixels;
};

/// Writes `image` to `path`. zlib `level` 0–9 (1: fast, files ~20 % larger than at 6).
/// Returns false (and sets `error`) on failure; never throws (called by the writer thread).
bool write_png(const std::string& path, const Image& image, int level, std::string* error);

/// Reads an 8-bit RGB or RGBA PNG (other formats are converted to RGB/RGBA). Throws
/// std::runtime_error naming the file on failure.
Image read_png(const std::string& path);

}  // namespace stroma::render
