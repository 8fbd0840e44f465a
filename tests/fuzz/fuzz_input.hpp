#pragma once
/// \file fuzz_input.hpp
/// Helpers shared by the libFuzzer targets (tests/fuzz/README.md).
///
/// A target feeds one input to one of Stroma's readers and lets only stroma::InputError — the
/// documented way every reader reports bad input — pass. Anything else (a crash, a sanitizer
/// report, another exception type, a hang past libFuzzer's -timeout, a leak) is a finding.

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <unistd.h>

namespace stroma::fuzz {

/// Writes the input to a per-process file with extension `ext` and returns its path: for the
/// readers that take a path (and pick the format by extension). Rewritten for every input.
inline std::string write_input(const uint8_t* data, size_t size, const std::string& ext) {
  static const std::string dir = [] {
    const char* shm = "/dev/shm";
    return std::string(access(shm, W_OK) == 0 ? shm : "/tmp");
  }();
  const std::string path = dir + "/stroma_fuzz_" + std::to_string(getpid()) + ext;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

}  // namespace stroma::fuzz
