#include "render/png_io.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include <png.h>

namespace stroma::render {

bool write_png(const std::string& path, const Image& image, int level, std::string* error) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) {
    if (error) *error = "cannot open '" + path + "' for writing: " + std::strerror(errno);
    return false;
  }
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info) {
    if (png) png_destroy_write_struct(&png, nullptr);
    std::fclose(f);
    if (error) *error = "libpng: out of memory";
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {  // libpng reports errors by longjmp
    const int e = errno;            // the failed write's reason (a full disk: ENOSPC)
    png_destroy_write_struct(&png, &info);
    std::fclose(f);
    std::remove(path.c_str());      // no half-written frame is left behind
    if (error) *error = "error writing '" + path + "'" + (e ? std::string(": ") + std::strerror(e) : std::string());
    return false;
  }
  png_init_io(png, f);
  png_set_compression_level(png, level);
  // The Sub filter alone: most of the gain of adaptive filtering on rendered images, a fraction
  // of its cost.
  png_set_filter(png, 0, level <= 3 ? PNG_FILTER_SUB : PNG_ALL_FILTERS);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), 8,
               image.channels == 4 ? PNG_COLOR_TYPE_RGBA : PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  const size_t stride = static_cast<size_t>(image.width) * image.channels;
  for (int y = 0; y < image.height; ++y)
    png_write_row(png, const_cast<png_bytep>(image.pixels.data() + y * stride));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  errno = 0;
  if (std::fclose(f) != 0) {
    if (error) *error = "error writing '" + path + "': " + std::strerror(errno ? errno : EIO);
    std::remove(path.c_str());
    return false;
  }
  return true;
}

Image read_png(const std::string& path) {
  png_image img;
  std::memset(&img, 0, sizeof img);
  img.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&img, path.c_str()))
    throw std::runtime_error("cannot read PNG '" + path + "': " + img.message);
  const bool alpha = (img.format & PNG_FORMAT_FLAG_ALPHA) != 0;
  img.format = alpha ? PNG_FORMAT_RGBA : PNG_FORMAT_RGB;
  Image out;
  out.width = static_cast<int>(img.width);
  out.height = static_cast<int>(img.height);
  out.channels = alpha ? 4 : 3;
  out.pixels.resize(PNG_IMAGE_SIZE(img));
  if (!png_image_finish_read(&img, nullptr, out.pixels.data(), 0, nullptr)) {
    png_image_free(&img);
    throw std::runtime_error("cannot decode PNG '" + path + "': " + img.message);
  }
  return out;
}

}  // namespace stroma::render
