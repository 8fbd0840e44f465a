#include "runtime/output_dir.hpp"

#include <cstdio>
#include <filesystem>

#include <fmt/format.h>

#include "tissue/input_error.hpp"

namespace stroma {

void ensure_writable_dir(const std::string& dir, const std::string& option) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw InputError(dir, 0, option, fmt::format("cannot create output directory: {}", ec.message()));
  const fs::path probe = fs::path(dir) / ".stroma_write_test";
  std::FILE* f = std::fopen(probe.c_str(), "w");
  if (!f) throw InputError(dir, 0, option, "output directory is not writable");
  std::fclose(f);
  fs::remove(probe, ec);
}

}  // namespace stroma
