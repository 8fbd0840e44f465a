// libFuzzer target: the surface readers (Wavefront OBJ, ASCII and binary STL, OFF, PLY). The first
// byte picks the extension (.obj, .stl, .off, .ply by its value mod 4); the rest is the file.
#include "fuzz_input.hpp"
#include "tissue/input_error.hpp"
#include "io/surface_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* const kExt[] = {".obj", ".stl", ".off", ".ply"};
  const std::string path = stroma::fuzz::write_input(data + 1, size - 1, kExt[data[0] % 4]);
  try {
    stroma::read_surface_mesh(path);
  } catch (const stroma::InputError&) {
  }
  return 0;
}
