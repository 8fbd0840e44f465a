#pragma once
/// \file output_dir.hpp
/// Checking an output directory before long work starts, so a bad --out fails at once with a
/// precise message instead of after a run (nothing half-written, nothing lost).

#include <string>

namespace stroma {

/// Creates `dir` (and its parents) and checks that a file can be written in it. Throws
/// OptionError(option, "DIR: reason") otherwise (runtime/option_error.hpp); `option` names the
/// flag (e.g. "--out").
void ensure_writable_dir(const std::string& dir, const std::string& option = "--out");

}  // namespace stroma
