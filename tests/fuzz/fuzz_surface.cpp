// libFuzzer target: the visual surface readers (Wavefront OBJ, ASCII and binary STL). The first
// byte picks the extension (even: .obj, odd: .stl); the rest is the file.
#include "fuzz_input.hpp"
#include "tissue/input_error.hpp"
#include "tissue/surface_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string path = stroma::fuzz::write_input(data + 1, size - 1, data[0] % 2 ? ".stl" : ".obj");
  try {
    stroma::read_surface_mesh(path);
  } catch (const stroma::InputError&) {
  }
  return 0;
}
