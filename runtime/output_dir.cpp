#include "runtime/output_dir.hpp"

#include <cstdio>
#include <filesystem>

#include <fmt/format.h>

#include "runtime/option_error.hpp"

namespace stroma {

void ensure_writable_dir(const std::string& dir, const std::string& option) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw OptionError(option, fmt::format("{}: cannot create output directory: {}", dir, ec.message()));
  const fs::path probe = fs::path(dir) / ".stroma_write_test";
  std::FILE* f = std::fopen(probe.c_str(), "w");
  if (!f) throw OptionError(option, dir + ": output directory is not writable");
  std::fclose(f);
  fs::remove(probe, ec);
}

}  // namespace stroma
